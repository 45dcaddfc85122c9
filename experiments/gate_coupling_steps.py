"""Why a structure coupled to the fluid keeps physics.md's step coefficients.

    python experiments/gate_coupling_steps.py                      # the default grid
    python experiments/gate_coupling_steps.py 0.25,0.2 0.875,0.55   # SPH,DEM coefficient pairs
    python experiments/gate_coupling_steps.py --seed 0.125,0.1 0.25,0.2 0.375,0.2 0.5,0.2

The coarse elastic gate (fluid 3.5 mm, discs 2.5 mm) run for 0.36 s with the SPH step at
``sph`` h/(c0 + |v|) and the DEM sub-step at ``dem`` √(m/k) (the derived ones are 0.25 and
0.2, ``solver.timestep.FSI_SPH_CFL`` and ``FSI_DEM_DT_FACTOR``; a fluid-only or DEM-only scene
gets 0.875 and 0.55). Records the peak tip ux, its time and the RMS of ux, uy against the
experiment (relative to its peak), as ``fpsi validate`` measures them. ``--seed`` runs the
seed-resolution gate (8 048 particles, 0.4 s; 1–4 min a pair) into
gate_coupling_steps_seed.json instead. The converged
answer (half of both derived steps) is the reference: the question is which larger steps
keep it. Writes experiments/results/gate_coupling_steps.json (merged per pair).
"""
from __future__ import annotations

import json
import math
import os
import sys
import time

import numpy as np

from fpsi_jax import cases
from fpsi_jax.cases.elastic_gate import GATE_COARSE, gate_metrics, tip_displacement, tip_observer
from fpsi_jax.model.errors import SimulationError
from fpsi_jax.run.driver import simulate
from fpsi_jax.solver import timestep

HERE = os.path.dirname(os.path.abspath(__file__))
OUT = os.path.join(HERE, "results", "gate_coupling_steps.json")
DEFAULT = ("0.125,0.1", "0.25,0.2", "0.25,0.55", "0.375,0.2", "0.375,0.55", "0.5,0.2",
           "0.5,0.55", "0.875,0.2", "0.875,0.55")


def run(sph_c: float, dem_c: float, t_end: float = 0.36, seed: bool = False,
        with_acc: bool = False) -> dict:
    sc = cases.build("elastic_gate", **({} if seed else GATE_COARSE))
    p = sc.params
    dt = timestep.sph_dt(sc, p) * sph_c / timestep.FSI_SPH_CFL
    sub = timestep.dem_dt(sc, p) * dem_c / timestep.FSI_DEM_DT_FACTOR
    n = max(1, math.ceil(dt / sub - 1e-9))
    t0 = time.perf_counter()
    res = simulate(sc, t_end, dt=dt, dem_substeps=n, unsafe_dt=True, progress=False,
                   observe=tip_observer(sc), structure_acceleration=with_acc)
    m = gate_metrics(*tip_displacement(sc, res))
    return {"sph_cfl": sph_c, "dem_factor": dem_c, "dt": dt, "dem_substeps": n,
            "peak_ux_mm": 1e3 * m["peak_ux_m"], "t_peak_s": m["t_peak_s"],
            "rms_ux_rel_peak": m["rms_ux_rel_peak"], "rms_uy_rel_peak": m["rms_uy_rel_peak"],
            "wall_s": time.perf_counter() - t0}


def main(pairs, seed=False, with_acc=False):
    path = OUT.replace(".json", "_seed.json") if seed else OUT
    if with_acc:
        path = path.replace(".json", "_with_acc.json")
    out = json.load(open(path)) if os.path.exists(path) else {}
    for spec in pairs:
        s, d = map(float, spec.split(","))
        try:
            row = run(s, d, 0.4 if seed else 0.36, seed, with_acc)
        except SimulationError as err:       # a step past the stable one: record where
            row = {"sph_cfl": s, "dem_factor": d, "unstable": str(err)}
        out[f"{s:g},{d:g}"] = row
        print(json.dumps(row), flush=True)
        with open(path, "w") as fh:
            json.dump(out, fh, indent=1)
    return out


if __name__ == "__main__":
    args = sys.argv[1:]
    seed = "--seed" in args
    with_acc = "--structure-acceleration" in args
    args = [a for a in args if a not in ("--seed", "--structure-acceleration")]
    main(args or DEFAULT, seed, with_acc)
