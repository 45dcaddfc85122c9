"""Two versions of the package timed in one process: a committed revision against the
working tree, chunks interleaved.

    python experiments/ab_versions.py --base REV [--cases elastic_gate ...] [--dem]
                                      [--rebuild] [--steps 20] [--reps 9] [--dx DX]

Process-level A/B runs on a shared two-core machine differ by 10–30 % from one process to
the next for the same program; two compiled programs timed alternately in one process see
the same slow spells. The base revision's ``fpsi_jax`` is extracted with ``git archive``
into a temporary folder and imported as ``fpsi_base`` (the package imports itself only
relatively). For each case and version: a run to ``--warm`` s, then compiled chunks of
``--steps`` steps (the whole step; with ``--dem`` the DEM part alone, all its sub-steps;
with ``--rebuild`` forced rebuilds of the SPH list), each version's from its own state,
timed in ``--reps`` interleaved rounds; the median ms per step is printed. Pin the process
to one core (``taskset -c 1``) for figures to compare.
"""
from __future__ import annotations

import argparse
import importlib
import os
import statistics
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def extract(rev: str, into: str) -> str:
    """``fpsi_jax`` of revision ``rev`` as the package ``fpsi_base`` under ``into``."""
    archive = subprocess.run(["git", "-C", ROOT, "archive", rev, "fpsi_jax"], check=True,
                             capture_output=True).stdout
    subprocess.run(["tar", "-x", "-C", into], input=archive, check=True)
    os.rename(os.path.join(into, "fpsi_jax"), os.path.join(into, "fpsi_base"))
    return into


def chunks(pkg: str, case: str, warm: float, steps: int, dem: bool, rebuild: bool, dx):
    """{what: (compiled chunk, its start)} for one version of the package."""
    import jax
    import jax.numpy as jnp
    reg = importlib.import_module(pkg + ".cases.registry")
    driver = importlib.import_module(pkg + ".run.driver")
    solver = importlib.import_module(pkg + ".solver")
    stages = importlib.import_module(pkg + ".solver.stages")
    nb = importlib.import_module(pkg + ".solver.neighbors")
    scene = reg.build(case, t_end=warm, **({} if dx is None else {"dx": dx}))
    state = driver.simulate(scene, progress=False).state
    phys, params = driver.setup(scene)
    p = params.as_arrays(solver.dtype(phys))

    def loop(body, start):
        fn = jax.jit(lambda s: jax.lax.fori_loop(0, steps, lambda i, c: body(c), s))
        return fn.lower(start).compile(), start

    out = {"step": loop(lambda s: solver.step(phys, s, p), state)}
    if dem and phys.has_solid:
        out["dem"] = loop(lambda s: stages.discs(phys, p, s), state)
    if rebuild and phys.has_fluid:
        cfg = phys.neighbors

        def nudge(c):
            lst, x = c
            x = x + 1e-7 * jnp.sin(x)
            return nb.rebuild(cfg, lst, nb.shift(cfg, x)), x
        out["rebuild"] = loop(nudge, (state.nbrs, stages.sph_positions(state)))
    return out, phys.dem_substeps


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--base", required=True, help="git revision to compare against")
    ap.add_argument("--cases", nargs="+", default=["elastic_gate", "two_phase_dam_break",
                                                   "fpsi_failure"])
    ap.add_argument("--warm", type=float, default=0.05)
    ap.add_argument("--steps", type=int, default=20)
    ap.add_argument("--reps", type=int, default=9)
    ap.add_argument("--dx", type=float, default=None, help="fluid spacing (dam_break)")
    ap.add_argument("--dem", action="store_true", help="also the DEM part alone")
    ap.add_argument("--rebuild", action="store_true", help="also a forced SPH rebuild")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        sys.path.insert(0, extract(args.base, tmp))
        sys.path.insert(0, ROOT)
        importlib.import_module("fpsi_base")      # sets the XLA flags before jax starts
        importlib.import_module("fpsi_jax")
        import jax
        for case in args.cases:
            fns, subs = {}, {}
            for tag, pkg in (("base", "fpsi_base"), ("tree", "fpsi_jax")):
                got, subs[tag] = chunks(pkg, case, args.warm, args.steps, args.dem,
                                        args.rebuild, args.dx)
                fns.update({(tag, k): v for k, v in got.items()})
            walls = {k: [] for k in fns}
            for _ in range(args.reps):
                for k, (fn, start) in fns.items():
                    t0 = time.perf_counter()
                    jax.block_until_ready(fn(start))
                    walls[k].append(time.perf_counter() - t0)
            for (tag, what), v in walls.items():
                ms = 1e3 * statistics.median(v) / args.steps
                extra = (f"  ({ms * 1e3 / subs[tag]:.1f} us a sub-step)"
                         if what == "dem" else "")
                print(f"{case:22s} {what:8s} {tag:5s} {ms:7.3f} ms a step{extra}", flush=True)


if __name__ == "__main__":
    main()
