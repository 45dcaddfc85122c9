"""The packed grain bed under still water (the `grain_bed` scene, 4 hexagonal layers) with
each voidage model, floor and grain pressure force ('archimedes', 'shared'): how long it
stays at rest, or how far from rest it is.

    .venv/bin/python experiments/grain_bed_variants.py [--t-end 0.2]

writes experiments/results/grain_bed_variants.csv (about 5 min on 2 cores)
"""
from __future__ import annotations

import argparse
import math
import time

import numpy as np

from fpsi_jax import cases
from fpsi_jax.cases.grain_bed import bed_observer
from fpsi_jax.model.errors import SimulationError
from fpsi_jax.run.driver import simulate

from _table import write_rows

VARIANTS = [(v, f, pres) for pres in ("archimedes", "shared")
            for v, f in (("area", 0.0), ("mapped", 0.0), ("area", 0.5), ("mapped", 0.5),
                         ("mapped", 0.8))]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--t-end", type=float, default=0.2)
    ap.add_argument("--out", default="experiments/results/grain_bed_variants.csv")
    a = ap.parse_args()
    rows = []
    for voidage, floor, pressure in VARIANTS:
        scene = cases.build("grain_bed", voidage=voidage, eps_floor=floor, t_end=a.t_end,
                            fpi_pressure=pressure)
        scale = math.sqrt(9.81 * scene.builder_kwargs["water_height"])
        t0 = time.perf_counter()
        row = dict(voidage=voidage, eps_floor=floor, fpi_pressure=pressure, t_end=a.t_end)
        try:
            res = simulate(scene, progress=False, observe=bed_observer)
            vf, vs, _ = (np.asarray(o, float) for o in res.observations)
            late = slice(int(0.75 * len(vf)), None)
            row.update(failed_at_s="", fluid_vmax_over_sqrt_gH=vf.max() / scale,
                       grain_vmax_over_sqrt_gH=vs.max() / scale,
                       fluid_vmax_last_quarter=vf[late].max() / scale,
                       grain_vmax_last_quarter=vs[late].max() / scale)
        except SimulationError as e:
            row.update(failed_at_s=e.time, fluid_vmax_over_sqrt_gH="",
                       grain_vmax_over_sqrt_gH="", fluid_vmax_last_quarter="",
                       grain_vmax_last_quarter="", quantity=e.quantity)
        row["wall_s"] = time.perf_counter() - t0
        rows.append(row)
        print(row, flush=True)
    write_rows(a.out, rows)


if __name__ == "__main__":
    main()
