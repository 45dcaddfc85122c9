"""Settling of one disc (W6.2.1) with both drag closures at three fluid resolutions.

Settling velocity (slope of y(t) over 0.2–0.6 s) and RMS(y − y_ref)/fall against Zhang et
al. 2019 (fpsi_jax/data); the seed's resolution is dx = 1.5 mm (fitted to 1.538 mm).

    .venv/bin/python experiments/sedimentation_drag.py [--dx 0.002 0.0015 0.00125 0.001]
        [--drag cylinder sphere] [--h0 0.003] [--no-added-mass] [--out CSV]

writes experiments/results/sedimentation_drag.csv (about 8 min on 2 cores). The smoothing
length h0 is the builder's, 2d = 5 mm, at every dx unless given (W6.2.1's is 3 mm), and
the grain has its added mass unless ``--no-added-mass``; the CSV reports the Shepard
fluid velocity at the grain over 0.2–0.6 s beside the settling velocity.
"""
from __future__ import annotations

import argparse

from fpsi_jax.cases.sedimentation import sedimentation_case

from _table import write_rows


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--dx", type=float, nargs="+", default=[0.002, 0.0015, 0.00125, 0.001])
    ap.add_argument("--drag", nargs="+", default=["cylinder", "sphere"])
    ap.add_argument("--h0", type=float, default=None)
    ap.add_argument("--no-added-mass", action="store_true")
    ap.add_argument("--out", default="experiments/results/sedimentation_drag.csv")
    a = ap.parse_args()
    rows = []
    for dx in a.dx:
        for drag in a.drag:
            over = {"drag": drag, "dx": dx, "added_mass": not a.no_added_mass,
                    **({"h0": a.h0} if a.h0 else {})}
            rms, vel = sedimentation_case(False, over)
            row = dict(drag=drag, added_mass=not a.no_added_mass, dx_mm=dx * 1e3,
                       dx_fitted_mm=rms.params["dx"] * 1e3, h0_mm=rms.params["h0"] * 1e3,
                       rms_over_fall=rms.value, v_settle=vel.value, v_ref=vel.reference,
                       v_error=(vel.value - vel.reference) / vel.reference,
                       fluid_velocity_at_grain=rms.params["fluid_velocity_at_grain"],
                       eps_p_mean=rms.params["eps_p_mean"], wall_s=rms.wall_s)
            rows.append(row)
            print(row, flush=True)
    write_rows(a.out, rows)


if __name__ == "__main__":
    main()
