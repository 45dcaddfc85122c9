"""Speed of the full-physics SPH dam break: particle-steps per second at about 5k, 20k and
80k particles on this machine, with neighbour rebuilds and compile time.

    .venv/bin/python experiments/bench_sph.py [--steps 200] [--reps 5] [--out FILE]

Each row: compile (timed alone), one warm-up chunk (excluded), then ``reps`` chunks of
``steps`` steps, every one from the same warmed-up state (the same work); it reports the
median chunk (``particle_steps_per_s``) and the fastest (``best_particle_steps_per_s``): on
this shared 2-core machine one chunk alone varied by up to 40 % from one run to the next. A
chunk whose neighbour lists overflow is grown and redone (``run_until_fits``, as the driver
does); the redone chunk is the recompiled program's warm-up and the timing starts again.
Writes experiments/results/bench_sph.json (``--out``: another path). Particle count = fluid
+ boundary particles (every particle sits in the neighbour list; only fluid rows are
summed).
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import statistics

import jax
import jax.numpy as jnp

from fpsi_jax import cases, solver
from fpsi_jax.run.driver import setup
from fpsi_jax.solver import timestep

from _bench import compile_and_warm_up, timed_chunks

HERE = os.path.dirname(os.path.abspath(__file__))


def bench(dx, steps, old_step=False, reps=5, **phys_opts):
    """``old_step``: physics.md's 0.25 h/(c0+|v|) and the 0.25 h skin that went with it,
    instead of the default 0.875 h/(c0+|v|) and 0.4 h skin."""
    sc = cases.build("dam_break", dx=dx)
    dt = timestep.stable_dt(sc) * 0.25 / timestep.SPH_CFL if old_step else None
    if old_step:
        phys_opts = {"skin": 0.25, **phys_opts}
    phys, params = setup(sc, dt, **phys_opts)
    p = params.as_arrays(jnp.float32)
    st = solver.init_state(sc, phys, p)
    # warm up into the flow (the column has started to move) before timing
    phys, st, chunk, compile_s = compile_and_warm_up(phys, st, p, steps)
    phys, start, end, walls, regrowths = timed_chunks(chunk, phys, st, reps)
    wall, best = statistics.median(walls), min(walls)
    n = sc.fluid.n + sc.boundary.n
    return {"dx": dx, "n_fluid": sc.fluid.n, "n_boundary": sc.boundary.n, "n_particles": n,
            "neighbour_capacity": int(end.nbrs.idx.shape[1]), "steps": steps,
            "wall_s": wall, "wall_s_chunks": walls, "compile_s": compile_s,
            "particle_steps_per_s": n * steps / wall,
            "best_particle_steps_per_s": n * steps / best,
            "fluid_particle_steps_per_s": sc.fluid.n * steps / wall,
            "rebuilds": int(end.status.rebuilds) - int(start.status.rebuilds),
            "regrowths_while_timing": regrowths, "dt": float(params.dt),
            "skin_over_h": float(phys.neighbors.skin / sc.fluid.h.min()),
            "old_step": old_step, "mechanisms": list(phys.mechanisms())}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--steps", type=int, default=200)
    ap.add_argument("--reps", type=int, default=5, help="timed chunks per row (median, best)")
    ap.add_argument("--dx", type=float, nargs="*", default=[0.0029, 0.00145, 0.00072])
    ap.add_argument("--no-old-step", action="store_true",
                    help="skip the rows at physics.md's step (0.25 h/(c0+|v|), skin 0.25 h)")
    ap.add_argument("--out", default=os.path.join(HERE, "results", "bench_sph.json"),
                    help="JSON file written (default experiments/results/bench_sph.json)")
    args = ap.parse_args()
    rows = []
    for dx, old in [(dx, old) for old in ((False,) if args.no_old_step else (False, True))
                    for dx in args.dx]:
        r = bench(dx, args.steps, old_step=old, reps=args.reps)
        rows.append(r)
        print(f"{'old step ' if old else ''}"
              f"dx={dx * 1e3:.2f} mm  N={r['n_particles']:6d}  K={r['neighbour_capacity']}  "
              f"{r['particle_steps_per_s'] / 1e6:.2f} M particle-steps/s "
              f"(best {r['best_particle_steps_per_s'] / 1e6:.2f})  "
              f"rebuilds {r['rebuilds']}/{args.steps}  compile {r['compile_s']:.1f} s",
              flush=True)
    out = {"machine": {"cpu_count": os.cpu_count(), "platform": platform.platform(),
                       "jax": jax.__version__, "backend": jax.default_backend()},
           "case": "dam_break (full physics: continuity, EOS, pressure + anti-clump, Morris "
                   "viscosity, artificial viscosity, XSPH, variable h, delta-SPH, "
                   "extrapolated boundary)",
           "peer_bar": "DualSPHysics CPU (2 threads), 5.5k-particle 2D dam break: 3.7 M",
           "xla_flags": os.environ.get("XLA_FLAGS", ""),
           "timing": f"median (and best) of {args.reps} chunks of {args.steps} steps from "
                     "the same warmed-up state",
           "rows": rows}
    os.makedirs(os.path.dirname(os.path.abspath(args.out)), exist_ok=True)
    with open(args.out, "w") as fh:
        json.dump(out, fh, indent=1)


if __name__ == "__main__":
    main()
