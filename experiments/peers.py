"""Peers side by side on this machine: the same case (2D dam break), a similar particle
count and the same number of steps, for us, PySPH and DualSPHysics; particle-steps/s of
each, wall seconds per simulated second, and our ratios; with the fixed figures measured
here earlier for JAX-SPH, which no registry installs.

    nice -n 10 .venv/bin/python experiments/peers.py                # install PySPH, 5k + 20k
    nice -n 10 .venv/bin/python experiments/peers.py --sizes 5000 20000 80000 --steps 200
    nice -n 10 .venv/bin/python experiments/peers.py --ours-only    # re-measure us, keep peers
    nice -n 10 .venv/bin/python experiments/peers.py --pysph-only --skip-install
    nice -n 10 .venv/bin/python experiments/peers.py --sizes 5000 20000 80000 --no-pysph
        # us and DualSPHysics side by side, PySPH's last figures kept (no network needed
        # once DualSPHysics is built: FPSI_DSPH_SRC names a source tree)
    nice -n 10 .venv/bin/python experiments/peers.py --sizes --front-dx 0.005 0.0025 \
        --skip-install     # the whole K&O window only: speed at equal accuracy

Writes experiments/results/peers.json (merged per size: a run with --ours-only keeps the
peers' figures of the last run, and the reverse) and peers.png.

DualSPHysics
    DualSPHysics 5.4's CPU solver built from its public source by ``dualsphysics.py``
    (a shallow clone, Chrono / WaveGen / MoorDyn+ off, ~6 min on 2 cores, cached) and run
    on our own particles at our dx (GenCase is published as a binary only; the same
    particles on both sides), with its stock dam-break settings (Verlet, Wendland h = √2 dx,
    α = 0.02, Fourtakas' density diffusion, DBC boundary, variable step at CFL 0.2) and our
    sound speed; 2 OpenMP threads. Timed from its own RunPARTs.csv: the steps and wall time
    of the output interval after a first (warm-up) interval of about ``steps`` steps. Its
    step is its own CFL step, so per simulated second (``wall_per_sim_s``: both sides early
    in the flow, where its step is ≈ 0.2 h/c0 and ours 0.875 h/(c0 + |v|)) is the figure
    that counts both codes' step sizes; with
    ``--front-dx`` both also run the whole Koshizuka & Oka window (T ≤ 2.75) at those dx and
    report their front error next to their wall time (speed at equal accuracy): ours is run
    twice in the process and timed the second time (``first_call_wall_s``: the first call,
    with tracing and compilation or loading the compiled step from JAX's cache), the solver
    as a whole process (its set-up takes milliseconds; the wall includes writing the ~56 part
    files its front is read from, while ours observes in memory).
    ``--no-dsph`` leaves it out (the last figures in peers.json are kept).

PySPH
    PySPH 1.0b2 from PyPI, built from source into its own virtual environment outside the
    repository (default ~/.cache/fpsi-peers/pysph-venv, --venv or $FPSI_PEERS_VENV):
    ``pip install "numpy<2" cython mako setuptools wheel compyle``, then
    ``pip install --no-build-isolation cyarray`` and ``pip install --no-build-isolation
    pysph`` (pysph's setup.py cimports cyarray's .pxd files, which its sdist does not
    declare; without build isolation the build also sees numpy<2, the runtime numpy). Needs
    gcc; ~3 min. A failed install is reported with the failing command and the tail of the
    pip log (``<venv>/fpsi-install.log``); our figures and the fixed ones are still reported.

    Case: the stock ``pysph.examples.dam_break_2d`` (Gomez-Gesteira et al. 2010: 1 × 2 m
    column in a 4 × 4 m tank, 4 boundary layers; WCSPH scheme: Tait EOS, continuity,
    momentum with artificial viscosity α = 0.1, XSPH, h updated from ρ (Ferrari),
    hg-corrected boundary pressure; WendlandQuintic kernel, h = 1.3 dx; PEC integrator, one
    acceleration evaluation per step; float64; linked-list NNPS rebuilt every step). The
    stock example keeps h and m of dx = 0.03 at any --dx, so a small driver (written by this
    script into the venv) subclasses DamBreak2D and resets h = 1.3 dx and m = ρ dx² after
    create_particles. Run with ``--openmp`` (compyle's flag: PySPH's parser resets
    use_openmp to it, so setting the config beforehand does nothing) and
    OMP_NUM_THREADS = --threads (both cores),
    fixed dt = 0.125 h / c0 (the stock initial step; ``--timestep --no-adaptive-timestep``),
    ``--max-steps 2·steps``, ``--disable-output --pfreq 2**30``, log to a temporary folder.

What is timed
    Both sides: ``steps`` steps after a warm-up of ``steps`` steps, wall clock only, so no
    compile, build or set-up is in it. Ours: ``bench(dx, steps)`` of bench_sph.py (XLA
    compile, one warm-up chunk, then the median of timed chunks of ``steps`` steps from the
    warmed-up state, neighbour rebuilds included). PySPH: the driver's post_step callback
    reads time.perf_counter() after step ``steps`` and after step ``2·steps`` (Cython
    generation and compile happen in Application.setup, before the first step, and are
    cached under ~/.pysph). Particle count = fluid + boundary particles on both sides
    (everything in the neighbour search).
    Best of --repeat runs on each side; PySPH is run with each of --omp-wait-policy
    (default: libgomp's own, and PASSIVE) in every round, since libgomp's spinning threads
    lose many times over when another process holds a core (seen here: 0.3 s → 5 s for 100
    steps at 5k). The machine is shared: before each run the script waits (up to
    --wait-idle s) for the other processes to use < 0.3 core, and records the cores other
    processes used during each run (``other_load_cores``, from /proc/stat minus the run's
    own CPU time); PySPH's own CPU time over the timed steps / wall (``cpu_over_wall``)
    tells how many cores it actually got. While every run of a size was loaded, up to
    --extra-tries more rounds follow; a figure still loaded is marked ``loaded`` in the
    JSON, "~" in the table and hollow in the plot: it understates that side, re-run when
    the machine is quiet. A timed chunk of ours that overflows the neighbour lists (seen
    at dx = 3.5 mm) is grown and redone inside bench (``run_until_fits``, as the driver
    does; recorded as ``regrowths_while_timing``).
"""
from __future__ import annotations

import argparse
import json
import math
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import textwrap
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
RESULTS = os.path.join(HERE, "results")
OUT_JSON = os.path.join(RESULTS, "peers.json")
OUT_PNG = os.path.join(RESULTS, "peers.png")
DEFAULT_VENV = os.environ.get("FPSI_PEERS_VENV",
                              os.path.expanduser("~/.cache/fpsi-peers/pysph-venv"))
PYSPH_SPEC = "pysph==1.0b2"

# Figures measured on this machine earlier (2D dam break, particle-steps/s, particles =
# fluid + boundary), not re-measured by this script: JAX-SPH, which no registry installs.
FIXED_PEERS = {
    "JAX-SPH": {
        "version": "0.1.0", "mode": "JAX CPU", "precision": "float32",
        "rows": [{"n_particles": 7000, "particle_steps_per_s": 0.27e6},
                 {"n_particles": 24000, "particle_steps_per_s": 0.15e6}],
        "note": "fixed figures measured earlier on this machine (not re-run by this script)"},
}

INSTALL_STEPS = [
    ["install", "--upgrade", "pip"],
    ["install", "numpy<2", "cython", "mako", "setuptools", "wheel", "compyle"],
    ["install", "--no-build-isolation", "cyarray"],
    ["install", "--no-build-isolation", PYSPH_SPEC],
]

# The driver runs inside the PySPH venv. Two modes:
#   driver.py --fpsi-pick N        print {"dx", "n_fluid", "n_boundary"} for ~N particles
#   driver.py <PySPH options>      the benchmark; env FPSI_WARM, FPSI_STEPS, FPSI_OUT
DRIVER = textwrap.dedent('''\
    """Written by experiments/peers.py: PySPH's dam_break_2d with h and m reset for --dx,
    timed from its post_step callback (steps FPSI_WARM .. FPSI_WARM + FPSI_STEPS)."""
    import json, os, sys, time
    import numpy as np


    def cpu_busy_s():
        with open("/proc/stat") as fh:
            v = [int(x) for x in fh.readline().split()[1:9]]
        return (sum(v) - v[3] - v[4]) / os.sysconf("SC_CLK_TCK")


    def counts(dx):
        from pysph.tools.geometry import get_2d_tank, get_2d_block
        # as DamBreak2D.create_particles without --staggered-grid
        xt, _ = get_2d_tank(dx=dx, length=4.0, height=4.0, base_center=[2, 0], num_layers=4)
        xf, _ = get_2d_block(dx=dx, length=1.0, height=2.0, center=[0.5, 1])
        return len(xf), len(xt)


    def pick(target):
        nf, nb = counts(0.01)
        dx0 = 0.01 * (target / (nf + nb)) ** -0.5
        best = None
        for k in range(-60, 61):
            dx = float("%.4g" % (dx0 * (1 + 0.005 * k)))
            nf, nb = counts(dx)
            if best is None or abs(nf + nb - target) < abs(best[1] + best[2] - target):
                best = (dx, nf, nb)
        return {"dx": best[0], "n_fluid": best[1], "n_boundary": best[2]}


    if len(sys.argv) == 3 and sys.argv[1] == "--fpsi-pick":
        print(json.dumps(pick(int(sys.argv[2]))))
        sys.exit(0)

    import compyle, cyarray, Cython, pysph
    from compyle.config import get_config
    from pysph.examples import dam_break_2d as db

    WARM, STEPS = int(os.environ["FPSI_WARM"]), int(os.environ["FPSI_STEPS"])
    T_START = time.perf_counter()


    class Bench(db.DamBreak2D):
        marks = {}

        def create_particles(self):
            fluid, boundary = super().create_particles()
            for pa in (fluid, boundary):  # the stock example keeps those of dx = 0.03
                pa.h[:] = self.hdx * self.dx
                pa.m[:] = db.ro * self.dx ** 2
            return [fluid, boundary]

        def pre_step(self, solver):
            self.marks.setdefault("first_step", time.perf_counter())

        def post_step(self, solver):
            self.n_done = getattr(self, "n_done", 0) + 1
            if self.n_done in (WARM, WARM + STEPS):
                self.marks[self.n_done] = (time.perf_counter(), time.process_time(),
                                           cpu_busy_s())


    app = Bench()
    app.run()
    (t0, c0, b0), (t1, c1, b1) = app.marks[WARM], app.marks[WARM + STEPS]
    fluid, boundary = app.particles
    wall, cpu = t1 - t0, c1 - c0
    speed = np.sqrt(fluid.u ** 2 + fluid.v ** 2)
    out = {"dx": app.dx, "h": float(fluid.h[0]), "m": float(fluid.m[0]),
           "n_fluid": int(fluid.get_number_of_particles()),
           "n_boundary": int(boundary.get_number_of_particles()),
           "steps": STEPS, "warmup_steps": WARM, "steps_run": int(app.solver.count),
           "dt": float(app.solver.dt), "t_end": float(app.solver.t),
           "wall_s": wall, "cpu_s": cpu, "cpu_over_wall": cpu / wall,
           "other_load_cores": max(0.0, (b1 - b0 - cpu) / wall),
           "setup_s": app.marks["first_step"] - T_START,
           "openmp": bool(get_config().use_openmp),
           "omp_num_threads": os.environ.get("OMP_NUM_THREADS"),
           "omp_wait_policy": os.environ.get("OMP_WAIT_POLICY", "(libgomp default)"),
           "max_speed": float(speed.max()), "finite": bool(np.all(np.isfinite(fluid.x))
                                                           and np.all(np.isfinite(speed))),
           "versions": {"pysph": pysph.__version__, "compyle": compyle.__version__,
                        "cyarray": getattr(cyarray, "__version__", "?"),
                        "cython": Cython.__version__, "numpy": np.__version__,
                        "python": sys.version.split()[0]}}
    with open(os.environ["FPSI_OUT"], "w") as fh:
        json.dump(out, fh, indent=1)
''')


# --- machine load ------------------------------------------------------------------------

def cpu_busy_s():
    """CPU seconds all cores have been busy since boot (/proc/stat, idle and iowait out)."""
    with open("/proc/stat") as fh:
        v = [int(x) for x in fh.readline().split()[1:9]]
    return (sum(v) - v[3] - v[4]) / os.sysconf("SC_CLK_TCK")


def wait_idle(max_wait, threshold=0.3):
    """Wait (≤ max_wait s) for a 1 s window in which other processes use < threshold core
    (we are idle while waiting). Returns the cores the last window saw busy."""
    t_end = time.time() + max_wait
    while True:
        b0 = cpu_busy_s()
        time.sleep(1.0)
        busy = cpu_busy_s() - b0
        if busy < threshold or time.time() >= t_end:
            if busy >= threshold:
                print(f"  (machine still busy: other processes use {busy:.1f} cores; "
                      "measuring anyway)", flush=True)
            return busy


def machine_info():
    model = "?"
    try:
        with open("/proc/cpuinfo") as fh:
            model = next(l.split(":", 1)[1].strip() for l in fh if l.startswith("model name"))
    except (OSError, StopIteration):
        pass
    gcc = shutil.which("gcc")
    gcc_v = (subprocess.run([gcc, "--version"], capture_output=True, text=True).stdout
             .splitlines()[0] if gcc else None)
    return {"cpu_model": model, "cpu_count": os.cpu_count(), "platform": platform.platform(),
            "python": sys.version.split()[0], "gcc": gcc_v, "loadavg_at_start": os.getloadavg(),
            "niceness": os.nice(0)}


# --- PySPH -------------------------------------------------------------------------------

class PeerError(RuntimeError):
    pass


def venv_python(venv):
    return os.path.join(venv, "bin", "python")


def pysph_importable(venv):
    py = venv_python(venv)
    return os.path.exists(py) and subprocess.run(
        [py, "-c", "import pysph.examples.dam_break_2d"], capture_output=True).returncode == 0


def install_pysph(venv, reinstall=False):
    """Create ``venv`` and build PySPH into it (skipped when it already imports)."""
    if reinstall and os.path.isdir(venv):
        shutil.rmtree(venv)
    if pysph_importable(venv):
        print(f"PySPH: already installed in {venv}", flush=True)
        return
    if shutil.which("gcc") is None and shutil.which("cc") is None:
        raise PeerError("no C compiler (gcc/cc) on PATH: PySPH builds from source")
    os.makedirs(os.path.dirname(venv) or ".", exist_ok=True)
    log_path = os.path.join(venv, "fpsi-install.log")
    print(f"PySPH: building into {venv} (log {log_path}; a few minutes)", flush=True)
    t0 = time.perf_counter()
    r = subprocess.run([sys.executable, "-m", "venv", "--clear", venv], capture_output=True,
                       text=True)
    if r.returncode != 0:
        raise PeerError(f"`{sys.executable} -m venv {venv}` failed (exit {r.returncode}):\n"
                        f"{(r.stdout + r.stderr)[-3000:]}")
    with open(log_path, "w") as log:
        for step in INSTALL_STEPS:
            cmd = [venv_python(venv), "-m", "pip"] + step
            log.write(f"\n$ {' '.join(cmd)}\n")
            log.flush()
            r = subprocess.run(cmd, stdout=log, stderr=subprocess.STDOUT, timeout=3600)
            if r.returncode != 0:
                log.flush()
                with open(log_path) as fh:
                    tail = "".join(fh.readlines()[-40:])
                raise PeerError(f"`pip {' '.join(step)}` failed (exit {r.returncode}); last "
                                f"lines of {log_path}:\n{tail}")
    if not pysph_importable(venv):
        raise PeerError(f"PySPH installed but `import pysph.examples.dam_break_2d` fails "
                        f"with {venv_python(venv)}")
    print(f"PySPH: built in {time.perf_counter() - t0:.0f} s", flush=True)


def write_driver(venv):
    path = os.path.join(venv, "fpsi_peers_dam_break.py")
    with open(path, "w") as fh:
        fh.write(DRIVER)
    return path


def pysph_pick(venv, driver, target):
    r = subprocess.run([venv_python(venv), driver, "--fpsi-pick", str(target)],
                       capture_output=True, text=True, timeout=600)
    if r.returncode != 0:
        raise PeerError(f"particle count failed:\n{r.stderr[-3000:]}")
    return json.loads(r.stdout.strip().splitlines()[-1])


def pysph_run(venv, driver, dx, steps, threads, wait_policy):
    """One PySPH run of 2·steps steps at spacing dx; the driver's figures for the last
    ``steps``."""
    c0 = 10.0 * math.sqrt(2 * 9.81 * 2.0)  # the example's c0 = 10 √(2 g H), H = 2 m
    dt = 0.125 * 1.3 * dx / c0
    tmp = tempfile.mkdtemp(prefix="fpsi-pysph-")
    out = os.path.join(tmp, "result.json")
    env = dict(os.environ, OMP_NUM_THREADS=str(threads), FPSI_WARM=str(steps),
               FPSI_STEPS=str(steps), FPSI_OUT=out)
    env.pop("OMP_WAIT_POLICY", None)
    if wait_policy:
        env["OMP_WAIT_POLICY"] = wait_policy
    cmd = [venv_python(venv), driver, "--openmp", "--dx", repr(dx), "--timestep", repr(dt),
           "--no-adaptive-timestep", "--max-steps", str(2 * steps), "--tf", "1000",
           "--disable-output", "--pfreq", str(2 ** 30), "-q", "-d", os.path.join(tmp, "out")]
    try:
        r = subprocess.run(cmd, capture_output=True, text=True, env=env, cwd=tmp,
                           timeout=1800)
        if r.returncode != 0 or not os.path.exists(out):
            raise PeerError(f"PySPH run failed (exit {r.returncode}):\n"
                            f"{(r.stdout + r.stderr)[-3000:]}")
        with open(out) as fh:
            res = json.load(fh)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    if not res["finite"]:
        raise PeerError(f"PySPH run went bad at dx={dx}: non-finite positions/velocities")
    res["n_particles"] = res["n_fluid"] + res["n_boundary"]
    res["particle_steps_per_s"] = res["n_particles"] * steps / res["wall_s"]
    res["command"] = (f"OMP_NUM_THREADS={threads} "
                      + (f"OMP_WAIT_POLICY={wait_policy} " if wait_policy else "")
                      + " ".join(os.path.basename(c) if i < 2 else c
                                 for i, c in enumerate(cmd[:-2])))
    return res


# --- ours --------------------------------------------------------------------------------

def our_count(dx):
    from fpsi_jax import cases
    sc = cases.build("dam_break", dx=dx)
    return sc.fluid.n + sc.boundary.n


def our_dx_for(target):
    """dx (4 significant digits) of our dam_break scene whose particle count is closest to
    ``target`` (count falls with dx: bisection in log dx, then the neighbours)."""
    lo, hi = 2e-4, 2e-2  # dx bounds: ~1.1 M and ~250 particles
    for _ in range(30):
        mid = math.sqrt(lo * hi)
        if our_count(mid) > target:
            lo = mid
        else:
            hi = mid
    dx = float("%.4g" % lo)
    cands = [float("%.4g" % (dx * (1 + 0.001 * k))) for k in range(-4, 5)]
    return min(cands, key=lambda d: abs(our_count(d) - target))


def git_state():
    """Commit of the checkout and whether fpsi_jax/ or experiments/bench_sph.py differ
    from it (our speed is that of the code in the tree at run time)."""
    def git(*a):
        return subprocess.run(["git", *a], cwd=HERE, capture_output=True, text=True).stdout
    return {"commit": git("rev-parse", "--short", "HEAD").strip() or None,
            "dirty": bool(git("status", "--porcelain", "--", "../fpsi_jax", "bench_sph.py",
                              "_bench.py").strip())}


def ours_run(dx, steps):
    """bench(dx, steps) of bench_sph.py (lists that overflow are grown and the chunk redone
    inside it), with the load of other processes over the call."""
    import jax
    from bench_sph import bench
    t0, c0, b0 = time.perf_counter(), time.process_time(), cpu_busy_s()
    r = bench(dx, steps)
    t1, c1, b1 = time.perf_counter(), time.process_time(), cpu_busy_s()
    r["other_load_cores"] = max(0.0, (b1 - b0 - (c1 - c0)) / (t1 - t0))
    r["other_load_over"] = "the whole bench() call (compile, warm-up and timed chunk)"
    r["jax"], r["backend"] = jax.__version__, jax.default_backend()
    r["git"] = git_state()
    r["precision"] = "float32"
    return r


# --- DualSPHysics ------------------------------------------------------------------------

def dsph_run(dx, steps, threads):
    """DualSPHysics on our particles at ``dx``: about ``steps`` warm-up steps (its first
    output interval), then the next interval timed from its RunPARTs.csv."""
    import dualsphysics
    k = dualsphysics.case_particles(dx)[3]
    dt0 = 0.2 * math.sqrt(2.0) * dx / k["c0"]       # its CFL step at rest (h = √2 dx)
    t_out = steps * dt0
    t0, c0, b0 = time.perf_counter(), os.times(), cpu_busy_s()
    res = dualsphysics.run(dx, 2 * t_out * 1.0001, t_out, threads=threads)
    t1, c1, b1 = time.perf_counter(), os.times(), cpu_busy_s()
    own = (c1.children_user + c1.children_system) - (c0.children_user + c0.children_system)
    part = next(p for p in res["parts"] if p["part"] == 2)
    prev = next(p for p in res["parts"] if p["part"] == 1)
    wall = part["wall_s"]
    n = res["case"]["n_particles"]
    return {"dx": dx, "n_particles": n, "n_fluid": res["case"]["n_fluid"],
            "n_boundary": res["case"]["n_boundary"], "steps": part["steps"],
            "warmup_steps": prev["steps"], "wall_s": wall,
            "particle_steps_per_s": n * part["steps"] / wall,
            "dt_mean": (part["t"] - prev["t"]) / part["steps"],
            "wall_per_sim_s": wall / (part["t"] - prev["t"]), "t_timed": [prev["t"], part["t"]],
            "other_load_cores": max(0.0, (b1 - b0 - own) / (t1 - t0)),
            "other_load_over": "the whole solver process (set-up, warm-up, timed interval)",
            "threads": threads, "command": res["command"], "settings": res["case"]}


# --- comparison --------------------------------------------------------------------------

def nearest_fixed(name, n):
    rows = FIXED_PEERS[name]["rows"]
    return min(rows, key=lambda r: abs(math.log(r["n_particles"] / n)))


def best_of(fns, repeat, wait, quiet_load, extra):
    """Best (highest particle-steps/s) of ``repeat`` rounds of the runs ``fns``, each after
    waiting for a quiet machine, and up to ``extra`` more rounds while no run had other
    processes under ``quiet_load`` cores; all rates are kept. ``loaded`` marks a best run
    taken while the machine was busy."""
    runs = []
    for i in range(repeat + extra):
        if i >= repeat and min(r["other_load_cores"] for r in runs) < quiet_load:
            break
        if i >= repeat:
            print("    (every run so far shared the machine; one more round)", flush=True)
        for fn in fns:
            wait_idle(wait)
            runs.append(fn())
    best = dict(max(runs, key=lambda r: r["particle_steps_per_s"]))
    best["loaded"] = best["other_load_cores"] >= quiet_load
    best["all_runs_particle_steps_per_s"] = [r["particle_steps_per_s"] for r in runs]
    best["all_runs_other_load_cores"] = [r["other_load_cores"] for r in runs]
    if len(fns) > 1:
        best["all_runs_omp_wait_policy"] = [r["omp_wait_policy"] for r in runs]
    return best


def compare(row):
    ours, py = row.get("ours"), row.get("pysph")
    n = (ours or py or {}).get("n_particles") or row["target"]
    row.pop("dualsphysics_fixed", None)
    ds = row.get("dsph") or {}
    row["jaxsph_fixed"] = (nearest_fixed("JAX-SPH", n)
                           if n < 2 * FIXED_PEERS["JAX-SPH"]["rows"][-1]["n_particles"]
                           else None)
    rate = (ours or {}).get("particle_steps_per_s")
    row["ratio_ours_over_pysph"] = (rate / py["particle_steps_per_s"]
                                    if rate and py and "particle_steps_per_s" in py else None)
    row["ratio_ours_over_dualsphysics"] = (
        rate / ds["particle_steps_per_s"] if rate and ds.get("particle_steps_per_s") else None)
    if ours and ours.get("dt") and rate:
        ours["wall_per_sim_s"] = ours["n_particles"] / rate / ours["dt"]
    row["sim_speed_ours_over_dualsphysics"] = (
        ds["wall_per_sim_s"] / ours["wall_per_sim_s"]
        if (ours or {}).get("wall_per_sim_s") and ds.get("wall_per_sim_s") else None)
    row["ratio_ours_over_jaxsph"] = (rate / row["jaxsph_fixed"]["particle_steps_per_s"]
                                     if rate and row["jaxsph_fixed"] else None)
    if (ours or {}).get("steps") and (py or {}).get("steps") and py["steps"] != ours["steps"]:
        row["warning"] = f"steps differ: ours {ours['steps']}, PySPH {py['steps']}"
    return row


def fmt_m(x, loaded=False):
    return (f"{x / 1e6:6.2f} M" + ("~" if loaded else " ")) if x else "     —   "


def print_table(rows):
    print("\n2D dam break, particle-steps/s (fluid + boundary particles; best of the runs)")
    head = (f"{'size':>6} | {'ours N':>7} {'ours':>9} | {'PySPH N':>7} {'PySPH':>9} | "
            f"{'ours/PySPH':>10} | {'DSPH N':>7} {'DSPH':>9} {'ours/DSPH':>9} | "
            f"{'wall/sim-s ours':>15} {'DSPH':>7} | {'JAX-SPH* N':>10} {'JAX-SPH*':>8}")
    print(head)
    print("-" * len(head))
    for r in rows:
        o, p = r.get("ours") or {}, r.get("pysph") or {}
        d, j = r.get("dsph") or {}, r["jaxsph_fixed"] or {}
        ratio = r["ratio_ours_over_pysph"]
        rd = r["ratio_ours_over_dualsphysics"]
        wo, wd = o.get("wall_per_sim_s"), d.get("wall_per_sim_s")
        print(f"{r['target']:>6} | {o.get('n_particles', '—'):>7} "
              f"{fmt_m(o.get('particle_steps_per_s'), o.get('loaded'))} | "
              f"{p.get('n_particles', '—'):>7} "
              f"{fmt_m(p.get('particle_steps_per_s'), p.get('loaded'))} | "
              f"{(f'{ratio:.3f}' if ratio else '—'):>10} | {d.get('n_particles', '—'):>7} "
              f"{fmt_m(d.get('particle_steps_per_s'), d.get('loaded'))} "
              f"{(f'{rd:.3f}' if rd else '—'):>9} | "
              f"{(f'{wo:.1f} s' if wo else '—'):>15} {(f'{wd:.1f} s' if wd else '—'):>7} | "
              f"{j.get('n_particles', '—'):>10} {fmt_m(j.get('particle_steps_per_s'))}")
        for side in ("ours", "pysph", "dsph"):
            if (r.get(side) or {}).get("error"):
                print(f"       {side} failed: {r[side]['error'].splitlines()[0]}")
        if r.get("warning"):
            print(f"       warning: {r['warning']}")
    print("DSPH: DualSPHysics 5.4 CPU, 2 threads, built from source, on our particles "
          "(its own CFL step); wall/sim-s: wall seconds per simulated second early in the "
          "flow; * fixed figure measured earlier: JAX-SPH 0.1.0 float32")
    if any((r.get(s) or {}).get("loaded") for r in rows for s in ("ours", "pysph", "dsph")):
        print("~ every run at this size shared the machine with other processes "
              "(other_load_cores in peers.json): an underestimate, re-run when quiet")


def print_front(front):
    print("\nWhole K&O window (T <= 2.75), same particles: front error and wall time")
    for r in front:
        print(f"  {r['label']:30s} a/dx {r['a_over_dx']:5.1f}  worst vs K&O "
              f"{100 * r['vs_ko']['worst']:+5.1f} % at T = {r['vs_ko']['T_worst']:.2f}  "
              f"{r['steps']:>6} steps  wall {r['wall_s']:6.1f} s  "
              f"({r['wall_per_sim_s']:.1f} s per simulated s"
              + (f"; {r['first_call_wall_s']:.1f} s in the process's first call, with "
                 "tracing and compilation" if "first_call_wall_s" in r else "") + ")")


def plot(rows, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(7.0, 5.2))
    hollow_label = "hollow: measured while the machine was busy"
    for key, label, style, color in (("ours", "fpsi_jax (ours, float32, JAX CPU)", "o-", "C0"),
                                     ("pysph", "PySPH 1.0b2 (OpenMP, 2 threads)", "s-", "C1")):
        pts = sorted((r[key]["n_particles"], r[key]["particle_steps_per_s"],
                      bool(r[key].get("loaded")))
                     for r in rows if (r.get(key) or {}).get("particle_steps_per_s"))
        if pts:
            n, rate, loaded = zip(*pts)
            ax.plot(n, rate, style, color=color, label=label)
            hollow = [(a, b) for a, b, c in pts if c]
            if hollow:
                ax.plot(*zip(*hollow), style[0], color=color, mfc="white", label=hollow_label)
                hollow_label = "_nolegend_"
    pts = sorted((r["dsph"]["n_particles"], r["dsph"]["particle_steps_per_s"])
                 for r in rows if (r.get("dsph") or {}).get("particle_steps_per_s"))
    if pts:
        ax.plot(*zip(*pts), "^-", color="C2",
                label="DualSPHysics 5.4 (built from source, OpenMP, 2 threads)")
    for name, style, color in (("JAX-SPH", "v--", "C3"),):
        p = FIXED_PEERS[name]
        pts = [(q["n_particles"], q["particle_steps_per_s"]) for q in p["rows"]]
        ax.plot(*zip(*pts), style, color=color, alpha=0.7,
                label=f"{name} {p['version']} ({p['mode']}; earlier, fixed)")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("particles (fluid + boundary)")
    ax.set_ylabel("particle-steps / s")
    ax.set_title("2D dam break on this machine (2 cores)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.16), ncol=2)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


# --- main --------------------------------------------------------------------------------

def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", type=int, nargs="*", default=[5000, 20000],
                    help="target particle counts (fluid + boundary); 80000 is optional")
    ap.add_argument("--steps", type=int, default=200,
                    help="timed steps on each side (after as many warm-up steps)")
    ap.add_argument("--repeat", type=int, default=2, help="runs per size and side; best kept")
    ap.add_argument("--threads", type=int, default=os.cpu_count(),
                    help="OMP_NUM_THREADS for PySPH")
    ap.add_argument("--omp-wait-policy", nargs="+", default=["default", "PASSIVE"],
                    choices=["default", "ACTIVE", "PASSIVE"],
                    help="OMP_WAIT_POLICY values PySPH is run with, each --repeat times "
                         "(best kept); 'default' leaves libgomp's own (spin, then sleep), "
                         "which slows 2 threads many times over when another process "
                         "holds a core")
    ap.add_argument("--wait-idle", type=float, default=60.0,
                    help="before each run wait up to this many s for a quiet machine")
    ap.add_argument("--quiet-load", type=float, default=0.25,
                    help="a run is 'loaded' when other processes used ≥ this many cores")
    ap.add_argument("--extra-tries", type=int, default=3,
                    help="more rounds (per size and side) while every run was loaded")
    ap.add_argument("--venv", default=DEFAULT_VENV, help="PySPH's virtual environment")
    ap.add_argument("--skip-install", action="store_true",
                    help="use the PySPH venv as it is (no pip)")
    ap.add_argument("--reinstall", action="store_true", help="delete the venv and rebuild")
    side = ap.add_mutually_exclusive_group()
    side.add_argument("--ours-only", action="store_true",
                      help="measure us only; keep the PySPH figures of peers.json")
    side.add_argument("--pysph-only", action="store_true",
                      help="measure PySPH only; keep our figures of peers.json")
    ap.add_argument("--no-dsph", action="store_true",
                    help="leave DualSPHysics out (its last figures in peers.json are kept)")
    ap.add_argument("--no-pysph", action="store_true",
                    help="leave PySPH out (its last figures in peers.json are kept, and ours "
                         "run at the particle counts they matched)")
    ap.add_argument("--front-dx", type=float, nargs="*", default=[],
                    help="also run ours and DualSPHysics over the whole K&O window at these "
                         "dx: front error and wall time (e.g. 0.005 0.0025)")
    args = ap.parse_args()
    venv = os.path.abspath(os.path.expanduser(args.venv))
    dsph_on = not (args.no_dsph or args.ours_only or args.pysph_only)
    dsph_info = {}
    if dsph_on:
        import dualsphysics
        try:
            print("DualSPHysics: building from source if needed (~6 min once)", flush=True)
            exe, _, secs = dualsphysics.build()
            dsph_info = {"status": "built", "solver": exe, "build_s": round(secs, 1),
                         "source": dualsphysics.REPO_URL}
        except (dualsphysics.DsphError, OSError) as e:
            dsph_on = False
            dsph_info = {"status": "build failed", "error": str(e)}
            print(f"\n*** DualSPHysics could not be built: {e}\n", flush=True)
    policies = [None if p == "default" else p for p in args.omp_wait_policy]

    cache = {}
    if os.path.exists(OUT_JSON):
        with open(OUT_JSON) as fh:
            old = json.load(fh)
        cache = {r["target"]: r for r in old.get("sizes", [])}
        pysph_info = old.get("pysph", {})
        old_dsph_info, old_front = old.get("dualsphysics", {}), old.get("front", [])
        old_machine, old_settings = old.get("machine"), old.get("settings")
    else:
        pysph_info, old_dsph_info, old_front = {}, {}, []
        old_machine = old_settings = None
    measured = bool(args.sizes or args.front_dx)   # else: the table is rewritten only

    # PySPH: install, then one driver run per size
    pysph_ok = False
    if not (args.ours_only or args.no_pysph):
        pysph_info = {**pysph_info, "venv": venv, "spec": PYSPH_SPEC, "install_steps":
                      [" ".join(["pip"] + s) for s in INSTALL_STEPS]}
        try:
            if args.skip_install:
                if not pysph_importable(venv):
                    raise PeerError(f"--skip-install, but PySPH does not import from {venv}")
            else:
                install_pysph(venv, args.reinstall)
            driver = write_driver(venv)
            pysph_ok = True
            pysph_info["status"] = "installed"
        except (PeerError, subprocess.TimeoutExpired, OSError) as e:
            pysph_info.update(status="install failed", error=str(e))
            print(f"\n*** PySPH could not be installed: {e}\n*** Reporting our figures and "
                  "the fixed peer figures only.\n", flush=True)

    rows = []
    for target in args.sizes:
        row = dict(cache.get(target, {}), target=target)
        for k in ("warning",):
            row.pop(k, None)
        if not args.ours_only and pysph_ok:
            try:
                pick = pysph_pick(venv, driver, target)
                print(f"[{target}] PySPH dx={pick['dx']} m  N={pick['n_fluid'] + pick['n_boundary']}"
                      f"  ({args.repeat} × {len(policies)} × {2 * args.steps} steps)",
                      flush=True)
                row["pysph"] = best_of(
                    [lambda pol=pol: pysph_run(venv, driver, pick["dx"], args.steps,
                                               args.threads, pol)
                     for pol in policies], args.repeat, args.wait_idle, args.quiet_load,
                    args.extra_tries)
                p = row["pysph"]
                pysph_info["versions"] = p["versions"]
                print(f"    {p['particle_steps_per_s'] / 1e6:.2f} M particle-steps/s  wall "
                      f"{p['wall_s']:.2f} s  cpu/wall {p['cpu_over_wall']:.2f}  others "
                      f"{p['other_load_cores']:.2f} cores  set-up {p['setup_s']:.1f} s  "
                      f"OMP_WAIT_POLICY {p['omp_wait_policy']}  "
                      f"runs {[round(x / 1e6, 2) for x in p['all_runs_particle_steps_per_s']]} M",
                      flush=True)
            except (PeerError, subprocess.TimeoutExpired, OSError, KeyError) as e:
                row["pysph"] = {"error": str(e)}
                print(f"    PySPH failed at size {target}: {e}", flush=True)
        elif not (args.ours_only or args.no_pysph):
            row["pysph"] = {"error": pysph_info.get("error", "PySPH not installed")}
        if not args.pysph_only:
            py_n = (row.get("pysph") or {}).get("n_particles")
            dx = our_dx_for(py_n or target)
            print(f"[{target}] ours dx={dx * 1e3:.4g} mm  N={our_count(dx)} "
                  f"({args.repeat} × (compile + 2 × {args.steps} steps))", flush=True)
            try:
                row["ours"] = best_of([lambda: ours_run(dx, args.steps)], args.repeat,
                                      args.wait_idle, args.quiet_load, args.extra_tries)
                o = row["ours"]
                print(f"    {o['particle_steps_per_s'] / 1e6:.2f} M particle-steps/s  wall "
                      f"{o['wall_s']:.2f} s  others {o['other_load_cores']:.2f} cores  "
                      f"compile {o['compile_s']:.1f} s  rebuilds {o['rebuilds']}/{args.steps}"
                      f"  runs {[round(x / 1e6, 2) for x in o['all_runs_particle_steps_per_s']]}"
                      " M", flush=True)
            except Exception as e:  # a bad run must not lose the peers' figures
                row["ours"] = {"dx": dx, "error": f"{type(e).__name__}: {e}"}
                print(f"    ours failed at size {target}: {e}", flush=True)
        if dsph_on:
            dx = (row.get("ours") or {}).get("dx") or our_dx_for(target)
            print(f"[{target}] DualSPHysics dx={dx * 1e3:.4g} mm  N={our_count(dx)} "
                  f"({args.repeat} × ~2 × {args.steps} steps)", flush=True)
            try:
                row["dsph"] = best_of([lambda: dsph_run(dx, args.steps, args.threads)],
                                      args.repeat, args.wait_idle, args.quiet_load,
                                      args.extra_tries)
                d = row["dsph"]
                print(f"    {d['particle_steps_per_s'] / 1e6:.2f} M particle-steps/s  "
                      f"{d['steps']} steps in {d['wall_s']:.2f} s  others "
                      f"{d['other_load_cores']:.2f} cores  {d['wall_per_sim_s']:.1f} s per "
                      f"simulated s  runs "
                      f"{[round(x / 1e6, 2) for x in d['all_runs_particle_steps_per_s']]} M",
                      flush=True)
            except Exception as e:
                row["dsph"] = {"dx": dx, "error": f"{type(e).__name__}: {e}"}
                print(f"    DualSPHysics failed at size {target}: {e}", flush=True)
        rows.append(compare(row))

    # keep sizes measured before and not asked for now
    done = {r["target"] for r in rows}
    rows += [compare(dict(r)) for t, r in cache.items() if t not in done]
    rows.sort(key=lambda r: r["target"])
    front = []
    if args.front_dx:
        import dam_break_front_peers as fp
        ko = fp.load("koshizuka_oka1996_surge_front.csv")
        for dx in args.front_dx:
            for fn in ([fp.run_ours] + ([fp.run_dsph] if dsph_on else [])):
                wait_idle(args.wait_idle)
                r = fn(dx)
                if fn is fp.run_ours:  # the first call traces and loads the compiled step
                    first = r["wall_s"]
                    wait_idle(args.wait_idle)
                    r = fn(dx)
                    r["first_call_wall_s"] = first
                T, Z = np.asarray(r.pop("T")), np.asarray(r.pop("Z"))
                r["vs_ko"] = fp.errors(T, Z, ko)
                r["vs_ko"].pop("at_points")
                r["t_end"] = float(T[-1]) / math.sqrt(2 * 9.81 / (r["a_over_dx"] * dx))
                r["wall_per_sim_s"] = r["wall_s"] / r["t_end"]
                d = r.pop("dsph", None)
                if d:       # the solver's own runtimes: its set-up is the difference
                    r.update({k: d[k] for k in ("total_runtime_s", "simulation_runtime_s",
                                                "command") if k in d})
                front.append(r)
                print(f"    {r['label']}: {100 * r['vs_ko']['worst']:+.1f} % vs K&O, "
                      f"{r['wall_s']:.1f} s", flush=True)
    out = {
        "generated": time.strftime("%Y-%m-%d %H:%M:%S %Z"),
        "machine": machine_info() if measured else old_machine,
        "case": "2D dam break, same number of steps on both sides, particle count matched "
                "(fluid + boundary particles)",
        "ours_case": "cases.dam_break (Koshizuka & Oka: 0.146 × 0.292 m column, 0.584 m "
                     "tank; full physics: continuity, EOS, pressure + anti-clump, Morris "
                     "viscosity, artificial viscosity, XSPH, variable h, delta-SPH, "
                     "extrapolated boundary; leapfrog, one neighbour pass per step; float32)",
        "pysph_case": "pysph.examples.dam_break_2d, WCSPH scheme (Tait EOS, continuity, "
                      "momentum + artificial viscosity alpha 0.1, XSPH, h from rho, "
                      "hg-corrected boundary; WendlandQuintic, h = 1.3 dx; PEC integrator, "
                      "one evaluation per step; float64), h and m reset for --dx, fixed dt "
                      "0.125 h / c0, OpenMP",
        "timed": "wall clock of `steps` steps after `steps` warm-up steps on both sides; "
                 "no compile or set-up. Ours: bench_sph.bench(dx, steps) (XLA compile, one "
                 "warm-up chunk, one timed chunk; neighbour rebuilds included). PySPH: "
                 "time.perf_counter() in its post_step callback after step `steps` and "
                 "after step 2*steps (Cython generation/compile is in Application.setup, "
                 "before step 1; linked-list NNPS update every step included). Best of "
                 "`repeat` runs per side (PySPH: each with every OMP_WAIT_POLICY of "
                 "settings); other_load_cores = cores other processes used "
                 "during a run (shared machine), cpu_over_wall = cores PySPH got.",
        "settings": old_settings if not measured else {
            "steps": args.steps, "repeat": args.repeat, "threads": args.threads,
            "omp_wait_policies": args.omp_wait_policy, "wait_idle_s": args.wait_idle,
            "quiet_load_cores": args.quiet_load, "extra_tries": args.extra_tries},
        "pysph": pysph_info,
        "dualsphysics": dsph_info or old_dsph_info,
        "front": front or old_front,
        "fixed_peers": FIXED_PEERS,
        "sizes": rows,
    }
    os.makedirs(RESULTS, exist_ok=True)
    with open(OUT_JSON, "w") as fh:
        json.dump(out, fh, indent=1)
    print_table(rows)
    if front:
        print_front(front)
    try:
        plot(rows, OUT_PNG)
    except Exception as e:  # the plot is a convenience
        print(f"(no plot: {e})")
    print(f"\nwrote {os.path.relpath(OUT_JSON)}, {os.path.relpath(OUT_PNG)}")


if __name__ == "__main__":
    main()
