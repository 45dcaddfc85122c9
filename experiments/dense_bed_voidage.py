"""The two-phase dam break (W6.2.2) and the FPSI failure cases I and II (W6.3) at the beds'
own voidage (no floor) against a floor of 0.8, for each fluid voidage ('area', 'mapped')
and grain pressure ('archimedes', 'shared'): how far each run gets, and its fronts or
broken bonds there. A variant is voidage:floor:pressure.

    .venv/bin/python experiments/dense_bed_voidage.py [--t-end 0.2]
        [--variants area:0:shared mapped:0.8:archimedes] [--scenes ...] [--out FILE]

writes experiments/results/dense_bed_voidage.csv (2–4 min a run on 2 cores); the builders'
defaults are the first variant, area:0:shared.
"""
from __future__ import annotations

import argparse
import time

import jax.numpy as jnp
import numpy as np

from fpsi_jax import cases
from fpsi_jax.model.errors import SimulationError
from fpsi_jax.run.driver import simulate

from _table import write_rows


def observe(state):
    """(rightmost fluid x, rightmost grain x, intact bonds)."""
    xg = state.solid.x[state.fpi.idx, 0]
    n_int = jnp.sum(state.bonds.intact) if state.bonds is not None else jnp.asarray(0)
    return jnp.max(state.fluid.x[:, 0]), jnp.max(xg), n_int


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--t-end", type=float, default=0.2)
    ap.add_argument("--variants", nargs="+",
                    default=["area:0:shared", "mapped:0.8:archimedes", "mapped:0.8:shared"])
    ap.add_argument("--scenes", nargs="+", default=["two_phase_dam_break", "fpsi_failure:I",
                                                    "fpsi_failure:II"])
    ap.add_argument("--out", default="experiments/results/dense_bed_voidage.csv")
    a = ap.parse_args()
    rows = []
    for spec in a.scenes:
        name, _, variant = spec.partition(":")
        extra = {"case": variant} if variant else {}
        for v in a.variants:
            voidage, floor, pressure = v.split(":")
            floor = float(floor)
            kw = dict(extra, voidage=voidage, eps_floor=floor, t_end=a.t_end)
            scene = cases.build(name, **kw)
            t0 = time.perf_counter()
            row = dict(scene=spec, voidage=voidage, eps_floor=floor,
                       fpi_pressure=pressure)
            try:
                res = simulate(scene, progress=False, observe=observe,
                               fpi_pressure=pressure)
                xf, xg, n_int = (np.asarray(o) for o in res.observations)
                row.update(reached_s=a.t_end, failed="", fluid_front_m=float(xf[-1]),
                           grain_front_m=float(xg[-1]),
                           broken_bonds=int(scene.bonds.n - n_int[-1])
                           if scene.bonds is not None else "")
            except SimulationError as e:
                row.update(reached_s=float(e.time), failed=e.quantity)
            row["wall_s"] = time.perf_counter() - t0
            rows.append(row)
            print(row, flush=True)
    keys = ["scene", "voidage", "eps_floor", "fpi_pressure", "reached_s", "failed",
            "fluid_front_m", "grain_front_m", "broken_bonds", "wall_s"]
    write_rows(a.out, rows, keys)


if __name__ == "__main__":
    main()
