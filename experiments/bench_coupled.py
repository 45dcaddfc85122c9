"""Where a coupled step's time goes: the elastic gate and the two-phase dam break (or any
registered scene with fluid and discs), per step and per part.

    .venv/bin/python experiments/bench_coupled.py [--cases elastic_gate two_phase_dam_break]
                                                  [--warm 0.05] [--steps 100] [--reps 5]
                                                  [--profile]

For each case: a run of ``--warm`` simulated seconds (the flow has started), then, from that
state, the median of ``--reps`` compiled chunks of ``--steps`` of

* the whole step (``solver.step``), with the neighbour rebuilds that fall in the chunk,
* the DEM part alone (``stages.discs``: all sub-steps of a step),
* a forced rebuild of the SPH list (positions nudged every time so nothing is hoisted),

and the SPH list's rebuild interval seen in the whole-step chunk (``Status.rebuilds``;
the DEM list's rebuilds, ``Status.dem_rebuilds``, are counted apart). ``--wall-rows``
adds, in the same process and interleaved chunk by chunk, the whole step with the wall rows read at the
width setup measured (NeighborConfig.wall_width) against the same step reading all K
slots (wall_width 0), each the median of ``--reps`` chunks; ``--wall-widths 15 22 25`` the
step at each of those widths; ``--walls-near`` the step and its DEM part with the DEM wall
contacts of the discs near a wall only (WallState.near) against every disc's in every
sub-step. ``--profile`` adds the time per
named scope (``jax.named_scope`` in the stages and physics modules) from a JAX profiler
trace of one chunk: the trace's per-op times are summed by the op's scope (ops outside any
scope are listed by their primitive). Profiling slows small ops; read the shares, not the
absolute figures. Writes experiments/results/bench_coupled.json.
"""
from __future__ import annotations

import argparse
import collections
import dataclasses
import glob
import gzip
import json
import os
import re
import statistics
import tempfile
import time

import jax
import jax.numpy as jnp

from fpsi_jax import cases, solver
from fpsi_jax.run.driver import setup, simulate
from fpsi_jax.solver import neighbors, stages

HERE = os.path.dirname(os.path.abspath(__file__))


def _median_ms(fn, state, steps, reps):
    jax.block_until_ready(fn(state))
    walls = []
    for _ in range(reps):
        t0 = time.perf_counter()
        jax.block_until_ready(fn(state))
        walls.append(time.perf_counter() - t0)
    return statistics.median(walls) / steps * 1e3


def _loop(body, steps):
    return jax.jit(lambda s: jax.lax.fori_loop(0, steps, lambda i, c: body(i, c), s))


def scope_profile(fn, state, steps):
    """µs per step by named scope from a profiler trace of one call of ``fn``."""
    hlo = fn.lower(state).compile().as_text()
    scope = {}
    for m in re.finditer(r'^\s*%?([\w.\-]+) = .*?op_name="([^"]*)"', hlo, re.M):
        parts = [p for p in m.group(2).split("/")
                 if not (p.startswith("jit(") or p in ("while", "body", "closed_call",
                                                       "cond", "branch_1_fun"))]
        dem = [p for p in parts if p.startswith("step.dem_substeps")]
        named = [p for p in parts if "." in p and not p.startswith("step.dem_substeps")]
        head = named[0] if named else (parts[-1] if parts else "?")
        scope[m.group(1)] = ("dem sub-step: " if dem else "") + head
    with tempfile.TemporaryDirectory() as d:
        with jax.profiler.trace(d):
            jax.block_until_ready(fn(state))
        trace = glob.glob(os.path.join(d, "**", "*.trace.json.gz"), recursive=True)[0]
        events = json.load(gzip.open(trace))["traceEvents"]
    total = collections.Counter()
    for e in events:
        if e.get("ph") == "X" and e.get("name") in scope and not e["name"].startswith("while"):
            total[scope[e["name"]]] += e["dur"]
    return {k: v / steps for k, v in total.most_common()}


def interleaved_ms(fns, state, steps, reps):
    """{name: median ms per step} of compiled chunks ``fns`` timed one after another,
    ``reps`` rounds (a slow spell of the machine hits every variant alike). A value of
    ``fns`` may be a pair (chunk, its own start state)."""
    runs = {k: f if isinstance(f, tuple) else (f, state) for k, f in fns.items()}
    for fn, s0 in runs.values():
        jax.block_until_ready(fn(s0))
    walls = {k: [] for k in runs}
    for _ in range(reps):
        for k, (fn, s0) in runs.items():
            t0 = time.perf_counter()
            jax.block_until_ready(fn(s0))
            walls[k].append(time.perf_counter() - t0)
    return {k: statistics.median(v) / steps * 1e3 for k, v in walls.items()}


def bench(name, warm, steps, reps, profile, wall_rows=False, walls_near=False,
          wall_widths=(), k_extra=()):
    scene = cases.build(name, t_end=warm)
    state = simulate(scene, progress=False).state
    phys, params = setup(scene)
    p = params.as_arrays(solver.dtype(phys))
    whole = _loop(lambda i, s: solver.step(phys, s, p), steps)
    dem = _loop(lambda i, s: stages.discs(phys, p, s), steps)
    cfg = phys.neighbors

    def nudge(i, carry):
        nb, x = carry
        x = x + 1e-7 * jnp.sin(i + x)
        return neighbors.rebuild(cfg, nb, neighbors.shift(cfg, x)), x

    rebuild = jax.jit(lambda c: jax.lax.fori_loop(0, steps, nudge, c))
    x0 = stages.sph_positions(state)
    end = whole(state)
    row = {"case": name, "t_from": float(state.t), "steps": steps, "reps": reps,
           "n_fluid": phys.n_fluid, "n_boundary": phys.n_boundary, "n_discs": phys.n_solid,
           "dem_substeps": phys.dem_substeps, "sph_capacity": int(state.nbrs.idx.shape[1]),
           "dem_capacity": int(state.solid_nbrs.idx.shape[1]),
           "step_ms": _median_ms(whole, state, steps, reps),
           "discs_ms": _median_ms(dem, state, steps, reps),
           "rebuild_ms": _median_ms(rebuild, (state.nbrs, x0), steps, reps),
           "rebuilds_in_chunk": int(end.status.rebuilds - state.status.rebuilds),
           "dem_rebuilds_in_chunk": int(end.status.dem_rebuilds - state.status.dem_rebuilds)}
    row["substep_us"] = row["discs_ms"] / phys.dem_substeps * 1e3
    row["rebuild_share"] = (row["rebuild_ms"] * row["rebuilds_in_chunk"] / steps
                            / row["step_ms"])
    if profile:
        row["profile_us_per_step"] = scope_profile(whole, state, steps)
    if wall_rows:
        full = dataclasses.replace(phys, neighbors=dataclasses.replace(cfg, wall_width=0))
        ab = interleaved_ms({"narrow": whole,
                             "full": _loop(lambda i, s: solver.step(full, s, p), steps)},
                            state, steps, reps)
        row.update(wall_width=cfg.wall_width, step_ms_wall_rows_narrow=ab["narrow"],
                   step_ms_wall_rows_full=ab["full"])
    if wall_widths:
        fns = {}
        for w in wall_widths:
            ph = dataclasses.replace(phys, neighbors=dataclasses.replace(cfg, wall_width=w))
            fns[w] = _loop(lambda i, s, ph=ph: solver.step(ph, s, p), steps)
        row["step_ms_at_wall_width"] = interleaved_ms(fns, state, steps, reps)
    if k_extra:
        # the same state with the SPH list allocated wider (min_neighbors raised): what a
        # slot of the list's width K costs the step
        fns = {}
        for extra in k_extra:
            c = dataclasses.replace(cfg, min_neighbors=row["sph_capacity"] + extra)
            nb = neighbors.allocate(c, x0)
            ph = dataclasses.replace(phys, neighbors=c)
            fns[int(nb.idx.shape[1])] = (_loop(lambda i, s, ph=ph: solver.step(ph, s, p), steps),
                                         state.replace(nbrs=nb))
        row["step_ms_at_K"] = interleaved_ms(fns, state, steps, reps)
    if walls_near and state.walls is not None:
        # the same chunks from a state whose walls are evaluated for every disc (near=None)
        always = state.replace(walls=state.walls.replace(near=None, n_near=None))
        ab = interleaved_ms({"near": whole, "always": (whole, always),
                             "dem_near": dem, "dem_always": (dem, always)},
                            state, steps, reps)
        row.update(walls_near_at_start=int(state.walls.n_near),
                   walls_near_in_chunk=int(end.walls.n_near),
                   walls_near_capacity=int(state.walls.near.shape[0]),
                   step_ms_walls_near=ab["near"], step_ms_walls_always=ab["always"],
                   discs_ms_walls_near=ab["dem_near"], discs_ms_walls_always=ab["dem_always"])
    return row


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--cases", nargs="*", default=["elastic_gate", "two_phase_dam_break"])
    ap.add_argument("--warm", type=float, default=0.05, help="simulated seconds first")
    ap.add_argument("--steps", type=int, default=100)
    ap.add_argument("--reps", type=int, default=5)
    ap.add_argument("--profile", action="store_true")
    ap.add_argument("--wall-rows", action="store_true",
                    help="A/B: wall rows at their measured width against all K slots")
    ap.add_argument("--wall-widths", nargs="*", type=int, default=[],
                    help="A/B: the whole step at each of these wall-row widths")
    ap.add_argument("--k-extra", nargs="*", type=int, default=[],
                    help="A/B: the whole step with the SPH list this many slots wider "
                         "(0: reallocated at the state's own width)")
    ap.add_argument("--walls-near", action="store_true",
                    help="A/B: DEM wall contacts of the discs near a wall only against "
                         "every disc's in every sub-step")
    ap.add_argument("--out", default=os.path.join(HERE, "results", "bench_coupled.json"))
    args = ap.parse_args()
    rows = []
    for name in args.cases:
        r = bench(name, args.warm, args.steps, args.reps, args.profile, args.wall_rows,
                  args.walls_near, args.wall_widths, args.k_extra)
        rows.append(r)
        print(f"{name}: step {r['step_ms']:.2f} ms; DEM {r['discs_ms']:.2f} ms "
              f"({r['dem_substeps']} sub-steps of {r['substep_us']:.0f} us, "
              f"{r['n_discs']} discs); SPH rebuild {r['rebuild_ms']:.2f} ms every "
              f"{args.steps / max(r['rebuilds_in_chunk'], 1):.1f} steps "
              f"({100 * r['rebuild_share']:.0f} % of the step); DEM list rebuilt "
              f"{r['dem_rebuilds_in_chunk']} times in {args.steps} steps", flush=True)
        if args.wall_rows:
            print(f"    wall rows read at {r['wall_width']} of {r['sph_capacity']} slots: step "
                  f"{r['step_ms_wall_rows_narrow']:.2f} ms against "
                  f"{r['step_ms_wall_rows_full']:.2f} ms at all slots", flush=True)
        if "step_ms_at_wall_width" in r:
            print("    step at wall-row width " + ", ".join(
                f"{w}: {ms:.2f} ms" for w, ms in r["step_ms_at_wall_width"].items()), flush=True)
        if "step_ms_at_K" in r:
            print("    step at list width " + ", ".join(
                f"K = {k}: {ms:.2f} ms" for k, ms in r["step_ms_at_K"].items()), flush=True)
        if "step_ms_walls_near" in r:
            print(f"    discs near a wall {r['walls_near_at_start']} -> "
                  f"{r['walls_near_in_chunk']} (room {r['walls_near_capacity']}): "
                  f"step {r['step_ms_walls_near']:.2f} against "
                  f"{r['step_ms_walls_always']:.2f} ms, DEM part "
                  f"{r['discs_ms_walls_near']:.2f} against "
                  f"{r['discs_ms_walls_always']:.2f} ms", flush=True)
        for k, v in list(r.get("profile_us_per_step", {}).items())[:15]:
            print(f"    {v:9.1f} us/step  {k}")
    os.makedirs(os.path.dirname(os.path.abspath(args.out)), exist_ok=True)
    with open(args.out, "w") as fh:
        json.dump({"timing": f"median of {args.reps} chunks of {args.steps} steps after "
                             f"{args.warm} s of simulated flow", "jax": jax.__version__,
                   "backend": jax.default_backend(), "rows": rows}, fh, indent=1)


if __name__ == "__main__":
    main()
