"""Runs the five application examples (cases that are not validation benchmarks) at their
full resolution, as a user would: ``fpsi run examples/<name>.toml --plot``.

Writes under ``experiments/results/examples/``: each case's probe plot and snapshot
(``<name>.png``, ``<name>_snapshot.png``), its probes as CSV, and ``examples.json`` with
the run's size, wall time and the figures each plot is about (deck load, log travel, baffle
tip deflection, flushing cone, the specimen's peak load, the wave heights). The HDF5 output goes to a temporary folder (tens of MB); the CSV keeps 400 rows.

    python experiments/example_cases.py [--only sediment_flushing] [--t-end 0.1]
"""
from __future__ import annotations

import argparse
import csv
import json
import pathlib
import re
import shutil
import subprocess
import sys
import tempfile
import time

ROOT = pathlib.Path(__file__).resolve().parents[1]
OUT = ROOT / "experiments" / "results" / "examples"
CASES = ("flood_bridge_debris", "sloshing_baffle", "sediment_flushing", "compression",
         "wave_flume")


def read_probes(path):
    with open(path) as f:
        rows = [r for r in csv.reader(f) if r and not r[0].startswith("#")]
    head, body = rows[0], [[float(v) for v in r] for r in rows[1:]]
    return {h: [r[i] for r in body] for i, h in enumerate(head)}


def thin(src, dst, rows=400):
    """Copies a per-step probe CSV keeping about ``rows`` evenly spaced rows."""
    lines = src.read_text().splitlines()
    head = [l for l in lines if l.startswith("#")] + [lines[len([l for l in lines
                                                                  if l.startswith("#")])]]
    body = lines[len(head):]
    step = max(1, len(body) // rows)
    dst.write_text("\n".join(head + body[step - 1::step]) + "\n")


def col(cols, prefix):
    """The first column whose name starts with ``prefix``."""
    return next(v for k, v in cols.items() if k.startswith(prefix))


def figures(name, cols):
    """The few numbers each example is about, from its probes."""
    if name == "flood_bridge_debris":
        fx = col(cols, "deck_load.Fx")
        ux, uy = col(cols, "log.ux"), col(cols, "log.uy")
        return {"deck_peak_Fx_N_per_m": max(fx, key=abs), "log_travel_x_m": ux[-1],
                "log_max_rise_m": max(uy)}
    if name == "sloshing_baffle":
        tip = col(cols, "tip.ux")
        m = col(cols, "load.M")
        return {"tip_max_abs_ux_m": max(abs(v) for v in tip),
                "foot_max_abs_moment_N": max(abs(v) for v in m)}
    if name == "sediment_flushing":
        ux = col(cols, "gate_face.ux")
        bed = [v for k, v in cols.items() if k.startswith("bed")]
        drop = [b[0] - b[-1] for b in bed]
        return {"gate_face_grains_mean_ux_m": ux[-1], "cone_depth_m": max(drop),
                "max_deposit_downstream_m": -min(drop)}
    if name == "compression":
        fy, uy = col(cols, "load.Fy"), col(cols, "platen.uy")
        cracks = col(cols, "cracks")
        k = max(range(len(fy)), key=lambda i: fy[i])
        return {"peak_load_N_per_m": fy[k], "peak_travel_m": -uy[k],
                "bonds_broken_at_peak": cracks[k], "bonds_broken_at_end": cracks[-1],
                "end_load_N_per_m": fy[-1]}
    if name == "wave_flume":
        t = cols["t [s]"]
        out = {}
        for k, v in cols.items():
            if k.startswith("gauge"):            # crest-to-trough over the last 2 s
                late = [y for ti, y in zip(t, v) if ti >= t[-1] - 2.0]
                out[f"{k.split('.')[0]}_H_last_2s_m"] = max(late) - min(late)
        out["piston_max_abs_Fx_N_per_m"] = max(abs(v) for v in col(cols, "piston_load.Fx"))
        return out
    return {}


def run(name, t_end=None):
    tmp = pathlib.Path(tempfile.mkdtemp())
    h5 = tmp / f"{name}.h5"
    cmd = ["fpsi", "run", str(ROOT / "examples" / f"{name}.toml"), "--out", str(h5),
           "--plot", "--quiet"]
    if t_end:
        cmd += ["--t-end", str(t_end)]
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    print(proc.stdout + proc.stderr)
    if proc.returncode:
        return {"rc": proc.returncode, "error": (proc.stdout + proc.stderr).strip()[-400:]}
    OUT.mkdir(parents=True, exist_ok=True)
    for src in (f"{name}.png", f"{name}_snapshot.png"):
        shutil.copy(tmp / src, OUT / src)
    thin(tmp / f"{name}_probes.csv", OUT / f"{name}_probes.csv")
    summary = next(l for l in proc.stdout.splitlines() if " steps of " in l)
    m = re.search(r"(\d+) steps of ([\d.e+-]+) s x (\d+) DEM sub-steps, (\d+) particles",
                  summary)
    rec = {"rc": 0, "process_wall_s": round(wall, 1), "summary": summary}
    if m:
        rec.update(steps=int(m[1]), dt_s=float(m[2]), dem_substeps=int(m[3]),
                   particles=int(m[4]))
    m = re.search(r"stepping ([\d.]+) s", summary)
    if m:
        rec.update(stepping_wall_s=float(m[1]))
    m = re.search(r"([\d.]+) M particle-steps/s", summary)
    if m:
        rec.update(M_particle_steps_per_s=float(m[1]))
    rec.update(figures(name, read_probes(tmp / f"{name}_probes.csv")))
    shutil.rmtree(tmp)
    return rec


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", choices=CASES)
    ap.add_argument("--t-end", type=float, help="shorten every run (a quick look)")
    args = ap.parse_args()
    path = OUT / "examples.json"
    record = json.loads(path.read_text()) if path.exists() else {}
    for name in (args.only,) if args.only else CASES:
        record[name] = run(name, args.t_end)
        print(name, json.dumps(record[name], indent=1))
        OUT.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(record, indent=1) + "\n")
    return 0 if all(r.get("rc") == 0 for r in record.values()) else 1


if __name__ == "__main__":
    sys.exit(main())
