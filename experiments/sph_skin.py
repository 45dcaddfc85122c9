"""The SPH list's skin against the size of the scene: cost per particle-step of the dam
break at several skins, every size timed from the same simulated time, interleaved in one
process.

    .venv/bin/python experiments/sph_skin.py [--dx 0.00145 0.00051] [--skins 0.4 0.55 0.7]
                                             [--t-from 0.05] [--steps 100] [--reps 5]

A wider skin (× h, ``Physics`` option ``skin``; the default 0.4 h was measured at 6.9k and
24k particles) lists more pairs, K ∝ (2h + skin)², and rebuilds the list less often:
particles may move skin/2 about a common centre between builds. For each dx: the
full-physics dam break (as bench_sph.py) at the derived step, run to ``--t-from`` with the
default skin, then, from that state, the list allocated afresh at each skin, one warm-up
chunk each (lists grown if they overflow), and ``--reps`` rounds of one chunk of each skin,
alternating; the median chunk of each. Writes experiments/results/sph_skin.csv.
"""
from __future__ import annotations

import argparse
import csv
import os
import statistics

import jax.numpy as jnp

from fpsi_jax import cases, solver
from fpsi_jax.run.driver import run_until_fits, setup
from fpsi_jax.solver import neighbors, stages

from _bench import compile_and_warm_up

HERE = os.path.dirname(os.path.abspath(__file__))


def fresh_list(phys, st):
    return st.replace(nbrs=neighbors.allocate(phys.neighbors, stages.sph_positions(st)))


def rows_for(dx, skins, steps, reps, t_from):
    sc = cases.build("dam_break", dx=dx)
    phys, params = setup(sc)
    p = params.as_arrays(jnp.float32)
    st = solver.init_state(sc, phys, p)
    phys, st, chunk, _ = compile_and_warm_up(phys, st, p, steps)
    while float(st.t) < t_from:
        c = run_until_fits(chunk, phys, st, chunk.dt)
        phys, st = c.phys, c.end
    start, chunks = {}, {}
    for s in skins:                 # each skin's list and program, grown until it fits
        ph, _ = setup(sc, skin=s)
        chunks[s] = type(chunk)(p, steps)
        c = run_until_fits(chunks[s], ph, fresh_list(ph, st), chunk.dt)
        start[s] = (c.phys, c.state)
    walls, ends = {s: [] for s in skins}, {}
    for _ in range(reps):
        for s in skins:
            ph, s0 = start[s]
            end, wall = chunks[s](ph, s0)
            walls[s].append(wall)
            ends[s] = end
    n = sc.fluid.n + sc.boundary.n
    out = []
    for s in skins:
        ph, s0 = start[s]
        m = statistics.median(walls[s]) / steps
        out.append({"dx": dx, "n_particles": n, "t_from": float(s0.t), "skin_h": s,
                    "neighbour_capacity": int(s0.nbrs.idx.shape[1]), "steps": steps,
                    "rebuilds": int(ends[s].status.rebuilds - s0.status.rebuilds),
                    "overflowed": bool(ends[s].status.overflow),
                    "ms_per_step": m * 1e3, "ns_per_particle_step": m / n * 1e9,
                    "ms_per_step_all": [round(w / steps * 1e3, 3) for w in walls[s]]})
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--dx", type=float, nargs="*", default=[0.00145, 0.00051])
    ap.add_argument("--skins", type=float, nargs="*", default=[0.4, 0.55, 0.7])
    ap.add_argument("--steps", type=int, default=100)
    ap.add_argument("--reps", type=int, default=5)
    ap.add_argument("--t-from", type=float, default=0.05)
    ap.add_argument("--out", default=os.path.join(HERE, "results", "sph_skin.csv"))
    args = ap.parse_args()
    rows = []
    for dx in args.dx:
        for r in rows_for(dx, args.skins, args.steps, args.reps, args.t_from):
            rows.append(r)
            print(f"dx={dx * 1e3:.2f} mm N={r['n_particles']:7d} skin {r['skin_h']} h "
                  f"K={r['neighbour_capacity']}: {r['ns_per_particle_step']:.0f} ns a "
                  f"particle-step, rebuilds {r['rebuilds']}/{args.steps}", flush=True)
    os.makedirs(os.path.dirname(os.path.abspath(args.out)), exist_ok=True)
    with open(args.out, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)


if __name__ == "__main__":
    main()
