"""Dam-break front Z(T) vs Koshizuka & Oka (1996) from a run's HDF5 file.

    .venv/bin/fpsi run dam_break --out results/dam_break.h5 --plot     # (= make run)
    .venv/bin/python experiments/dam_break_front.py results/dam_break.h5

Writes experiments/results/dam_break_front.csv (T, Z_sim, Z_exp where the data has a point)
and copies the run's plot to experiments/results/dam_break.png.
"""
import os
import shutil
import sys

import numpy as np

from fpsi_jax.cases.registry import load_csv
from fpsi_jax.run import io

HERE = os.path.dirname(os.path.abspath(__file__))


def main(path="results/dam_break.h5"):
    run = io.read(path)
    kw = run.scene["builder_kwargs"]
    a, dx = kw["column_width"], kw["dx"]
    T = run.time * np.sqrt(2 * 9.81 / a)
    Z = (run.fluid["x"][:, :, 0].max(axis=1) + 0.5 * dx) / a
    ref = load_csv("koshizuka_oka1996_surge_front.csv")
    ref = ref[ref[:, 0] <= T.max()]
    z = np.interp(ref[:, 0], T, Z)
    os.makedirs(os.path.join(HERE, "results"), exist_ok=True)
    out = os.path.join(HERE, "results", "dam_break_front.csv")
    np.savetxt(out, np.c_[ref, z, (z - ref[:, 1]) / ref[:, 1]], delimiter=",",
               header="T_nondim,Z_exp,Z_sim,rel_error", comments="", fmt="%.5f")
    png = os.path.splitext(path)[0] + ".png"
    if os.path.exists(png):
        shutil.copy(png, os.path.join(HERE, "results", "dam_break.png"))
    for row in np.c_[ref, z, (z - ref[:, 1]) / ref[:, 1]]:
        print("T=%.3f  Z_exp=%.3f  Z_sim=%.3f  err=%+.1f%%" % (*row[:3], 100 * row[3]))


if __name__ == "__main__":
    main(*sys.argv[1:])
