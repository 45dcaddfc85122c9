"""Cost per particle-step of the SPH dam break from ~7k to ~340k particles, three ways of
cutting the pair passes and the list rebuild into row blocks, timed interleaved in one
process:

* ``default``: the pair passes in one pass over all rows (``Physics.pair_block`` 0) and
  the rebuild's candidate pass in row blocks (``rebuild_block``, the CPU default: it takes
  effect from ``pairs.MIN_BLOCKS`` blocks of rows),
* ``one_pass``: both over all rows at once,
* ``blocks``: both in row blocks of ``--block`` rows.

    .venv/bin/python experiments/sph_scaling.py [--dx 0.0029 0.00145 0.00072 0.00051 0.00036]
                                                [--steps 100] [--reps 5] [--t-from 0.05]
                                                [--across]

For each dx: the full-physics dam break (as bench_sph.py) at the derived step, a warm-up
chunk (lists grown if they overflow), with ``--t-from`` further chunks until the flow
reaches that simulated time, then ``--reps`` rounds of one chunk of each setting from the
same warmed-up state, alternating; the median chunk of each. Without ``--t-from`` every
size is timed after its first chunk, so the coarse scenes are timed later in the flow
(100 steps are 0.012 s at 6.9k and 0.0015 s at 344k): the water moves faster there and
the list is rebuilt more often a step. From one simulated time the flow is the same at
every size and a particle moves about the same fraction of h in a step (CFL h/(c0 +
|v|)), so the rebuilds a step nearly match (11–16 in 100 steps from 0.05 s, 6.9k to
344k) and the cost per particle-step compares the step itself. The settings compute the same step (tests/solver/test_stages.py: equal to round-off). Writes
experiments/results/sph_scaling.csv and sph_scaling.png.

``--across`` times the default setting alone, the sizes' chunks interleaved (every size
warmed up first, then one chunk of each in turn, ``--reps`` rounds), so a change of the
machine's speed falls on all sizes alike: results/sph_scaling_across.csv.
"""
from __future__ import annotations

import argparse
import csv
import dataclasses
import os
import statistics

import jax.numpy as jnp

from fpsi_jax import cases, solver
from fpsi_jax.model.config import CPU_REBUILD_BLOCK
from fpsi_jax.run.driver import run_until_fits, setup

from _bench import compile_and_warm_up

HERE = os.path.dirname(os.path.abspath(__file__))


#: (pair passes' block, rebuild's block) of each setting, given --block
SETTINGS = {"default": lambda b: (0, b), "one_pass": lambda b: (0, 0),
            "blocks": lambda b: (b, b)}


def with_block(phys, pair_block, rebuild_block):
    nb = dataclasses.replace(phys.neighbors, row_block=rebuild_block)
    return dataclasses.replace(phys, pair_block=pair_block, neighbors=nb)


def warmed(dx, steps, t_from=None, phys_of=lambda ph: with_block(ph, 0, 0)):
    """The dam break at ``dx``: its scene, a compiled ``steps``-long chunk and the state
    after a warm-up chunk (lists grown), run on to ``t_from`` where given."""
    sc = cases.build("dam_break", dx=dx)
    phys, params = setup(sc)
    p = params.as_arrays(jnp.float32)
    st = solver.init_state(sc, phys, p)
    phys, st, chunk, _ = compile_and_warm_up(phys_of(phys), st, p, steps)
    while t_from is not None and float(st.t) < t_from:
        c = run_until_fits(chunk, phys, st, chunk.dt)
        phys, st = c.phys, c.end
    return sc, phys, st, chunk


def across_sizes(dxs, steps, reps, t_from):
    """The default setting only, every size warmed up first and then one chunk of each size
    in turn, ``reps`` rounds: a change of the machine's speed during the measurement falls
    on every size alike, so the sizes compare with each other."""
    runs = [warmed(dx, steps, t_from, lambda ph: ph) for dx in dxs]
    walls = [[] for _ in runs]
    ends = [None] * len(runs)
    for _ in range(reps):
        for k, (sc, phys, st, chunk) in enumerate(runs):
            ends[k], wall = chunk(phys, st)
            walls[k].append(wall)
    rows = []
    for (sc, phys, st, chunk), w, end, dx in zip(runs, walls, ends, dxs):
        n = sc.fluid.n + sc.boundary.n
        m = statistics.median(w) / steps
        rows.append({"dx": dx, "n_particles": n, "t_from": float(st.t),
                     "neighbour_capacity": int(st.nbrs.idx.shape[1]), "steps": steps,
                     "rebuilds": int(end.status.rebuilds - st.status.rebuilds),
                     "overflowed": bool(end.status.overflow),
                     "ms_per_step": m * 1e3, "M_particle_steps_per_s": n / m / 1e6,
                     "ns_per_particle_step": m / n * 1e9,
                     "ns_min": min(w) / steps / n * 1e9, "ns_max": max(w) / steps / n * 1e9})
    return rows


def row(dx, steps, reps, block, t_from=None):
    sc, phys, st, chunk = warmed(dx, steps, t_from)
    settings = {tag: with_block(phys, *f(block)) for tag, f in SETTINGS.items()}
    walls, ends = {b: [] for b in settings}, {}
    for ph in settings.values():            # compile each (untimed)
        chunk(ph, st)
    for _ in range(reps):
        for b, ph in settings.items():
            end, wall = chunk(ph, st)
            walls[b].append(wall)
            ends[b] = end
    n = sc.fluid.n + sc.boundary.n
    out = {"dx": dx, "n_particles": n, "n_fluid": sc.fluid.n, "t_from": float(st.t),
           "neighbour_capacity": int(st.nbrs.idx.shape[1]), "steps": steps,
           "rebuilds": int(ends["default"].status.rebuilds - st.status.rebuilds),
           "overflowed": any(bool(e.status.overflow) for e in ends.values()),
           "pair_block": block}
    for tag in SETTINGS:
        m = statistics.median(walls[tag]) / steps
        out[f"ms_per_step_{tag}"] = m * 1e3
        out[f"M_particle_steps_per_s_{tag}"] = n / m / 1e6
        out[f"ns_per_particle_step_{tag}"] = m / n * 1e9
    return out


def plot(rows, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    n = [r["n_particles"] for r in rows]
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.plot(n, [r["ns_per_particle_step_default"] for r in rows], "o-",
            label=f"default: pair passes in one pass, rebuild in blocks of "
                  f"{rows[0]['pair_block']} rows")
    ax.plot(n, [r["ns_per_particle_step_one_pass"] for r in rows], "^--",
            label="both in one pass over all rows")
    ax.plot(n, [r["ns_per_particle_step_blocks"] for r in rows], "s:",
            label=f"both in row blocks of {rows[0]['pair_block']}")
    ax.set_xscale("log")
    ax.set_ylim(bottom=0)
    ax.set_xlabel("particles (fluid + boundary)")
    ax.set_ylabel("ns per particle-step")
    ax.set_title("SPH dam break, derived step, 2-core CPU")
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--dx", type=float, nargs="*",
                    default=[0.0029, 0.00145, 0.00072, 0.00051, 0.00036])
    ap.add_argument("--steps", type=int, default=100)
    ap.add_argument("--reps", type=int, default=5)
    ap.add_argument("--block", type=int, default=CPU_REBUILD_BLOCK)
    ap.add_argument("--t-from", type=float, default=None,
                    help="time every size from this simulated time [s]")
    ap.add_argument("--across", action="store_true",
                    help="the default setting only, chunks of the sizes interleaved "
                         "(writes sph_scaling_across.csv unless --out)")
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    name = "sph_scaling_across.csv" if args.across else "sph_scaling.csv"
    args.out = args.out or os.path.join(HERE, "results", name)
    if args.across:
        rows = across_sizes(args.dx, args.steps, args.reps, args.t_from)
        for r in rows:
            print(f"N={r['n_particles']:7d} {r['M_particle_steps_per_s']:.2f} M p-steps/s "
                  f"{r['ns_per_particle_step']:.0f} ns ({r['ns_min']:.0f}-{r['ns_max']:.0f}), "
                  f"rebuilds {r['rebuilds']}/{args.steps}", flush=True)
        ns = [r["ns_per_particle_step"] for r in rows]
        print(f"spread (max/min - 1): {max(ns) / min(ns) - 1:.1%}")
        with open(args.out, "w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=list(rows[0]))
            w.writeheader()
            w.writerows(rows)
        return
    rows = []
    for dx in args.dx:
        r = row(dx, args.steps, args.reps, args.block, args.t_from)
        rows.append(r)
        print(f"dx={dx * 1e3:.2f} mm N={r['n_particles']:7d} K={r['neighbour_capacity']} "
              + ", ".join(f"{tag} {r[f'M_particle_steps_per_s_{tag}']:.2f} M p-steps/s "
                          f"({r[f'ns_per_particle_step_{tag}']:.0f} ns)" for tag in SETTINGS)
              + f", rebuilds {r['rebuilds']}/{args.steps}", flush=True)
    os.makedirs(os.path.dirname(os.path.abspath(args.out)), exist_ok=True)
    with open(args.out, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    plot(rows, os.path.splitext(args.out)[0] + ".png")


if __name__ == "__main__":
    main()
