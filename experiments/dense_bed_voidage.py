"""The two-phase dam break (W6.2.2) and the FPSI failure case I (W6.3) at the beds' own
voidage (no floor) against the builders' floor of 0.8, with the 'archimedes' and 'shared'
grain pressure: how far each run gets, and its fronts or broken bonds there.

    .venv/bin/python experiments/dense_bed_voidage.py [--t-end 0.2] [--floors 0 0.8]
        [--pressures archimedes shared] [--out FILE]

writes experiments/results/dense_bed_voidage.csv; the floored 'archimedes' runs are the
shipped ones (experiments/two_phase_dam_break.py, fpsi_failure.py: 6–10 min each).
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
    ap.add_argument("--floors", type=float, nargs="+", default=[0.0, 0.8])
    ap.add_argument("--pressures", nargs="+", default=["archimedes", "shared"])
    ap.add_argument("--out", default="experiments/results/dense_bed_voidage.csv")
    a = ap.parse_args()
    rows = []
    for name, extra in (("two_phase_dam_break", {}), ("fpsi_failure", {})):
        for floor in a.floors:
            for pressure in a.pressures:
                kw = dict(extra, eps_floor=floor, t_end=a.t_end)
                scene = cases.build(name, **kw)
                t0 = time.perf_counter()
                row = dict(scene=name, eps_floor=floor, fpi_pressure=pressure)
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
    keys = ["scene", "eps_floor", "fpi_pressure", "reached_s", "failed", "fluid_front_m",
            "grain_front_m", "broken_bonds", "wall_s"]
    write_rows(a.out, rows, keys)


if __name__ == "__main__":
    main()
