"""Does the order particles are stored in matter to the SPH step's speed? The dam break
with its particles in the builders' lattice order (row by row, nearly cell order), in a
random order (what a long, mixing flow tends to), and sorted by cell (what a sort at each
list rebuild would keep, as DualSPHysics and GPU SPH codes do), timed interleaved in one
process.

    taskset -c 1 .venv/bin/python experiments/particle_order.py [--dx 0.00145 0.00072]
                                                               [--steps 100] [--reps 5]

``--t-mix T`` starts from the flow at time T, its fluid in the order an unsorted run left
it (``--shifting A``: with particle shifting, which the dam break at dx ≤ 1.45 mm needs
past the wall impact). For each dx and each order: the same scene with its fluid (and, for the ``*_all``
orders, boundary) particles permuted before set-up, one warm-up chunk, then ``--reps``
rounds of one chunk of each order from its own warmed-up state, alternating; the median
chunk of each. The physics is the same for every order (a permutation of the same
particles); the rows differ only in which memory the neighbour gathers read. Writes
experiments/results/particle_order.csv.
"""
from __future__ import annotations

import argparse
import csv
import dataclasses
import os
import statistics

import jax.numpy as jnp
import numpy as np

from fpsi_jax import cases, solver
from fpsi_jax.run.driver import run_until_fits, setup

from _bench import compile_and_warm_up

HERE = os.path.dirname(os.path.abspath(__file__))


def cell_order(x, cell):
    """Indices sorting positions by cell, rows of cells along x (the cell list's order)."""
    c = np.floor((x - x.min(axis=0)) / cell).astype(np.int64)
    return np.lexsort((c[:, 0], c[:, 1]))


def row_order(x, band):
    """Indices sorting positions by horizontal bands of height ``band``, then by x: the
    builders' lattice order for a lattice, and its nearest match for scattered particles."""
    b = np.floor((x[:, 1] - x[:, 1].min()) / band).astype(np.int64)
    return np.lexsort((x[:, 0], b))


def morton_order(x, cell):
    """Indices sorting positions along a Z-order curve of cells of size ``cell``."""
    c = np.floor((x - x.min(axis=0)) / cell).astype(np.int64)
    key = np.zeros(len(x), np.int64)
    for bit in range(21):
        key |= ((c[:, 0] >> bit) & 1) << (2 * bit)
        key |= ((c[:, 1] >> bit) & 1) << (2 * bit + 1)
    return np.argsort(key, kind="stable")


def permuted(block, order):
    fields = {f.name: getattr(block, f.name) for f in dataclasses.fields(block)}
    return dataclasses.replace(block, **{k: np.asarray(v)[order] for k, v in fields.items()
                                         if isinstance(v, np.ndarray)
                                         and v.shape[:1] == (block.n,)})


def scene_in_order(sc, dx, order, seed=0):
    rng = np.random.default_rng(seed)
    cell = 2.0 * float(np.max(sc.fluid.h)) * 1.4

    def perm(block):
        x = np.asarray(block.x)
        if order.startswith("random"):
            return rng.permutation(block.n)
        if order.startswith("cells"):
            return cell_order(x, cell)
        if order.startswith("rows"):
            return row_order(x, dx)
        if order.startswith("morton"):
            return morton_order(x, dx)
        return np.arange(block.n)
    fluid = permuted(sc.fluid, perm(sc.fluid))
    boundary = sc.boundary
    if order.endswith("_all"):
        boundary = permuted(sc.boundary, perm(sc.boundary))
    return dataclasses.replace(sc, fluid=fluid, boundary=boundary)


def mixed_scene(dx, t_mix, steps=200, **opts):
    """The dam break as it stands at ``t_mix``: its fluid in the order the run left it
    (run unsorted)."""
    sc = cases.build("dam_break", dx=dx)
    phys, params = setup(sc, sort_fluid=False, **opts)
    p = params.as_arrays(jnp.float32)
    st = solver.init_state(sc, phys, p)
    phys, st, chunk, _ = compile_and_warm_up(phys, st, p, steps)
    while float(st.t) < t_mix:
        c = run_until_fits(chunk, phys, st, chunk.dt)
        phys, st = c.phys, c.end
    f = st.fluid
    keep = np.asarray(f.t_out) < 0 if f.t_out is not None else slice(None)  # not parked
    fluid = dataclasses.replace(sc.fluid, **{k: np.asarray(getattr(f, k), np.float64)[keep]
                                             for k in ("x", "v", "rho", "h", "mass")})
    print(f"dx {dx * 1e3:.2f} mm: the flow at t = {float(st.t):.3f} s", flush=True)
    return dataclasses.replace(sc, fluid=fluid)


def row(dx, steps, reps, orders, t_mix=0.0, **opts):
    runs = {}
    base = mixed_scene(dx, t_mix, **opts) if t_mix > 0 else cases.build("dam_break", dx=dx)
    for order in orders:
        stored, _, sort = order.partition("+")
        sc = scene_in_order(base, dx, stored)
        phys, params = setup(sc, sort_fluid=sort == "sort", **opts)
        p = params.as_arrays(jnp.float32)
        st = solver.init_state(sc, phys, p)
        phys, st, chunk, _ = compile_and_warm_up(phys, st, p, steps)
        runs[order] = (phys, st, chunk)
    walls = {o: [] for o in orders}
    rebuilds = {}
    for _ in range(reps):
        for o, (phys, st, chunk) in runs.items():
            end, wall = chunk(phys, st)
            walls[o].append(wall)
            rebuilds[o] = int(end.status.rebuilds - st.status.rebuilds)
    n = sc.fluid.n + sc.boundary.n
    out = []
    for o in orders:
        m = statistics.median(walls[o]) / steps
        out.append({"dx": dx, "n_particles": n, "t_mix": t_mix, "order": o, "steps": steps,
                    "ms_per_step": 1e3 * m, "ns_per_particle_step": 1e9 * m / n,
                    "particle_steps_per_s": n / m, "rebuilds": rebuilds[o],
                    "neighbour_capacity": int(runs[o][1].nbrs.idx.shape[1])})
        print(f"dx {dx * 1e3:.2f} mm N {n:7d} {o:12s} {1e3 * m:8.3f} ms a step  "
              f"{1e9 * m / n:6.1f} ns a particle-step  rebuilds {rebuilds[o]}", flush=True)
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--dx", type=float, nargs="*", default=[0.00145, 0.00072])
    ap.add_argument("--steps", type=int, default=100)
    ap.add_argument("--reps", type=int, default=5)
    ap.add_argument("--t-mix", type=float, default=0.0,
                    help="start from the flow at this time, its particles as the run left them")
    ap.add_argument("--shifting", type=float, default=0.0,
                    help="particle shifting A (Physics.shifting) for every run")
    ap.add_argument("--orders", nargs="*",
                    default=["built", "cells", "random", "random_all"])
    ap.add_argument("--out", default=os.path.join(HERE, "results", "particle_order.csv"))
    args = ap.parse_args()
    rows = []
    for dx in args.dx:
        rows += row(dx, args.steps, args.reps, args.orders, args.t_mix,
                    shifting=args.shifting)
    with open(args.out, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    print("wrote", args.out)


if __name__ == "__main__":
    main()
