"""DualSPHysics 5.4 built from its public source and run on our dam break's particles.

    .venv/bin/python experiments/dualsphysics.py --dx 0.005 --t-end 0.4    # one run, printed

Used by ``peers.py`` (per step and per simulated second) and ``dam_break_front_peers.py``
(the front against Koshizuka & Oka). What it does:

Build (once, ~6 min on 2 cores; cached under ~/.cache/fpsi-peers/dualsphysics, or
``$FPSI_DSPH_HOME``)
    The source is ``git clone --depth 1 https://github.com/DualSPHysics/DualSPHysics`` (or an
    existing tree: ``--dsph-src`` / ``$FPSI_DSPH_SRC``). Its CPU solver is compiled with the
    tree's own ``src/source/Makefile_cpu`` and Chrono, WaveGen and MoorDyn+ switched off
    (``COMPILE_CHRONO=NO COMPILE_WAVEGEN=NO COMPILE_MOORDYNPLUS=NO``: the three need
    precompiled libraries; a dam break uses none of them), g++ -O3 -fopenmp -ffast-math as
    the Makefile sets.

Case
    DualSPHysics' pre-processor GenCase is distributed as a binary only, so the particles
    are laid out here: our ``dam_break`` builder's lattice at the given dx (fluid column,
    three layers of boundary particles on the walls and the floor, whose spacing the builder
    fits to the tank, 4.99 mm at dx = 5 mm: the same particles on both sides), written into
    the solver's case file by ``dualsphysics/fpsi_dsph_io.cpp`` with the solver's own writer
    (JPartDataBi4), and the case's XML written below. The
    solver's settings are those of its stock 2D dam break (examples/main/01_DamBreak,
    CaseDambreakVal2D): Wendland kernel with h = √2·dp (coefh 1), Verlet stepping (a Euler
    step every 40), artificial viscosity α = 0.02, Fourtakas' density diffusion δ = 0.1,
    dynamic boundary particles (DBC), variable step at CFL 0.2. The sound speed is ours
    (B = ρ0 c0²/γ with our builder's c0 = 10 √(2gH), 23.9 m/s: 0.71× the stock case's
    20 √(gH), so its step is 1.4× what its stock settings would take), the fluid starts at
    our hydrostatic densities, the boundary at ρ0; the masses are ours (ρ0 dx², and ρ0 dx_b²
    for the boundary).

Run and read-back
    ``DualSPHysics5.4CPU_linux64 <case> <out> -cpu -ompthreads:2 -svres`` on an otherwise
    idle machine; Run.out gives the steps and runtimes of the whole run, RunPARTs.csv the
    steps and wall time of each output interval (so the first can be left out as warm-up;
    its timer stops before the interval's part file is written); the output parts are read
    back with ``fpsi_dsph_io dump``.
"""
from __future__ import annotations

import argparse
import functools
import json
import os
import re
import shutil
import subprocess
import tempfile
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
REPO_URL = "https://github.com/DualSPHysics/DualSPHysics"
DEFAULT_HOME = os.environ.get("FPSI_DSPH_HOME",
                              os.path.expanduser("~/.cache/fpsi-peers/dualsphysics"))
EXE_NAME = "DualSPHysics5.4CPU_linux64"
IO_SOURCE = os.path.join(HERE, "dualsphysics", "fpsi_dsph_io.cpp")
# The DualSPHysics sources the case reader/writer needs (its own particle-file classes).
IO_DEPS = ["JPartDataBi4.cpp", "JBinaryData.cpp", "Functions.cpp", "JException.cpp",
           "JObject.cpp", "JPartDataHead.cpp"]


class DsphError(RuntimeError):
    pass


# --- build -------------------------------------------------------------------------------

def source_tree(home=DEFAULT_HOME, src=None):
    """A DualSPHysics source tree: ``src``, $FPSI_DSPH_SRC, or a shallow clone in ``home``."""
    src = src or os.environ.get("FPSI_DSPH_SRC")
    if src:
        if not os.path.isfile(os.path.join(src, "src", "source", "Makefile_cpu")):
            raise DsphError(f"{src} is not a DualSPHysics tree (no src/source/Makefile_cpu)")
        return src
    dst = os.path.join(home, "src")
    if not os.path.isfile(os.path.join(dst, "src", "source", "Makefile_cpu")):
        os.makedirs(home, exist_ok=True)
        r = subprocess.run(["git", "clone", "--depth", "1", REPO_URL, dst],
                           capture_output=True, text=True)
        if r.returncode != 0:
            raise DsphError(f"git clone {REPO_URL} failed: {r.stderr.strip()[-500:]}")
    return dst


def build(home=DEFAULT_HOME, src=None, jobs=2):
    """Compile the CPU solver once, and the case tool when missing or older than its source;
    returns (solver, tool, build_seconds)."""
    exe = os.path.join(home, "bin", EXE_NAME)
    tool = os.path.join(home, "bin", "fpsi_dsph_io")
    t0 = time.perf_counter()
    stale = (not os.path.exists(tool)
             or os.path.getmtime(tool) < os.path.getmtime(IO_SOURCE))   # the tool was edited
    if not os.path.exists(exe) or stale:
        build_src = os.path.join(home, "build", "src", "source")
        if not os.path.isdir(build_src):
            shutil.copytree(os.path.join(source_tree(home, src), "src", "source"), build_src)
        os.makedirs(os.path.dirname(exe), exist_ok=True)
        log = os.path.join(home, "build.log")
        if not os.path.exists(exe):
            with open(log, "w") as fh:
                r = subprocess.run(
                    ["make", "-f", "Makefile_cpu", f"-j{jobs}", "COMPILE_CHRONO=NO",
                     "COMPILE_WAVEGEN=NO", "COMPILE_MOORDYNPLUS=NO",
                     f"EXECS_DIRECTORY={os.path.dirname(exe)}"],
                    cwd=build_src, stdout=fh, stderr=subprocess.STDOUT)
            if r.returncode != 0 or not os.path.exists(exe):
                raise DsphError(f"DualSPHysics build failed (exit {r.returncode}); see {log}")
        r = subprocess.run(["g++", "-O2", "-std=c++11", "-I.", IO_SOURCE, *IO_DEPS, "-o", tool],
                           cwd=build_src, capture_output=True, text=True)
        if r.returncode != 0:
            raise DsphError(f"fpsi_dsph_io build failed: {r.stderr[-1500:]}")
    return exe, tool, time.perf_counter() - t0


# --- case --------------------------------------------------------------------------------

@functools.lru_cache(maxsize=8)
def case_particles(dx):
    """Our dam break at ``dx``: (boundary xy, fluid xy, fluid rho, scene constants); built
    once per dx (the callers ask for the constants before the run writes the case)."""
    from fpsi_jax import cases
    scene = cases.build("dam_break", dx=dx)
    kw = scene.builder_kwargs
    xb = np.asarray(scene.boundary.x, dtype=float)
    xf = np.asarray(scene.fluid.x, dtype=float)
    rho = np.asarray(scene.fluid.rho, dtype=float)
    g = float(-np.asarray(scene.params.gravity)[1])
    mb = np.asarray(scene.boundary.mass, dtype=float)
    if np.ptp(mb) > 1e-6 * mb.max():
        raise DsphError("the boundary particles' masses differ; DualSPHysics takes one")
    return xb, xf, rho, {"rho0": float(kw["rho0"]), "c0": float(kw["c0"]), "g": g,
                         "mass_boundary": float(mb[0]),
                         "column_width": float(kw["column_width"]), "n_fluid": len(xf),
                         "n_boundary": len(xb)}


PARAMETERS = [  # the stock CaseDambreakVal2D execution parameters (DualSPHysics 5.4)
    ("StepAlgorithm", 1), ("VerletSteps", 40), ("Kernel", 2), ("ViscoTreatment", 1),
    ("ViscoBoundFactor", 1), ("DensityDT", 2), ("DensityDTvalue", 0.1), ("Shifting", 0),
    ("RigidAlgorithm", 1), ("CoefDtMin", 0.05), ("DtIni", 0), ("DtMin", 0),
    ("DtAllParticles", 0), ("RhopOutMin", 700), ("RhopOutMax", 1300),
]


def write_case(workdir, tool, dx, t_end, t_out, alpha=0.02, cfl=0.2, coefh=1.0, gamma=7.0):
    """Case ``dambreak`` in ``workdir``: its XML and, through the tool, its .bi4."""
    xb, xf, rho, k = case_particles(dx)
    rho0, c0 = k["rho0"], k["c0"]
    h = float(coefh * np.sqrt(2.0) * dx)
    b = rho0 * c0 ** 2 / gamma
    mass = rho0 * dx ** 2
    mass_b = k["mass_boundary"]
    nb, nf = len(xb), len(xf)
    txt = os.path.join(workdir, "particles.txt")
    with open(txt, "w") as fh:
        fh.write(f"{nb + nf} {nb} {nf} {dx!r} {h!r} {b!r} {rho0!r} {gamma!r} {mass_b!r} "
                 f"{mass!r}\n")
        np.savetxt(fh, np.c_[xb, np.zeros((nb, 2)), np.full(nb, rho0)], fmt="%.9g")
        np.savetxt(fh, np.c_[xf, np.zeros((nf, 2)), rho], fmt="%.9g")
    params = PARAMETERS + [("Visco", alpha), ("TimeMax", t_end), ("TimeOut", t_out)]
    plist = "\n".join(f'      <parameter key="{key}" value="{val}" />' for key, val in params)
    xml = f"""<?xml version="1.0" encoding="UTF-8" ?>
<case app="fpsi-jax experiments/dualsphysics.py">
  <execution>
    <constants>
      <data2d value="true" />
      <data2dposy value="0" />
      <gravity x="0" y="0" z="{-k['g']!r}" />
      <cflnumber value="{cfl!r}" />
      <gamma value="{gamma!r}" />
      <rhop0 value="{rho0!r}" />
      <dp value="{dx!r}" />
      <h value="{h!r}" />
      <b value="{b!r}" />
      <massbound value="{mass_b!r}" />
      <massfluid value="{mass!r}" />
    </constants>
    <particles np="{nb + nf}" nb="{nb}" nbf="{nb}" mkboundfirst="11" mkfluidfirst="1">
      <fixed mkbound="0" mk="11" begin="0" count="{nb}" />
      <fluid mkfluid="0" mk="1" begin="{nb}" count="{nf}" />
    </particles>
    <parameters>
{plist}
      <simulationdomain>
        <posmin x="default" y="default" z="default" />
        <posmax x="default" y="default" z="default + 50%" />
      </simulationdomain>
    </parameters>
  </execution>
</case>
"""
    with open(os.path.join(workdir, "dambreak.xml"), "w") as fh:
        fh.write(xml)
    r = subprocess.run([tool, "case", workdir, "dambreak", txt], capture_output=True, text=True)
    if r.returncode != 0:
        raise DsphError(f"writing the case failed: {(r.stdout + r.stderr)[-1500:]}")
    return {**k, "dx": dx, "h": float(h), "B": float(b), "alpha": alpha, "cfl": cfl,
            "n_particles": nb + nf}


# --- run ---------------------------------------------------------------------------------

def _int(s):
    return int(s.replace(",", "").replace(".", ""))


def parse_run_out(path):
    """Run.out's summary: runtimes, steps per second, steps, excluded particles."""
    summary = {}
    with open(path, errors="replace") as fh:
        for line in fh:
            for key, name in (("Total Runtime", "total_runtime_s"),
                              ("Simulation Runtime", "simulation_runtime_s"),
                              ("Runtime per physical second", "runtime_per_sim_s"),
                              ("Steps per second", "steps_per_s")):
                if line.startswith(key):
                    summary[name] = float(line.split(":")[-1].split()[0])
            if line.startswith("Steps of simulation"):
                summary["steps"] = _int(line.split(":")[-1].strip())
            if line.startswith("Excluded particles."):
                summary["excluded"] = _int(line.split(":")[-1].strip())
    return summary


def parse_parts(path):
    """RunPARTs.csv: per output interval its end time, steps and wall time (``PartRuntime``,
    whose timer stops before the part's file is written; full precision, unlike Run.out's
    Part lines)."""
    with open(path, errors="replace") as fh:
        head = fh.readline().strip().split(";")
        rows = [line.strip().split(";") for line in fh
                if line.strip() and not line.startswith("#")]   # notes follow the table
    col = {name: k for k, name in enumerate(head)}
    return [{"part": int(r[col["Part"]]), "t": float(r[col["TimeStep [s]"]]),
             "steps": _int(r[col["Steps"]]), "wall_s": float(r[col["PartRuntime [s]"]])}
            for r in rows]


def run(dx, t_end, t_out, threads=2, home=DEFAULT_HOME, keep=None, read_parts=False, **kw):
    """Build if needed, write the case, run it; the figures (and the parts' fronts)."""
    exe, tool, _ = build(home)
    work = keep or tempfile.mkdtemp(prefix="fpsi-dsph-")
    os.makedirs(work, exist_ok=True)
    case = write_case(work, tool, dx, t_end, t_out, **kw)
    out = os.path.join(work, "out")
    cmd = [exe, os.path.join(work, "dambreak"), out, "-cpu", f"-ompthreads:{threads}",
           "-svres"]
    env = dict(os.environ, OMP_NUM_THREADS=str(threads))
    t0 = time.perf_counter()
    r = subprocess.run(cmd, capture_output=True, text=True, env=env, cwd=work)
    wall = time.perf_counter() - t0
    run_out = os.path.join(out, "Run.out")
    if r.returncode != 0 or not os.path.exists(run_out):
        raise DsphError(f"DualSPHysics failed (exit {r.returncode}): "
                        f"{(r.stdout + r.stderr)[-2000:]}")
    summary = parse_run_out(run_out)
    parts = parse_parts(os.path.join(out, "RunPARTs.csv"))
    res = {"case": case, "t_end": t_end, "t_out": t_out, "threads": threads,
           "process_wall_s": wall, "parts": parts, **summary,
           "command": " ".join([EXE_NAME, "dambreak", "out", *cmd[3:]])}
    if read_parts:
        res["x_max"] = fronts(tool, out, case["n_boundary"])
    if keep is None:
        shutil.rmtree(work, ignore_errors=True)
    return res


def fronts(tool, out, n_boundary):
    """[(t, rightmost fluid x)] from every output part (excluded particles are not in it)."""
    rows = []
    data = os.path.join(out, "data") if os.path.isdir(os.path.join(out, "data")) else out
    for name in sorted(f for f in os.listdir(data) if re.match(r"Part_\d{4}\.bi4$", f)):
        txt = os.path.join(data, name + ".txt")
        r = subprocess.run([tool, "dump", os.path.join(data, name), txt],
                           capture_output=True, text=True)
        if r.returncode != 0:
            raise DsphError(f"reading {name} failed: {r.stderr[-500:]}")
        with open(txt) as fh:
            t = float(fh.readline().split()[0])
        a = np.loadtxt(txt, skiprows=1, ndmin=2)
        fluid = a[a[:, 0] >= n_boundary]
        rows.append((t, float(fluid[:, 1].max())))
        os.remove(txt)
    return rows


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--dx", type=float, default=0.005)
    ap.add_argument("--t-end", type=float, default=0.4)
    ap.add_argument("--t-out", type=float, default=0.05)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--home", default=DEFAULT_HOME)
    ap.add_argument("--dsph-src", default=None, help="an existing DualSPHysics tree")
    ap.add_argument("--keep", default=None, help="keep the case and output in this folder")
    args = ap.parse_args()
    exe, tool, secs = build(args.home, args.dsph_src)
    print(f"solver {exe} ({'built in %.0f s' % secs if secs > 1 else 'cached'})", flush=True)
    res = run(args.dx, args.t_end, args.t_out, args.threads, args.home, args.keep,
              read_parts=True)
    res.pop("parts")
    print(json.dumps(res, indent=1))


if __name__ == "__main__":
    main()
