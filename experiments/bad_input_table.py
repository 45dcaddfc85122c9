"""Bad input through the command line: every item must be refused before anything compiles.

Each row runs ``python -m fpsi_jax.cli ...`` as a subprocess (in a scratch folder, so a
command that wrongly writes is seen) and records its exit code, its stderr and the wall
time. Every row must show exit code 2, one ``error: ...`` line naming the key and what is
allowed, nothing written, in seconds (no JAX compile).

    python experiments/bad_input_table.py            # all rows, 2 at a time
    python experiments/bad_input_table.py -j 4

Writes experiments/results/bad_input.csv (input, exit_code, message, seconds, lines,
wrote) and prints the table; exits 1 if any row is not exit 2 with one line and nothing
written.
"""
from __future__ import annotations

import argparse
import csv
import os
import shutil
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
RESULTS = os.path.join(ROOT, "experiments", "results")
CAL = os.path.join(ROOT, "examples", "calibrate", "cantilever_synthetic.toml")
COLLISION = os.path.join(ROOT, "examples", "collision.toml")

# two discs, and a tank of water: the scenes the bad scene files below add to
PAIR = """
[scene]
t_end = 0.01
gravity = [0.0, 0.0]
domain = [0.0, 0.0, 0.1, 0.1]
[[discs]]
name = "pair"
points = [[0.04, 0.05], [0.06, 0.05]]
radius = 0.005
rho = 2700.0
[contacts]
kn = 1.0e5
"""
TANK = """
[scene]
t_end = 0.01
[fluid]
dx = 0.01
[[fluid.region]]
box = [0.0, 0.0, 0.2, 0.1]
[tank]
width = 0.4
height = 0.2
"""

# scene files written into the scratch folder before the rows run: name -> text
FILES = {
    "bad_probe_body.toml": PAIR + """[[probe]]
name = "left"
kind = "displacement"
body = "nope"
point = [0.04, 0.05]
""",
    "bad_probe_kind.toml": """
[scene]
t_end = 0.01
gravity = [0.0, 0.0]
domain = [0.0, 0.0, 0.1, 0.1]
[[discs]]
name = "pair"
points = [[0.04, 0.05], [0.06, 0.05]]
radius = 0.005
rho = 2700.0
[[probe]]
name = "left"
kind = "speed"
body = "pair"
point = [0.04, 0.05]
""",
    "unknown_key.toml": """
[scene]
t_end = 0.01
gravity = [0.0, 0.0]
domain = [0.0, 0.0, 0.1, 0.1]
colour = "blue"
""",
    "nan_dx.toml": """
[scene]
t_end = 0.2
[fluid]
dx = nan
[[fluid.region]]
box = [0.0, 0.0, 0.2, 0.3]
[tank]
width = 0.8
height = 0.6
""",
    "bad_switch.toml": """
[scene]
t_end = 0.01
gravity = [0.0, 0.0]
domain = [0.0, 0.0, 0.1, 0.1]
[[discs]]
name = "pair"
points = [[0.04, 0.05], [0.06, 0.05]]
radius = 0.005
rho = 2700.0
[physics]
x64 = "maybe"
""",
    "huge_fluid.toml": """
[scene]
t_end = 0.2
[fluid]
dx = 1e-7
[[fluid.region]]
box = [0.0, 0.0, 0.2, 0.3]
[tank]
width = 0.8
height = 0.6
""",
    "not_toml.toml": "[scene\nt_end = 1\n",
    "not_a_csv.csv": b"\x89HDF\r\n\x1a\n\x00\xff",      # an HDF5 file's first bytes
    "reference_not_csv.toml": PAIR + """[[probe]]
name = "left"
kind = "displacement"
body = "pair"
point = [0.04, 0.05]
reference = "not_a_csv.csv"
""",
    "probe_outside.toml": TANK + """[[probe]]
name = "p"
kind = "pressure"
point = [30.0, 5.0]
""",
    "obstacle_displacement.toml": TANK + """[[obstacle]]
name = "pier"
box = [0.3, 0.0, 0.32, 0.05]
[[probe]]
name = "u"
kind = "displacement"
body = "pier"
""",
    "discs_outside.toml": TANK + """[[grains]]
name = "bed"
box = [0.5, 0.0, 0.6, 0.02]
d = 0.005
rho = 2650.0
[contacts]
kn = 1.0e5
""",
}

#: a folder nobody may write in: chmod 555 stops a user, not root (then a sysfs folder)
READ_ONLY = "/sys/fs" if os.geteuid() == 0 else "{tmp}/ro"


RUN = ["run", "dam_break"]
# (label, argv after `python -m fpsi_jax.cli`); {tmp} is the scratch folder
ROWS = [
    ("unknown scene", ["run", "nope"]),
    ("unknown key", RUN + ["--set", "foo=1"]),
    ("--set without =", RUN + ["--set", "dx"]),
    ("dx=nan", RUN + ["--set", "dx=nan"]),
    ("dx=inf", RUN + ["--set", "dx=inf"]),
    ("dx=-inf", RUN + ["--set", "dx=-inf"]),
    ("dx=abc", RUN + ["--set", "dx=abc"]),
    ("dx=true", RUN + ["--set", "dx=true"]),
    ("dx=[1,2]", RUN + ["--set", "dx=[1,2]"]),
    ("dx=none", RUN + ["--set", "dx=none"]),
    ("dx=1 (larger than the column)", RUN + ["--set", "dx=1"]),
    ("dx=1e-9 (too many particles)", RUN + ["--set", "dx=1e-9"]),
    ("dx=1e9", RUN + ["--set", "dx=1e9"]),
    ("dx=0", RUN + ["--set", "dx=0"]),
    ("delta_sph=maybe", RUN + ["--set", "delta_sph=maybe"]),
    ("x64=maybe", RUN + ["--set", "x64=maybe"]),
    ("x64=2", RUN + ["--set", "x64=2"]),
    ("kernel=gauss", RUN + ["--set", "kernel=gauss"]),
    ("kernel=1", RUN + ["--set", "kernel=1"]),
    ("gravity=abc", RUN + ["--set", "gravity=abc"]),
    ("gravity=[0]", RUN + ["--set", "gravity=[0]"]),
    ("capacity_multiplier=-1", RUN + ["--set", "capacity_multiplier=-1"]),
    ("c0=0", RUN + ["--set", "c0=0"]),
    ("c0=nan", RUN + ["--set", "c0=nan"]),
    ("rho_tolerance=-1", RUN + ["--set", "rho_tolerance=-1"]),
    ("mu=-1", RUN + ["--set", "mu=-1"]),
    ("eps_xsph=abc", RUN + ["--set", "eps_xsph=abc"]),
    ("dem_substeps=2.5", ["run", "elastic_gate", "--set", "dem_substeps=2.5"]),
    ("fsi=bogus", ["run", "elastic_gate", "--set", "fsi=bogus"]),
    ("cantilever variant=nope", ["run", "cantilever", "--set", "variant=nope"]),
    ("itasca_beam n_balls=2.5 (integer key)", ["run", "itasca_beam", "--set", "n_balls=2.5"]),
    ("--t-end inf", RUN + ["--t-end", "inf"]),
    ("--t-end nan", RUN + ["--t-end", "nan"]),
    ("--t-end -1", RUN + ["--t-end", "-1"]),
    ("--t-end 1e9", RUN + ["--t-end", "1e9"]),
    ("--t-end abc", RUN + ["--t-end", "abc"]),
    ("--every inf", RUN + ["--every", "inf"]),
    ("--every 0", RUN + ["--every", "0"]),
    ("--every > t_end", RUN + ["--t-end", "0.1", "--every", "1"]),
    ("--dt nan", RUN + ["--dt", "nan"]),
    ("--dt 1 (above the bound)", RUN + ["--dt", "1"]),
    ("--unsafe-dt without --dt", RUN + ["--unsafe-dt"]),
    ("--max-particles 0", RUN + ["--max-particles", "0"]),
    ("--max-particles 10", RUN + ["--max-particles", "10"]),
    ("--out in a read-only folder", RUN + ["--out", READ_ONLY + "/x.h5"]),
    ("--out under a file", RUN + ["--out", "{tmp}/afile/x.h5"]),
    ("--out /proc/x.h5", RUN + ["--out", "/proc/x.h5"]),
    ("--out x.xdmf", RUN + ["--out", "{tmp}/x.xdmf"]),
    ("--out an existing folder", RUN + ["--out", "{tmp}/dir.h5"]),
    ("--out a file not ours", RUN + ["--out", "{tmp}/notours.h5", "--overwrite"]),
    ("--resume a missing file", ["run", "--resume", "{tmp}/missing.h5"]),
    ("missing scene file", ["run", "{tmp}/missing.toml"]),
    ("scene file: not TOML", ["run", "{tmp}/not_toml.toml"]),
    ("scene file: unknown key", ["run", "{tmp}/unknown_key.toml"]),
    ("scene file: dx = nan", ["run", "{tmp}/nan_dx.toml"]),
    ("scene file: x64 = 'maybe'", ["run", "{tmp}/bad_switch.toml"]),
    ("scene file: dx = 1e-7", ["run", "{tmp}/huge_fluid.toml"]),
    ("scene file: probe of an unknown body", ["run", "{tmp}/bad_probe_body.toml"]),
    ("scene file: unknown probe kind", ["run", "{tmp}/bad_probe_kind.toml"]),
    ("scene file: reference curve not a CSV", ["run", "{tmp}/reference_not_csv.toml", "--plot"]),
    ("scene file: probe point outside the domain", ["run", "{tmp}/probe_outside.toml"]),
    ("scene file: grains beside the tank", ["run", "{tmp}/discs_outside.toml"]),
    ("scene file: displacement of an obstacle", ["run", "{tmp}/obstacle_displacement.toml"]),
    ("scene file: --set unknown key", ["run", COLLISION, "--set", "foo=1"]),
    ("scene file: --set x64=maybe", ["run", COLLISION, "--set", "x64=maybe"]),
    ("validate unknown case", ["validate", "nope"]),
    ("validate key of one case only", ["validate", "hydrostatic_tank", "collision", "--quick",
                                       "--set", "depth=0.2"]),
    ("validate --set dx=nan", ["validate", "dam_break", "--quick", "--set", "dx=nan"]),
    ("validate --json unwritable", ["validate", "collision", "--quick", "--json",
                                    READ_ONLY + "/v.json"]),
    ("validate --json a folder", ["validate", "collision", "--quick", "--json", "{tmp}"]),
    ("calibrate --lr nan", ["calibrate", CAL, "--lr", "nan", "--out", "{tmp}/cal"]),
    ("calibrate --lr -1", ["calibrate", CAL, "--lr", "-1", "--out", "{tmp}/cal"]),
    ("calibrate --noise inf", ["calibrate", CAL, "--noise", "inf", "--out", "{tmp}/cal"]),
    ("calibrate --steps 0", ["calibrate", CAL, "--steps", "0", "--out", "{tmp}/cal"]),
    ("calibrate --probe nope", ["calibrate", CAL, "--probe", "nope", "--out", "{tmp}/cal"]),
    ("calibrate --fit nope", ["calibrate", CAL, "--fit", "nope", "--out", "{tmp}/cal"]),
    ("calibrate --window 1,0", ["calibrate", CAL, "--window", "1,0", "--out", "{tmp}/cal"]),
    ("calibrate --data not a CSV", ["calibrate", CAL, "--data", "{tmp}/not_a_csv.csv",
                                    "--out", "{tmp}/cal"]),
    ("calibrate --start E=nan", ["calibrate", CAL, "--start", "E=nan", "--out", "{tmp}/cal"]),
    ("calibrate --out unwritable", ["calibrate", CAL, "--out", READ_ONLY + "/cal"]),
    ("calibrate --out a file", ["calibrate", CAL, "--out", "{tmp}/afile"]),
    ("calibrate unknown case", ["calibrate", "nope", "--out", "{tmp}/cal"]),
    ("calibrate case --lr nan", ["calibrate", "cantilever_static", "--lr", "nan",
                                 "--out", "{tmp}/cal"]),
    ("calibrate case --set zeta=abc", ["calibrate", "cantilever_damping", "--set",
                                       "zeta=abc", "--out", "{tmp}/cal"]),
]


def scratch() -> str:
    """A fresh folder with the rows' files: each row runs in its own, so what it writes is
    its own."""
    tmp = tempfile.mkdtemp(prefix="fpsi_bad_input_")
    for name, text in FILES.items():
        with open(os.path.join(tmp, name), "wb" if isinstance(text, bytes) else "w") as fh:
            fh.write(text)
    os.makedirs(os.path.join(tmp, "ro"))
    os.chmod(os.path.join(tmp, "ro"), 0o555)
    with open(os.path.join(tmp, "afile"), "w") as fh:
        fh.write("a file, not a folder\n")
    os.makedirs(os.path.join(tmp, "dir.h5"))
    with open(os.path.join(tmp, "notours.h5"), "w") as fh:
        fh.write("somebody else's data\n")
    return tmp


def listing(tmp) -> set:
    out = set()
    for dirpath, dirnames, filenames in os.walk(tmp):
        for n in dirnames + filenames:
            out.add(os.path.relpath(os.path.join(dirpath, n), tmp))
    return out


def run_row(label, argv, timeout):
    tmp = scratch()
    try:
        return _run_row(label, argv, tmp, timeout)
    finally:
        os.chmod(os.path.join(tmp, "ro"), 0o755)
        shutil.rmtree(tmp, ignore_errors=True)


def _run_row(label, argv, tmp, timeout):
    argv = [a.replace("{tmp}", tmp) for a in argv]
    before = listing(tmp)
    t0 = time.perf_counter()
    try:
        p = subprocess.run([sys.executable, "-m", "fpsi_jax.cli", *argv], cwd=tmp,
                           capture_output=True, text=True, timeout=timeout,
                           env={**os.environ, "PYTHONPATH": ROOT})
        rc, err = p.returncode, p.stderr.strip()
    except subprocess.TimeoutExpired:
        rc, err = "timeout", ""
    seconds = time.perf_counter() - t0
    wrote = sorted(listing(tmp) - before)
    lines = err.splitlines()
    shown = " ".join(argv).replace(tmp, "{tmp}").replace(ROOT + "/", "")
    return {"input": f"{label}: fpsi {shown}",
            "exit_code": rc, "message": (lines[-1] if lines else "").replace(tmp, "{tmp}"),
            "seconds": round(seconds, 2), "lines": len(lines), "wrote": " ".join(wrote)}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("-j", "--jobs", type=int, default=2)
    ap.add_argument("--timeout", type=float, default=120.0)
    ap.add_argument("--out", default=os.path.join(RESULTS, "bad_input.csv"))
    args = ap.parse_args(argv)
    with ThreadPoolExecutor(args.jobs) as pool:
        rows = list(pool.map(lambda r: run_row(*r, args.timeout), ROWS))
    os.makedirs(os.path.dirname(args.out), exist_ok=True)
    with open(args.out, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    bad = 0
    for r in rows:
        ok = r["exit_code"] == 2 and r["lines"] == 1 and not r["wrote"]
        bad += not ok
        print(f"{'ok ' if ok else 'BAD'} {r['exit_code']!s:>3} {r['seconds']:6.2f}s "
              f"{r['input']}\n        {r['message']}"
              + (f"\n        wrote: {r['wrote']}" if r["wrote"] else "")
              + (f"\n        ({r['lines']} lines on stderr)" if r["lines"] != 1 else ""))
    print(f"{len(rows)} inputs, {len(rows) - bad} refused properly; wrote {args.out}")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
