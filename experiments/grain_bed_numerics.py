"""How still the grain bed's tank is with and without the bed, for the numerical settings
that decide an SPH tank's rest: the boundary spacing against the fluid's, h/Δx and the
artificial viscosity α.

For each setting: `grain_bed_at_rest`'s four figures for both packings (pore pressure L1,
largest fluid speed in the last quarter, largest grain speed there, floor load against the
bed's buoyant weight; `grain_bed.bed_metrics`) and, as the control, the same tank of water
without grains (`hydrostatic_tank` 0.0504 × 0.1008 m at Δx 2.4 mm): its largest speed in the
last quarter and in each tenth of the run, relative to √(gH): how still these numerics
keep water alone, against which the bed's fluid is read.

    .venv/bin/python experiments/grain_bed_numerics.py [--t-end 2] [--jobs 2]

writes experiments/results/grain_bed_numerics.csv (about 25 min on 2 cores, two runs at a
time)
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor

from _table import write_rows

# (label, grain_bed keywords); the water control takes the same boundary spacing, h and α
SETTINGS = [
    ("W6.2.2 numerics: boundary 1.5 mm, h 1.25 dx, alpha 0.02", {}),
    ("boundary spacing = dx", {"dx_boundary": 0.0024}),
    ("h 1.5 dx, alpha 0.1", {"h0": 0.0036, "alpha_av": 0.1}),
    ("h 1.5 dx, alpha 0.1, boundary spacing = dx",
     {"h0": 0.0036, "alpha_av": 0.1, "dx_boundary": 0.0024}),
]

_BED = """
import json, sys
from fpsi_jax import cases
from fpsi_jax.cases.grain_bed import bed_observer, bed_metrics
from fpsi_jax.run.driver import simulate
kw = json.loads(sys.argv[1])
scene = cases.build("grain_bed", **kw)
res = simulate(scene, progress=False, observe=bed_observer)
p, vf, vs, load = bed_metrics(scene, res)
print(json.dumps(dict(pore_pressure_l1=p, fluid_max_v=vf, grain_max_v=vs, floor_load=load)))
"""

_WATER = """
import json, sys, numpy as np, jax.numpy as jnp
from fpsi_jax import cases
from fpsi_jax.run.driver import simulate
kw = json.loads(sys.argv[1])
scene = cases.build("hydrostatic_tank", **kw)
res = simulate(scene, progress=False,
               observe=lambda s: jnp.max(jnp.sqrt(jnp.sum(s.fluid.v ** 2, -1))))
v = np.asarray(res.observations, float) / np.sqrt(9.81 * kw["depth"])
n = len(v)
print(json.dumps(dict(water_max_v_last_quarter=float(v[int(0.75 * n):].max()),
                      water_max_v_tenths=[round(float(v[i * n // 10:(i + 1) * n // 10].max()), 4)
                                          for i in range(10)])))
"""


def _run(code, kw):
    out = subprocess.run([sys.executable, "-c", code, json.dumps(kw)], capture_output=True,
                         text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--t-end", type=float, default=2.0)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--out", default="experiments/results/grain_bed_numerics.csv")
    a = ap.parse_args()
    jobs = []
    for label, kw in SETTINGS:
        for packing in ("hex", "random"):
            jobs.append((label, packing, _BED, {**kw, "packing": packing, "t_end": a.t_end}))
        dx = 0.0024
        water = dict(depth=0.1008, width=0.0504, dx=dx,
                     dx_boundary=kw.get("dx_boundary", 0.0015),
                     h_factor=kw.get("h0", 0.003) / dx, alpha=kw.get("alpha_av", 0.02),
                     delta=0.1, t_end=a.t_end)
        jobs.append((label, "water only", _WATER, water))
    with ThreadPoolExecutor(a.jobs) as pool:
        results = list(pool.map(lambda j: _run(j[2], j[3]), jobs))
    rows = []
    for (label, what, _, kw), res in zip(jobs, results):
        row = dict(setting=label, run=what, t_end=a.t_end, **res)
        if "water_max_v_tenths" in row:
            row["water_max_v_tenths"] = " ".join(f"{x:.4f}" for x in row["water_max_v_tenths"])
        rows.append(row)
        print(row, flush=True)
    write_rows(a.out, rows)


if __name__ == "__main__":
    main()
