"""Speed of the full-physics SPH dam break (issue 2): particle-steps per second at about
5k, 20k and 80k particles on this machine, with neighbour rebuilds and compile time.

    .venv/bin/python experiments/bench_sph.py [--steps 200] [--reps 5]

Each row times ``reps`` chunks of ``steps`` steps, every one from the same warmed-up state
(the same work), and reports the median chunk (``particle_steps_per_s``) and the fastest
(``best_particle_steps_per_s``): on this shared 2-core machine one chunk alone varied by
up to 40 % from one run to the next. Writes experiments/results/bench_sph.json. Particle
count = fluid + boundary particles (every particle sits in the neighbour list; only fluid
rows are summed).
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import statistics

import jax
import jax.numpy as jnp

from fpsi_jax import integrate, scenes
from fpsi_jax.simulate import grow, reallocate, setup

from _bench import compile_and_warm_up, needs_growth, timed_chunk

HERE = os.path.dirname(os.path.abspath(__file__))


def bench(dx, steps, old_step=False, reps=5, **phys_opts):
    """``old_step``: physics.md's 0.25 h/(c0+|v|) and the 0.25 h skin that went with it (the
    figures before issue 7 changed the step to 0.875 h/(c0+|v|) and the skin to 0.4 h)."""
    sc = scenes.build("dam_break", dx=dx)
    dt = integrate.stable_dt(sc) * 0.25 / integrate.SPH_CFL if old_step else None
    if old_step:
        phys_opts = {"skin": 0.25, **phys_opts}
    phys, params = setup(sc, dt, **phys_opts)
    p = params.as_arrays(jnp.float32)
    st = integrate.init_state(sc, phys, p)
    # warm up into the flow (the column has started to move) before timing; lists grown
    # as the driver would if they overflow
    phys, st, compiled, compile_s = compile_and_warm_up(phys, st, p, steps)
    for _ in range(4):               # a timed chunk that overflows is grown and redone
        r0 = int(st.status.rebuilds)
        walls = []
        for _ in range(reps):
            new, wall = timed_chunk(compiled, st, p)
            walls.append(wall)
            if needs_growth(new):
                break
        if not needs_growth(new):
            break
        phys = grow(phys, new)
        phys, st, compiled, _ = compile_and_warm_up(phys, reallocate(phys, st), p, steps)
    wall, best = statistics.median(walls), min(walls)
    st = new
    n = sc.fluid.n + sc.boundary.n
    if bool(st.status.bad) or bool(st.status.overflow):
        raise RuntimeError(f"bench run went bad: code {int(st.status.code)} particle "
                           f"{int(st.status.particle)} step {int(st.status.step)} overflow "
                           f"{bool(st.status.overflow)}")
    return {"dx": dx, "n_fluid": sc.fluid.n, "n_boundary": sc.boundary.n, "n_particles": n,
            "neighbour_capacity": int(st.nbrs.idx.shape[1]), "steps": steps,
            "wall_s": wall, "wall_s_chunks": walls, "compile_s": compile_s,
            "particle_steps_per_s": n * steps / wall,
            "best_particle_steps_per_s": n * steps / best,
            "fluid_particle_steps_per_s": sc.fluid.n * steps / wall,
            "rebuilds": int(st.status.rebuilds) - r0, "dt": float(params.dt),
            "skin_over_h": float(phys.neighbors.skin / sc.fluid.h.min()),
            "old_step": old_step, "mechanisms": list(phys.mechanisms())}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--steps", type=int, default=200)
    ap.add_argument("--reps", type=int, default=5, help="timed chunks per row (median, best)")
    ap.add_argument("--dx", type=float, nargs="*", default=[0.0029, 0.00145, 0.00072])
    ap.add_argument("--no-old-step", action="store_true",
                    help="skip the rows at physics.md's step (0.25 h/(c0+|v|), skin 0.25 h)")
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
    os.makedirs(os.path.join(HERE, "results"), exist_ok=True)
    with open(os.path.join(HERE, "results", "bench_sph.json"), "w") as fh:
        json.dump(out, fh, indent=1)


if __name__ == "__main__":
    main()
