"""Synthetic-truth calibration of a new case, at a coarse resolution: the sloshing tank's
elastic baffle (examples/calibrate/sloshing_baffle_synthetic.toml, fluid spacing doubled,
5 mm discs). Its own run with E = 4 MPa and c = 10 1/s, sampled every millisecond with 2 %
Gaussian noise, is fitted from twice the truth by ``fpsi calibrate``'s LM (forward-mode
Jacobian, float64) in at most 30 steps, to the noise floor, and each parameter lands within
three reported standard errors of the truth.

Why three: with correct error bars a fitted value lies within one standard error of the
truth in 68 % of noise draws and within three in 99.7 %, so one draw cannot be held to one
standard error. For this draw (the seed of the shipped data file) E lands 1.4 and c 2.2
standard errors off; the coverage over several draws, at this resolution and at the file's,
is measured by experiments/calibrate_sloshing_synthetic.py."""
import math
import pathlib

import numpy as np
import pytest

from calibrate import usercase
from calibrate.cli import LOSS_TOL, PATIENCE, REL_TOL
from calibrate.fit import fit
from fpsi_jax import scenefile

FILE = (pathlib.Path(__file__).resolve().parents[2] / "examples" / "calibrate"
        / "sloshing_baffle_synthetic.toml")
TRUE = {"baffle.E": 4.0e6, "dem.damping": 10.0}
SEED = 24            # the seed of the shipped data file, not chosen by the outcome


def coarse_case():
    spec = scenefile.read(str(FILE))
    spec["fluid"]["dx"] *= 2
    for s in spec["structure"]:
        s["d"] = 0.005
    return scenefile.compose(spec, str(FILE))


def noisy_record(sf, path, noise=0.02, every=1e-3):
    t, u = usercase.forward(sf, sf.scene.t_end)
    ts = np.arange(1, math.floor(t[-1] / every + 1e-9) + 1) * every
    ux = np.interp(ts, np.r_[0.0, t], np.r_[0.0, u[:, 0]])
    y = ux + np.random.default_rng(SEED).normal(0.0, noise * np.abs(ux).max(), ux.shape)
    with open(path, "w") as fh:
        fh.write("t [s], tip.ux [mm]\n")
        fh.writelines(f"{a:.6g}, {b * 1e3:.10g}\n" for a, b in zip(ts, y))


@pytest.mark.slow             # ~150 s on 2 cores: make test-slow
def test_sloshing_baffle_recovers_E_and_damping_from_twice_off(tmp_path):
    sf = coarse_case()
    assert float(sf.scene.params.get("dem.damping")) == TRUE["dem.damping"]
    assert sf.materials["baffle"]["E"] == TRUE["baffle.E"]
    data = tmp_path / "tip.csv"
    noisy_record(sf, data)
    s = usercase.settings(sf, data=str(data))
    assert s.jacobian == "ad" and s.start == ("baffle.E=8e6", "damping=20")
    case = usercase.build(sf, s)
    res = fit(case.calibration, optimizer=s.optimizer, max_steps=s.steps, loss_tol=LOSS_TOL,
              rel_tol=REL_TOL, patience=PATIENCE, jacobian=s.jacobian, progress=False)
    assert res.start["baffle.E"] == pytest.approx(2 * TRUE["baffle.E"])
    assert res.start["dem.damping"] == pytest.approx(2 * TRUE["dem.damping"])
    assert res.steps <= 30
    # the residual left is the noise: σ = 2 % of max |u_x| over m samples, residuals / √m
    m = len(case.t)
    assert res.stderr["s"] == pytest.approx(0.02 / math.sqrt(m), rel=0.15)
    for name, true in TRUE.items():
        err = res.stderr[name]["std_error"]
        assert err < 0.2 * true                  # identified: c to ~15 %, E to ~0.2 %
        assert abs(res.best[name] - true) <= 3 * err, (name, res.best[name], err)
