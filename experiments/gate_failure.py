"""The elastic gate with weak bonds (scene ``gate_failure``): fracture sequence.

    python experiments/gate_failure.py [--coarse] [--set sigma_c=1e5 ...]

Writes experiments/results/gate_failure_snapshots.png (fluid, discs, intact bonds at six
times), gate_failure_breaks.csv (broken bonds vs time, by mode) and gate_failure.json.
"""
from __future__ import annotations

import argparse
import json
import os
import tempfile
import time

import numpy as np

from fpsi_jax.cases import overrides as ov
from fpsi_jax.cases.elastic_gate import GATE_COARSE
from fpsi_jax.run import io
from fpsi_jax.run.driver import simulate

OUT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "results")

if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--coarse", action="store_true")
    ap.add_argument("--set", action="append", default=[])
    args = ap.parse_args()
    os.makedirs(OUT, exist_ok=True)
    base = dict(GATE_COARSE) if args.coarse else {}
    scene, phys = ov.build("gate_failure", {**base, **ov.parse_pairs(args.set)})
    h5 = os.path.join(tempfile.mkdtemp(), "gate_failure.h5")
    t0 = time.perf_counter()
    res = simulate(scene, output=h5, every=0.005, progress=False, overwrite=True, **phys)
    wall = time.perf_counter() - t0
    run = io.read(h5)
    brk = run.breaks
    tb, mode = np.asarray(brk.get("time", [])), np.asarray(brk.get("mode", []))
    T = run.time
    counts = np.array([[t, np.sum(tb <= t), np.sum((tb <= t) & (mode == 1)),
                        np.sum((tb <= t) & (mode == 2))] for t in T])
    np.savetxt(os.path.join(OUT, "gate_failure_breaks.csv"), counts, delimiter=",",
               header="t_s,broken,tension,shear", comments="", fmt=["%.4f", "%d", "%d", "%d"])
    info = {"wall_s": wall, "sph_steps": res.n_steps, "dem_substeps": res.physics.dem_substeps,
            "n_bonds": scene.bonds.n, "broken_at_end": int(counts[-1, 1]),
            "first_break_s": float(tb.min()) if tb.size else None,
            "tension": int(counts[-1, 2]), "shear": int(counts[-1, 3]),
            "sigma_c": scene.builder_kwargs["sigma_c"], "tau_c": scene.builder_kwargs["tau_c"],
            "dx": scene.builder_kwargs["dx"], "d": scene.builder_kwargs["d"]}
    print(json.dumps(info))
    with open(os.path.join(OUT, "gate_failure.json"), "w") as fh:
        json.dump(info, fh, indent=1)

    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import LineCollection
    picks = np.linspace(0, len(T) - 1, 6).round().astype(int)
    fig, axes = plt.subplots(2, 3, figsize=(13, 6.5))
    i, j = run.bonds["i"], run.bonds["j"]
    for ax, k in zip(axes.ravel(), picks):
        xf = run.fluid["x"][k]
        ax.scatter(xf[:, 0], xf[:, 1], s=0.5, c="tab:blue")
        ax.scatter(run.boundary["x"][:, 0], run.boundary["x"][:, 1], s=0.3, c="0.6")
        xs = run.solid["x"][k]
        ax.scatter(xs[:, 0], xs[:, 1], s=1.5, c="tab:orange")
        ok = run.bonds["intact"][k].astype(bool)
        ax.add_collection(LineCollection(np.stack([xs[i[ok]], xs[j[ok]]], 1), colors="k",
                                         linewidths=0.4))
        ax.set_xlim(0.0, scene.builder_kwargs["tank_length"])
        ax.set_ylim(-0.005, 0.16)
        ax.set_aspect("equal")
        ax.set_title(f"t = {T[k]:.3f} s, broken {int(counts[k, 1])}/{scene.bonds.n}",
                     fontsize=9)
    fig.suptitle(f"gate_failure: sigma_c = tau_c = {info['sigma_c']:.3g} Pa")
    fig.tight_layout()
    fig.savefig(os.path.join(OUT, "gate_failure_snapshots.png"), dpi=110)
