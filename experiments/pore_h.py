"""How far the pore water's smoothing length grows in a run (Physics.pore_neighbours):
per output frame, the largest h against the scene's h0, how many fluid particles have
h > 1.05 h0, and the least voidage a fluid particle sees.

    fpsi run experiments/scenes/dry_bed.toml --out dry.h5
    python experiments/pore_h.py dry.h5 [--name dry_bed]

writes experiments/results/pore_h_<name>.csv.
"""
from __future__ import annotations

import argparse
import os

import h5py
import numpy as np

from _table import write_rows


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("h5")
    ap.add_argument("--name", default="dry_bed")
    a = ap.parse_args()
    rows = []
    with h5py.File(a.h5, "r") as f:
        frames = f["frames"]
        keys = sorted(frames.keys())
        h0 = float(np.median(frames[keys[0]]["fluid"]["h"][:]))
        for t, k in zip(f["time"][:], keys):
            fl = frames[k]["fluid"]
            h, eps = fl["h"][:], fl["eps"][:]
            rows.append({"t": round(float(t), 4), "h_max_over_h0": round(float(h.max()) / h0, 3),
                         "n_above_1.05_h0": int(np.sum(h > 1.05 * h0)), "n_fluid": int(h.size),
                         "eps_min": round(float(eps.min()), 3)})
    out = os.path.join(os.path.dirname(os.path.abspath(__file__)), "results",
                       f"pore_h_{a.name}.csv")
    write_rows(out, rows)
    for r in rows:
        print(r)
    print("->", out)


if __name__ == "__main__":
    main()
