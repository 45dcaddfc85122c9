"""Fluid–particle–structure interaction with failure (W6.3), cases I (σ̄_c = 4e4 Pa) and II
(2e4 Pa) to 0.2 s.

    python experiments/fpsi_failure.py [--cases I II] [--set key=value ...]

Writes experiments/results/fpsi_failure.json (first failure, broken bonds, pieces, run
time per case), fpsi_failure_breaks_<case>.csv (broken bonds and pieces vs time) and
fpsi_failure_<case>.png (snapshots at 0, 0.05, ..., 0.2 s with the intact bonds).
A "piece" is a connected set of structure discs joined by intact bonds (single discs count).
"""
from __future__ import annotations

import argparse
import json
import os
import tempfile
import time

import numpy as np

from fpsi_jax.cases import overrides as ov
from fpsi_jax.run import io
from fpsi_jax.run.driver import setup, simulate

try:
    from two_phase_dam_break import snapshots
except ImportError:   # run from the repository root
    from experiments.two_phase_dam_break import snapshots

OUT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "results")


def pieces(n_struct, first, i, j, intact):
    """Number of connected pieces of the structure (discs first .. first+n_struct−1)."""
    parent = np.arange(n_struct)

    def find(a):
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    for a, b in zip(i[intact] - first, j[intact] - first):
        ra, rb = find(a), find(b)
        if ra != rb:
            parent[ra] = rb
    return len({find(a) for a in range(n_struct)})


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--cases", nargs="+", default=["I", "II"])
    ap.add_argument("--set", action="append", default=[])
    ap.add_argument("--dt-factor", type=float, default=1.0,
                    help="time step as a fraction of the derived bound")
    args = ap.parse_args()
    os.makedirs(OUT, exist_ok=True)
    out, curves = {}, {}
    for case in args.cases:
        scene, phys = ov.build("fpsi_failure", {"case": case, **ov.parse_pairs(args.set)})
        b = scene.builder_kwargs
        h5 = os.path.join(tempfile.mkdtemp(), f"fpsi_failure_{case}.h5")
        t0 = time.perf_counter()
        dt = args.dt_factor * float(setup(scene, **phys)[1].dt)
        res = simulate(scene, output=h5, every=0.01, progress=False, dt=dt, overwrite=True, **phys)
        wall = time.perf_counter() - t0
        run = io.read(h5)
        tb = np.asarray(run.breaks.get("time", []))
        mode = np.asarray(run.breaks.get("mode", []))
        first = int(scene.solid.n - scene.solid.structure_indices().size)
        n_struct = int(scene.solid.structure_indices().size)
        i, j = run.bonds["i"], run.bonds["j"]
        n_pieces = [pieces(n_struct, first, i, j, run.bonds["intact"][k].astype(bool))
                    for k in range(run.frames)]
        curves[case] = np.stack([run.time, [np.sum(tb <= t) for t in run.time], n_pieces], 1)
        out[case] = {"sigma_c": b["sigma_c"], "tau_c": b["tau_c"], "wall_s": wall,
                     "dt_factor": args.dt_factor,
                     "sph_steps": res.n_steps, "dt": float(res.params.dt),
                     "dem_substeps": res.physics.dem_substeps,
                     "particle_steps_per_s": res.particle_steps_per_s,
                     "n_fluid": scene.fluid.n, "n_discs": scene.solid.n,
                     "n_structure_discs": n_struct, "n_bonds": scene.bonds.n,
                     "first_failure_s": float(tb.min()) if tb.size else None,
                     "broken_at_end": int(tb.size), "tension": int(np.sum(mode == 1)),
                     "shear": int(np.sum(mode == 2)), "pieces_at_end": n_pieces[-1],
                     "broken_at": {f"{t:.2f}": int(np.sum(tb <= t))
                                   for t in (0.05, 0.1, 0.15, 0.2)}}
        print(case, json.dumps(out[case]))
        from matplotlib.collections import LineCollection

        def bonds_on(ax, run, k):
            ok = run.bonds["intact"][k].astype(bool)
            xs = run.solid["x"][k]
            ax.add_collection(LineCollection(np.stack([xs[i[ok]], xs[j[ok]]], 1), colors="k",
                                             linewidths=0.3))

        keep = sorted({int(np.argmin(np.abs(run.time - m))) for m in np.arange(0.0, 0.201, 0.05)
                       if m <= run.time[-1] + 1e-6})
        sub = io.Run(**{**run.__dict__, "time": run.time[keep],
                        "fluid": {k: v[keep] for k, v in run.fluid.items()},
                        "solid": {k: (v[keep] if v.ndim > 1 else v) for k, v in run.solid.items()},
                        "bonds": {k: (v[keep] if v.ndim > 1 else v) for k, v in run.bonds.items()}})
        fig, _ = snapshots(sub, scene, f"FPSI with failure, case {case}: sigma_c = "
                           f"{b['sigma_c']:.3g} Pa", (-0.005, b["tank_length"] + 0.005),
                           (-0.005, 0.12))
        for ax, k in zip(fig.axes, range(sub.frames)):
            bonds_on(ax, sub, k)
        fig.savefig(os.path.join(OUT, f"fpsi_failure_{case}.png"), dpi=110)
        path = os.path.join(OUT, "fpsi_failure.json")
        old = json.load(open(path)) if os.path.exists(path) else {}
        with open(path, "w") as fh:
            json.dump({**old, case: out[case]}, fh, indent=1)
        np.savetxt(os.path.join(OUT, f"fpsi_failure_breaks_{case}.csv"), curves[case],
                   delimiter=",", header="t_s,broken,pieces", comments="", fmt="%.4g")
