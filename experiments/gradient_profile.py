"""Where a reverse-mode gradient's time goes: a profile of the gradient of a short rollout.

    python experiments/gradient_profile.py --case gate --steps 10            # every step remat
    python experiments/gradient_profile.py --case cantilever --steps 200 --no-remat-step

The case's calibration problem (``calibrate.cases``: the coarse elastic gate, or the
cantilever strip at d = 1.25 mm) gives the physics, start state and parameters; the loss is
Σ|x|² + Σv of the discs after ``--steps`` steps of one ``lax.scan`` (each step under
``jax.checkpoint`` unless ``--no-remat-step``), so the profile shows one chunk's reverse
pass without the outer chunking. The forward rollout and its gradient are compiled, timed
(median of 5 calls) and profiled once (``jax.profiler.trace``); the XLA operations' times are
summed by kind (a fusion by its name without the number) and the largest single operations
are listed with their HLO line. Traced times include the profiler's own cost per operation,
so compare shares, not absolute sums, with the timed wall. Writes
experiments/results/gradient_profile_<case>.json.
"""
from __future__ import annotations

import argparse
import collections
import glob
import gzip
import json
import os
import re
import statistics
import tempfile
import time

import fpsi_jax  # noqa: F401  (XLA flags before JAX starts)
import jax
import jax.numpy as jnp

OUT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "results")
_LINE = re.compile(r"^\s*(?:ROOT )?%?([\w.\-]+) = .*? ([\w\-]+)\(", re.M)


def problem(case):
    from calibrate import cases
    if case == "gate":
        return cases.elastic_gate(resolution="coarse", t_fit=0.2).calibration.problem
    return cases.cantilever_synthetic(d=0.00125, periods=2.0).calibration.problem


def loss_fn(pr, steps, remat_step):
    from fpsi_jax.solver import forward
    step = jax.checkpoint(forward.step, static_argnums=0) if remat_step else forward.step

    def loss(params, state):
        end = jax.lax.scan(lambda s, _: (step(pr.phys, s, params), None), state, None,
                           length=steps)[0]
        return jnp.sum(end.solid.x * end.solid.x) + jnp.sum(end.solid.v)
    return loss


def profile(compiled, args, steps, top):
    """(median wall ms a step, {kind: ms a step}, [(ms a step, HLO line)] of the largest
    operations, the same of the largest loops (e.g. the DEM sub-steps') of one call."""
    hlo = compiled.as_text()
    lines = {m.group(1): (m.group(2), hlo[m.start():hlo.find("\n", m.start())].strip())
             for m in _LINE.finditer(hlo)}
    jax.block_until_ready(compiled(*args))
    walls = []
    for _ in range(5):
        t0 = time.perf_counter()
        jax.block_until_ready(compiled(*args))
        walls.append(time.perf_counter() - t0)
    with tempfile.TemporaryDirectory() as d:
        with jax.profiler.trace(d):
            jax.block_until_ready(compiled(*args))
        path = glob.glob(os.path.join(d, "**", "*.trace.json.gz"), recursive=True)[0]
        events = json.load(gzip.open(path))["traceEvents"]
    kinds, ops, loops = collections.Counter(), collections.Counter(), collections.Counter()
    for e in events:
        name = e.get("name")
        if e.get("ph") != "X" or name not in lines:
            continue
        op = lines[name][0]
        if op == "while":                   # a loop's time includes its body's operations
            loops[name] += e["dur"]
        if op in ("while", "conditional", "call"):       # their bodies are counted inside
            continue
        kinds[op if op != "fusion" else "fusion " + re.sub(r"[._]\d+$", "", name)] += e["dur"]
        ops[name] += e["dur"]
    per = 1e-3 / steps                                    # µs in the trace → ms a step
    return (statistics.median(walls) * 1e3 / steps,
            {k: v * per for k, v in kinds.most_common(top)},
            [(v * per, lines[k][1][:160]) for k, v in ops.most_common(top)],
            [(v * per, lines[k][1][:160]) for k, v in loops.most_common(5)])


def main(args):
    pr = problem(args.case)
    loss = loss_fn(pr, args.steps, not args.no_remat_step)
    fargs = (pr.params, pr.state0)
    out = {"case": args.case, "steps": args.steps, "remat_step": not args.no_remat_step}
    for what, fn in (("forward", jax.jit(loss)), ("gradient", jax.jit(jax.grad(loss)))):
        wall, kinds, ops, loops = profile(fn.lower(*fargs).compile(), fargs, args.steps,
                                          args.top)
        out[what] = {"wall_ms_per_step": wall, "by_kind_ms_per_step": kinds,
                     "largest_ops_ms_per_step": ops, "inner_loops_ms_per_step": loops}
        print(f"{what}: {wall:.3f} ms a step (median of 5)")
        for k, v in kinds.items():
            print(f"  {v:8.3f}  {k}")
        print("  largest operations:")
        for v, line in ops[:args.top // 2]:
            print(f"  {v:8.3f}  {line[:120]}")
        print("  largest loops (a loop's time includes its body's operations):")
        for v, line in loops:
            print(f"  {v:8.3f}  {line[:120]}")
    out["ratio"] = out["gradient"]["wall_ms_per_step"] / out["forward"]["wall_ms_per_step"]
    print(f"gradient / forward: {out['ratio']:.1f}")
    os.makedirs(OUT, exist_ok=True)
    with open(os.path.join(OUT, f"gradient_profile_{args.case}.json"), "w") as fh:
        json.dump(out, fh, indent=1)


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--case", choices=("gate", "cantilever"), default="gate")
    ap.add_argument("--steps", type=int, default=10)
    ap.add_argument("--no-remat-step", action="store_true")
    ap.add_argument("--top", type=int, default=20)
    main(ap.parse_args())
