"""Cantilever (K6.3.3) static tip deflection for every stiffness mapping and packing.

5 mm × 79.375 mm rubber strip, E = 10 MPa, ν = 0.33, 1 N at the tip, discs d = 1.25 mm,
local damping 0.7 to the static state. Reference: Euler–Bernoulli PL³/(3EI) = 1.600 mm with
the nominal length, and with the as-built span (last clamped disc centre → loaded tip discs).

    .venv/bin/python experiments/cantilever_mappings.py [--d 0.00125]

writes experiments/results/cantilever_mappings.csv
"""
from __future__ import annotations

import argparse
import csv
import os
import time

from fpsi_jax.cases.cantilever import cantilever_static, tip_deflection

CASES = [("square", "k42_split"), ("square", "k42"), ("hex", "lattice"), ("hex", "k42"),
         ("hex", "k42_plate"), ("hex", "k42_split")]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--d", type=float, default=0.00125)
    ap.add_argument("--out", default="experiments/results/cantilever_mappings.csv")
    a = ap.parse_args()
    rows = []
    for packing, mapping in CASES:
        t0 = time.perf_counter()
        val, settle, scene, res, wall = cantilever_static(
            {"packing": packing, "mapping": mapping, "d": a.d})
        kw = scene.builder_kwargs
        ref = tip_deflection(kw["load"], kw["length"], kw["E"], kw["height"])
        span = kw["length"] - float(scene.solid.x[scene.solid.fixed, 0].max())
        ref_b = tip_deflection(kw["load"], span, kw["E"], kw["height"])
        row = dict(packing=packing, mapping=mapping, d=a.d, n_discs=scene.solid.n,
                   n_bonds=scene.bonds.n, deflection_mm=val * 1e3, reference_mm=ref * 1e3,
                   error_vs_nominal=val / ref - 1, span_mm=span * 1e3,
                   reference_as_built_mm=ref_b * 1e3, error_vs_as_built=val / ref_b - 1,
                   last_10pct_change=settle, steps=res.n_steps, wall_s=wall,
                   steps_per_s=res.n_steps / wall)
        rows.append(row)
        print(f"{packing:6s} {mapping:10s} {val * 1e3:.4f} mm  vs 1.600: {row['error_vs_nominal']:+.2%}"
              f"  vs as-built {ref_b * 1e3:.4f}: {row['error_vs_as_built']:+.2%}  "
              f"({res.n_steps} steps, {wall:.0f} s)", flush=True)
    os.makedirs(os.path.dirname(a.out), exist_ok=True)
    with open(a.out, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    print("wrote", a.out)


if __name__ == "__main__":
    main()
