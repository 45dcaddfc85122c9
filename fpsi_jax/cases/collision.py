"""``fpsi validate`` cases of the solid side: DEM contacts and parallel bonds (issue 3).

Analytic references are computed from the parameters of the scene as built (so ``--set``
checks a user's variant). Registered on import by :mod:`fpsi_jax.validate`.
"""
from __future__ import annotations

import math
import time

import numpy as np

from ..run.simulate import simulate
from ..solver import timestep
from . import overrides as ov
from .beams import euler_bernoulli_f1, tip_deflection
from .registry import Record, register


def _crossings(t, y, rising=False):
    """Times where y crosses 0 downwards (upwards if ``rising``), linearly interpolated."""
    s = np.sign(y)
    k = np.where((s[:-1] < 0) & (s[1:] >= 0) if rising else (s[:-1] > 0) & (s[1:] <= 0))[0]
    return t[k] + (t[k + 1] - t[k]) * y[k] / (y[k] - y[k + 1])


# --- collision ---------------------------------------------------------------------------
def collision_run(beta, overrides=None, steps_per_contact=300):
    """Run the two-disc collision at ``steps_per_contact`` steps over the analytic contact
    time (an accuracy setting, independent of the stability bound: the derived step resolves
    a contact with only ≈ 4 steps); returns (e, contact time, e_ref, tc_ref, scene, result)."""
    scene, phys = ov.build("collision", overrides or {}, {"beta": beta})
    beta, kn = float(scene.params.dem.beta_n), float(scene.params.dem.kn)
    m = 0.5 * float(scene.solid.mass[0])                  # reduced mass of the pair
    e_ref = math.exp(-math.pi * beta / math.sqrt(1 - beta ** 2))
    tc_ref = math.pi / math.sqrt(kn / m * (1 - beta ** 2))
    dt = min(tc_ref / steps_per_contact, timestep.stable_dt(scene))
    res = simulate(scene, progress=False, dt=dt, **phys,
                   observe=lambda s: (s.solid.x[1, 0] - s.solid.x[0, 0],
                                      s.solid.v[1, 0] - s.solid.v[0, 0]))
    gap, vrel = (np.asarray(a) for a in res.observations)
    kw = scene.builder_kwargs
    R = float(scene.solid.radius[0])
    t = dt * np.arange(1, len(gap) + 1)
    overlap = np.concatenate([[2 * R - (scene.solid.x[1, 0] - scene.solid.x[0, 0])],
                              2 * R - gap])
    t = np.concatenate([[0.0], t])
    t_in = _crossings(t, -overlap, rising=False)[0]      # overlap becomes > 0
    t_out = _crossings(t, overlap, rising=False)[0]      # overlap returns to 0
    e = abs(float(vrel[-1])) / (2 * kw["speed"])
    return e, t_out - t_in, e_ref, tc_ref, scene, res


@register("collision", "two discs head-on, β = 0, 0.1, 0.3: restitution (1 %), duration (2 %)")
def collision(quick: bool = False, overrides: dict | None = None):
    out = []
    for beta in (0.0, 0.1, 0.3):
        t0 = time.perf_counter()
        e, tc, e_ref, tc_ref, scene, res = collision_run(beta, overrides)
        wall = time.perf_counter() - t0
        info = {**scene.builder_kwargs, "dt": float(res.params.dt), "steps": res.n_steps}
        re, rt = abs(e - e_ref) / e_ref, abs(tc - tc_ref) / tc_ref
        out += [Record("collision", f"restitution, beta = {beta}", e, e_ref, re, 0.01,
                       re < 0.01, wall, info),
                Record("collision", f"contact time [s], beta = {beta}", tc, tc_ref, rt, 0.02,
                       rt < 0.02, wall, info)]
    return out


# --- rolling -----------------------------------------------------------------------------
@register("rolling", "disc sliding without spin (μ = 0.3) ends rolling at 2/3 v0 (1 %)")
def rolling(quick: bool = False, overrides: dict | None = None):
    scene, phys = ov.build("rolling", overrides or {})
    t0 = time.perf_counter()
    res = simulate(scene, progress=False, **phys,
                   observe=lambda s: (s.solid.v[0, 0], s.solid.omega[0]))
    wall = time.perf_counter() - t0
    v, w = (np.asarray(a) for a in res.observations)
    v0 = scene.builder_kwargs["speed"]
    tail = v[int(0.8 * len(v)):]
    ratio = float(tail.mean()) / v0
    ref = 2.0 / 3.0
    err = abs(ratio - ref) / ref
    info = {**scene.builder_kwargs, "steps": res.n_steps, "dt": float(res.params.dt),
            "omega_R_over_v0": float(-w[-1] * scene.solid.radius[0] / v0)}
    return [Record("rolling", "final speed / v0 (mean of last 20 %)", ratio, ref, err, 0.01,
                   err < 0.01, wall, info)]


# --- static beams ------------------------------------------------------------------------
def tip_run(scene, phys, tip):
    """Run ``scene`` observing the mean vertical displacement of the discs ``tip`` every
    step; returns (displacements, result, wall seconds)."""
    y0 = float(scene.solid.x[tip, 1].mean())
    t0 = time.perf_counter()
    res = simulate(scene, progress=False, **phys, observe=lambda s: s.solid.x[tip, 1].mean() - y0)
    return np.asarray(res.observations), res, time.perf_counter() - t0


@register("itasca_beam", "K6.1 / Itasca 11-ball parallel-bond beam, tip deflection (0.2 %)")
def itasca_beam(quick: bool = False, overrides: dict | None = None):
    scene, phys = ov.build("itasca_beam", overrides or {})
    y, res, wall = tip_run(scene, phys, np.abs(scene.solid.f_ext[:, 1]) > 0)
    kw = scene.builder_kwargs
    E = kw["kn_bar"] * 2 * kw["radius"]
    I = math.pi * kw["bond_radius"] ** 4 / 4
    L = 2 * kw["radius"] * (kw["n_balls"] - 1)
    ref = kw["load"] * L ** 3 / (3 * E * I)
    val = -float(y[-1])
    err = abs(val - ref) / ref
    settle = abs(float(y[-1] - y[int(0.9 * len(y))])) / ref
    info = {**kw, "steps": res.n_steps, "dt": float(res.params.dt),
            "value_in": val / 0.0254, "reference_in": ref / 0.0254, "last_10pct_change": settle}
    return [Record("itasca_beam", "tip deflection [m]", val, ref, err, 0.002, err < 0.002,
                   wall, info)]


def cantilever_static(overrides=None, base=None):
    scene, phys = ov.build("cantilever", overrides or {}, {"variant": "tip", **(base or {})})
    y, res, wall = tip_run(scene, phys, np.abs(scene.solid.f_ext[:, 1]) > 0)
    return -float(y[-1]), abs(float(y[-1] - y[int(0.9 * len(y))])) / abs(float(y[-1])), \
        scene, res, wall


@register("cantilever", "K6.3.3 rubber cantilever, 1 N tip load: deflection vs PL³/(3EI) (3 %)")
def cantilever(quick: bool = False, overrides: dict | None = None):
    base = {"d": 0.0025} if quick else {}
    val, settle, scene, res, wall = cantilever_static(overrides, base)
    kw = scene.builder_kwargs
    ref = tip_deflection(kw["load"], kw["length"], kw["E"], kw["height"])
    span = kw["length"] - float(scene.solid.x[scene.solid.fixed, 0].max())
    ref_built = tip_deflection(kw["load"], span, kw["E"], kw["height"])
    err = abs(val - ref) / ref
    info = {**kw, "quick": quick, "n_discs": scene.solid.n, "steps": res.n_steps,
            "dt": float(res.params.dt), "last_10pct_change": settle,
            "as_built_span": span, "reference_as_built_span": ref_built,
            "error_vs_as_built_span": (val - ref_built) / ref_built}
    return [Record("cantilever", "tip deflection [m] vs nominal L", val, ref, err, 0.03,
                   err < 0.03, wall, info)]


@register("cantilever_frequency", "cantilever free vibration f1 vs Euler–Bernoulli (5 %)")
def cantilever_frequency(quick: bool = False, overrides: dict | None = None):
    base = {"variant": "free", **({"d": 0.0025} if quick else {})}
    scene, phys = ov.build("cantilever", overrides or {}, base)
    x = scene.solid.x
    y, res, wall = tip_run(scene, phys, np.abs(x[:, 0] - x[:, 0].max()) < 1e-9)
    dt = float(res.params.dt)
    tc = _crossings(dt * np.arange(1, len(y) + 1), y)
    f = (len(tc) - 1) / (tc[-1] - tc[0])
    kw = scene.builder_kwargs
    ref = euler_bernoulli_f1(kw["E"], kw["rho"], kw["height"], kw["length"])
    span = kw["length"] - float(x[scene.solid.fixed, 0].max())
    err = abs(f - ref) / ref
    info = {**kw, "quick": quick, "n_discs": scene.solid.n, "steps": res.n_steps, "dt": dt,
            "periods": len(tc) - 1, "as_built_span": span,
            "reference_as_built_span": euler_bernoulli_f1(kw["E"], kw["rho"], kw["height"], span)}
    return [Record("cantilever_frequency", "first natural frequency [Hz]", f, ref, err, 0.05,
                   err < 0.05, wall, info)]


# --- bond fracture -----------------------------------------------------------------------
@register("bond_tension", "bonded bar pulled apart: breaks at F/A = σ̄_c (1 %)")
def bond_tension(quick: bool = False, overrides: dict | None = None):
    scene, phys = ov.build("bond_tension", overrides or {})
    t0 = time.perf_counter()
    res = simulate(scene, progress=False, **phys)
    wall = time.perf_counter() - t0
    b = res.state.bonds
    tb = np.asarray(b.t_break)
    kw = scene.builder_kwargs
    broke = tb >= 0
    area = kw["d"] * float(res.params.bond.lam) * float(res.params.bond.thickness)
    if not broke.any():
        return [Record("bond_tension", "stress at break [Pa]", float("nan"), kw["sigma_c"],
                       float("inf"), 0.01, False, wall, {**kw, "note": "no bond broke"})]
    t_first = float(tb[broke].min())
    force = float(scene.solid.f_ext[-1, 0]) * min(1.0, t_first / kw["ramp_time"])
    sigma = force / area
    err = abs(sigma - kw["sigma_c"]) / kw["sigma_c"]
    mode = int(np.asarray(b.mode)[broke][np.argmin(tb[broke])])
    info = {**kw, "steps": res.n_steps, "dt": float(res.params.dt), "t_break": t_first,
            "bond": int(np.flatnonzero(broke)[np.argmin(tb[broke])]),
            "mode": {1: "tension", 2: "shear"}[mode], "n_broken": int(broke.sum())}
    return [Record("bond_tension", "applied stress F/A at the first break [Pa]", sigma,
                   float(kw["sigma_c"]), err, 0.01, err < 0.01 and mode == 1, wall, info)]
