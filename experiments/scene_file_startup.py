"""How long a user waits from ``fpsi run my_case.toml`` to the first computed frame.

    python experiments/scene_file_startup.py [--repeats 3]

For each example file the command ``fpsi run FILE --t-end T1 --every T1 --quiet`` runs as
a fresh process (Python start, imports, reading and checking the file, building the
scene, compiling the step, the first frame interval of simulation, writing HDF5 + XDMF),
with T1 the file's own frame interval ([output] every, default t_end/100). The wall time
of that process is the time to the first frame after t = 0; the median of ``--repeats``
runs is reported, with the split the run itself prints (set-up and compilation).
Writes experiments/results/scene_file_startup.json.
"""
from __future__ import annotations

import argparse
import json
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
FILES = ["examples/elastic_gate.toml", "examples/dam_break_on_post.toml",
         "examples/cantilever.toml"]


def frame_interval(path):
    sys.path.insert(0, ROOT)
    from fpsi_jax import scenefile
    case = scenefile.load(os.path.join(ROOT, path))
    every = case.output["every"]
    return float(every) if every else float(case.scene.t_end) / 100.0


def once(path, t1, out_dir):
    out = os.path.join(out_dir, "run.h5")
    cmd = [sys.executable, "-m", "fpsi_jax.cli", "run", path, "--t-end", repr(t1),
           "--every", repr(t1), "--out", out, "--quiet"]
    t0 = time.perf_counter()
    p = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if p.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed: {p.stderr.strip()}")
    m = re.search(r"set-up and compilation ([0-9.]+) s", p.stdout)
    return wall, float(m.group(1)) if m else None


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    rows = []
    for path in FILES:
        t1 = frame_interval(path)
        walls, compiles = [], []
        with tempfile.TemporaryDirectory() as tmp:
            for _ in range(args.repeats):
                w, c = once(path, t1, tmp)
                walls.append(w)
                compiles.append(c)
        row = {"file": path, "first_frame_t_s": t1, "wall_s": walls,
               "median_wall_s": statistics.median(walls),
               "setup_and_compile_s": compiles}
        rows.append(row)
        print(f"{path}: first frame (t = {t1:.4g} s) after {row['median_wall_s']:.1f} s "
              f"(median of {args.repeats}; set-up and compilation {compiles})")
    rec = {"cpus": os.cpu_count(), "rows": rows,
           "command": "python experiments/scene_file_startup.py"}
    path = os.path.join(HERE, "results", "scene_file_startup.json")
    with open(path, "w") as fh:
        json.dump(rec, fh, indent=1)
    print("wrote", os.path.relpath(path, ROOT))


if __name__ == "__main__":
    main()
