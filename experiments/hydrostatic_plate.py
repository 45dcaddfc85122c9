"""Plate clamped at both ends under still water (K6.3.3) at the seed's resolution.

    python experiments/hydrostatic_plate.py [--coarse] [--shear-factors 20 1]

For each shear_factor: the midpoint deflection history, the settled mean (last quarter of the
run) against K44 (thin plate) and K44 + Timoshenko shear for the strip's shear modulus.
Writes experiments/results/hydrostatic_plate.{json,png}.
"""
from __future__ import annotations

import argparse
import json
import os
import time

import numpy as np

from fpsi_jax.cases import overrides as ov
from fpsi_jax.cases.hydrostatic_plate import plate_deflection, plate_reference, plate_run

OUT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "results")

if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--coarse", action="store_true")
    ap.add_argument("--shear-factors", type=float, nargs="*", default=[20.0, 1.0])
    ap.add_argument("--coupling", default="extrapolated")
    ap.add_argument("--t-end", type=float, default=0.5)
    args = ap.parse_args()
    os.makedirs(OUT, exist_ok=True)
    base = dict(dx=0.0035, d=0.0025, dx_boundary=0.0025) if args.coarse else {}
    rows, series = [], []
    for sf in args.shear_factors:
        scene, phys = ov.build("hydrostatic_plate", {**base, "shear_factor": sf,
                                                     "coupling": args.coupling,
                                                     "t_end": args.t_end})
        t0 = time.perf_counter()
        w, t, w_late, res = plate_run(scene, **phys)
        wall = time.perf_counter() - t0
        kw = scene.builder_kwargs
        k44 = plate_deflection(kw["span_built"], kw["thickness_built"],
                               kw["water_height_built"], kw["E"], kw["nu"], kw["rho_water"],
                               kw["rho_plate"])
        ref = plate_reference(kw)
        row = {"shear_factor": sf, "coupling": args.coupling, "w_settled_m": w_late,
               "K44_m": k44, "K44_plus_shear_m": ref, "err_vs_K44": w_late / k44 - 1,
               "err_vs_K44_plus_shear": w_late / ref - 1, "wall_s": wall,
               "sph_steps": res.n_steps, "dem_substeps": res.physics.dem_substeps,
               "dt_s": float(res.params.dt), "n_fluid": scene.fluid.n,
               "n_boundary": scene.boundary.n, "n_discs": scene.solid.n,
               "dx": kw["dx"], "d": kw["d"], "t_end": args.t_end}
        rows.append(row)
        series.append((sf, t, w, ref))
        print(json.dumps(row), flush=True)
    name = "hydrostatic_plate_coarse" if args.coarse else "hydrostatic_plate"
    with open(os.path.join(OUT, f"{name}.json"), "w") as fh:
        json.dump(rows, fh, indent=1)
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(7, 4))
    for sf, t, w, ref in series:
        line, = ax.plot(t, w * 1e3, lw=1, label=f"fpsi-jax, shear_factor {sf:g}")
        ax.axhline(ref * 1e3, color=line.get_color(), ls="--", lw=0.8,
                   label=f"K44 + shear ({ref * 1e3:.4f} mm)")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("midpoint deflection [mm]")
    ax.set_title("Plate under still water (K6.3.3)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(os.path.join(OUT, f"{name}.png"), dpi=120)
