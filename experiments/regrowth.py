"""How often a run's neighbour lists grow, what grew and what it cost: a scene file run
with ``simulate`` from an empty compile cache (a user's first run), in a fresh process.

    python experiments/regrowth.py [--scene experiments/scenes/breaking_wall.toml]

Each regrowth is a recompile of the step and a redone chunk (driver.run_until_fits);
the lists' final sizes against those ``setup`` gave say which grew. Writes
experiments/results/regrowth.json.
"""
from __future__ import annotations

import argparse
import json
import os
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--scene", default=os.path.join(HERE, "scenes", "breaking_wall.toml"))
    ap.add_argument("--out", default=os.path.join(HERE, "results", "regrowth.json"))
    args = ap.parse_args()
    os.environ["FPSI_CACHE_DIR"] = tempfile.mkdtemp()       # before fpsi_jax is imported
    t0 = time.perf_counter()
    from fpsi_jax import scenefile
    from fpsi_jax.run.driver import setup, simulate
    case = scenefile.load(args.scene)
    start, _ = setup(case.scene)
    res = simulate(case.scene, probes=case.probes, progress=False)
    wall = time.perf_counter() - t0

    def sizes(phys):
        nb, dem = phys.neighbors, phys.dem_neighbors
        return {"sph": {k: getattr(nb, k) for k in ("min_neighbors", "wall_width", "r_cut")}
                if nb else None,
                "dem": {k: getattr(dem, k) for k in ("min_neighbors", "min_cell_capacity")}
                if dem else None}
    row = {"scene": os.path.relpath(args.scene), "process_s": wall,
           "before_stepping_s": wall - res.wall_s, "stepping_s": res.wall_s,
           "regrowths": res.reallocations, "regrowth_chunks": res.regrowth_chunks,
           "regrowth_s": res.regrowth_s, "lists_at_start": sizes(start),
           "lists_at_end": sizes(res.physics),
           "broken_bonds": int(res.probes["broken"][-1, 0])}
    print(json.dumps(row, indent=1))
    with open(args.out, "w") as fh:
        json.dump(row, fh, indent=1)


if __name__ == "__main__":
    main()
