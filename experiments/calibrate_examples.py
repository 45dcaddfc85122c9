"""The data files of the calibration examples (examples/calibrate/*.toml).

    python experiments/calibrate_examples.py [synthetic static damping sloshing]

* cantilever_synthetic.csv  the tip of cantilever_synthetic.toml's own run (E = 10 MPa,
                            c = 4 1/s), sampled every millisecond
* cantilever_static.csv     Euler–Bernoulli's static tip deflection δ = PL³/(3EI) of the
                            strip under 1 N (1.6003 mm), as samples over the last tenth of
                            cantilever_static.toml's run
* cantilever_damping.csv    a free vibration decaying with damping ratio ζ = 0.05 at the
                            model strip's own first-mode frequency (measured from
                            cantilever_damping.toml's run), y = A e^(−ζωt) sin(ω_d t)
* sloshing_baffle_synthetic.csv  the baffle tip u_x of sloshing_baffle_synthetic.toml's
                            own run (E = 4 MPa, c = 10 1/s) every millisecond, plus
                            Gaussian noise of σ = 2 % of the largest |u_x| (seed 24)
The gate's data are the experiment's (examples/data/antoci2007_tip.csv).
"""
from __future__ import annotations

import math
import os
import sys

import numpy as np

from calibrate import usercase
from calibrate.targets import free_vibration
from fpsi_jax import scenefile
from fpsi_jax.cases.cantilever import tip_deflection

HERE = os.path.dirname(os.path.abspath(__file__))
EX = os.path.join(HERE, "..", "examples", "calibrate")
DATA = os.path.join(EX, "data")
EVERY = 1e-3          # sample spacing [s]


def write(name, comment, header, rows):
    path = os.path.join(DATA, name)
    with open(path, "w") as fh:
        for line in comment.strip().splitlines():
            fh.write(f"# {line}\n")
        fh.write(", ".join(header) + "\n")
        for r in rows:
            fh.write(", ".join(f"{v:.10g}" for v in r) + "\n")
    print("wrote", os.path.relpath(path))
    return path


def samples(t_end, t0=EVERY):
    return np.arange(round(t0 / EVERY), math.floor(t_end / EVERY + 1e-9) + 1) * EVERY


def synthetic():
    sf = scenefile.load(os.path.join(EX, "cantilever_synthetic.toml"))
    t, u = usercase.forward(sf, sf.scene.t_end)
    ts = samples(t[-1])
    ux = np.interp(ts, np.r_[0.0, t], np.r_[0.0, u[:, 0]])
    uy = np.interp(ts, np.r_[0.0, t], np.r_[0.0, u[:, 1]])
    write("cantilever_synthetic.csv",
          "Synthetic: the tip of cantilever_synthetic.toml's own run (E = 10 MPa, c = 4 1/s), "
          "sampled every 1 ms\nby experiments/calibrate_examples.py (linear interpolation "
          "of the per-step record).",
          ["t [s]", "tip.ux [mm]", "tip.uy [mm]"], np.stack([ts, ux * 1e3, uy * 1e3], 1))


def static():
    sf = scenefile.load(os.path.join(EX, "cantilever_static.toml"))
    w = sf.calibration["window"]
    L, E, h = 0.079375, sf.materials["beam"]["E"], 0.005
    delta = tip_deflection(1.0, L, E, h)
    ts = samples(w[1], w[0])
    ts = ts[ts >= w[0]]
    write("cantilever_static.csv",
          f"Euler–Bernoulli static tip deflection of K6.3.3's strip under P = 1 N: "
          f"δ = PL³/(3EI) = {delta * 1e3:.6g} mm\n(L = {L} m, E = {E:g} Pa, I = h³/12, "
          f"h = {h} m), as samples over the last tenth of the run (experiments/"
          "calibrate_examples.py).",
          ["t [s]", "tip.uy [mm]"], np.stack([ts, np.full_like(ts, -delta * 1e3)], 1))


def damping(zeta=0.05):
    sf = scenefile.load(os.path.join(EX, "cantilever_damping.toml"))
    t, u = usercase.forward(sf, sf.scene.t_end)
    f_n, _, _ = (float(a) for a in free_vibration(t, u[:, 1]))
    ts = samples(t[-1])
    wn = 2 * math.pi * f_n
    wd = wn * math.sqrt(1 - zeta ** 2)
    amp = float(np.max(np.abs(u[:, 1])))
    y = amp * np.exp(-zeta * wn * ts) * np.sin(wd * ts)
    write("cantilever_damping.csv",
          f"A free vibration decaying with damping ratio ζ = {zeta}: y = A e^(−ζωt) "
          f"sin(ω_d t), ω = 2π·{f_n:.6g} Hz (the\nmodel strip's own first mode, measured "
          f"from cantilever_damping.toml's run), A = {amp * 1e3:.4g} mm, sampled every "
          "1 ms\n(experiments/calibrate_examples.py).",
          ["t [s]", "tip.uy [mm]"], np.stack([ts, y * 1e3], 1))


def noisy_record(sf, noise=0.02, seed=24, every=EVERY):
    """(t, u_x + noise) of the file's probe in its own run, sampled every ``every`` s, the
    noise Gaussian with σ = ``noise`` × the largest |u_x|."""
    t, u = usercase.forward(sf, sf.scene.t_end)
    ts = np.arange(1, math.floor(t[-1] / every + 1e-9) + 1) * every
    ux = np.interp(ts, np.r_[0.0, t], np.r_[0.0, u[:, 0]])
    rng = np.random.default_rng(seed)
    return ts, ux + rng.normal(0.0, noise * np.abs(ux).max(), ux.shape)


def sloshing(noise=0.02, seed=24):
    sf = scenefile.load(os.path.join(EX, "sloshing_baffle_synthetic.toml"))
    ts, y = noisy_record(sf, noise, seed)
    write("sloshing_baffle_synthetic.csv",
          f"Synthetic: the baffle tip of sloshing_baffle_synthetic.toml's own run (E = 4 MPa, "
          f"c = 10 1/s), sampled every 1 ms,\nplus Gaussian noise of σ = {noise:g} × the "
          f"largest |u_x| (numpy default_rng({seed})); experiments/calibrate_examples.py.",
          ["t [s]", "tip.ux [mm]"], np.stack([ts, y * 1e3], 1))


if __name__ == "__main__":
    os.makedirs(DATA, exist_ok=True)
    which = sys.argv[1:] or ["synthetic", "static", "damping", "sloshing"]
    for name in which:
        globals()[name]()
