"""Fluid–particle validation cases (issue 5): terminal velocity against the drag law's own
force balance, a neutrally buoyant grain, and the Glowinski sedimentation case against a
published y(t) (W6.2.1); registered with ``fpsi validate``."""
from __future__ import annotations

import time

import numpy as np

from ..model.errors import ParameterError
from ..physics import fpi
from ..run.simulate import simulate
from . import overrides as ov
from .registry import Record, load_csv, register

SEDIMENTATION_REFERENCE = "sedimentation_zhang2019_fpm_pst_y_position.csv"


def grain_observer(state):
    """(position, velocity, Shepard fluid velocity ū_f, voidage ε_p) of the first grain."""
    k = state.fpi.idx[0]
    return state.solid.x[k], state.solid.v[k], state.fpi.u_f[0], state.fpi.eps_p[0]


def grain_run(scene, **kw):
    """Run a one-grain scene; returns (t, x, v, u_f, ε_p, result) per step."""
    res = simulate(scene, progress=False, observe=grain_observer, **kw)
    x, v, u, e = (np.asarray(a, float) for a in res.observations)
    t = (np.arange(x.shape[0]) + 1) * float(res.params.dt)
    return t, x, v, u, e, res


def terminal_slip(eps, rho_p, rho_f, d, mu, g):
    """The slip s at which the drag law balances weight minus buoyancy,
    (ρ_p − ρ_f) g = β(ε, s)/(1 − ε) s (W19–W23 per unit grain volume), by bisection."""
    def excess(s):
        return (rho_p - rho_f) * g - float(fpi.interphase_beta(eps, s, rho_f, d, mu)) / (1 - eps) * s
    lo, hi = 0.0, 1.0
    while excess(hi) > 0:
        hi *= 2.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if excess(mid) > 0 else (lo, mid)
    return 0.5 * (lo + hi)


def _info(scene, res, quick, **extra):
    return {**scene.builder_kwargs, "quick": quick, "n_particles": scene.n_particles,
            "steps": res.n_steps, "dt": float(res.params.dt), **extra}


@register("terminal_velocity", "isolated small grain (ε → 1) settling: mean slip vs the "
          "root of the drag law's force balance")
def terminal_velocity(quick: bool = False, overrides: dict | None = None):
    base = dict(width=0.02, height=0.03, d=0.0005, rho_grain=5000.0, y0=0.025, x64=True,
                t_end=0.15 if quick else 0.3)
    scene, phys = ov.build("sedimentation", overrides or {}, base)
    t0 = time.perf_counter()
    t, x, v, u, e, res = grain_run(scene, every=scene.t_end / 5, **phys)
    wall = time.perf_counter() - t0
    kw = scene.builder_kwargs
    late = t > t[-1] / 3
    slip = float(np.mean(u[late, 1] - v[late, 1]))
    eps = float(np.mean(e[late]))
    g = float(-np.asarray(res.params.gravity)[1])
    ref = terminal_slip(eps, kw["rho_grain"], kw["rho_fluid"], kw["d"], kw["mu"], g)
    rel = abs(slip - ref) / ref
    info = _info(scene, res, quick, eps_p=eps, window_s=[float(t[late][0]), float(t[-1])],
                 grain_velocity=float(-np.mean(v[late, 1])),
                 fluid_velocity_at_grain=float(-np.mean(u[late, 1])))
    return [Record("terminal_velocity", "mean slip |u_f - v_p| [m/s]", slip, ref, rel, 0.02,
                   rel < 0.02, wall, info)]


@register("neutral_buoyancy", "grain of the fluid's density in still water: largest drift "
          "over 0.5 s, in diameters")
def neutral_buoyancy(quick: bool = False, overrides: dict | None = None):
    base = dict(rho_grain=1000.0, x64=True, t_end=0.25 if quick else 0.5)
    over = dict(overrides or {})
    scene, phys = ov.build("sedimentation", over, base)
    kw = scene.builder_kwargs
    if kw["rho_grain"] != kw["rho_fluid"]:
        raise ParameterError("neutral_buoyancy needs rho_grain == rho_fluid")
    t0 = time.perf_counter()
    t, x, v, u, e, res = grain_run(scene, every=scene.t_end / 5, **phys)
    wall = time.perf_counter() - t0
    drift = float(np.max(np.linalg.norm(x - np.array([kw["x0"], kw["y0"]]), axis=1)) / kw["d"])
    info = _info(scene, res, quick, final_drift_d=float(
        np.linalg.norm(x[-1] - np.array([kw["x0"], kw["y0"]])) / kw["d"]))
    return [Record("neutral_buoyancy", "max drift / d", drift, 0.0, drift, 0.1, drift < 0.1,
                   wall, info)]


def sedimentation_metrics(t, y, ref, y0):
    """RMS of y − y_ref over the reference times (relative to the fall y0 − y_ref,end) and
    the settling velocity (slope of a straight-line fit for 0.2 ≤ t ≤ 0.6 s) of ours and
    of the reference."""
    mask = ref[:, 0] <= t[-1]
    yi = np.interp(ref[mask, 0], t, y)
    rms = float(np.sqrt(np.mean((yi - ref[mask, 1]) ** 2)) / (y0 - ref[-1, 1]))
    win = (ref[:, 0] >= 0.2) & (ref[:, 0] <= 0.6)
    v_ref = -np.polyfit(ref[win, 0], ref[win, 1], 1)[0]
    ours = (t >= 0.2) & (t <= 0.6)
    v_ours = -np.polyfit(t[ours], y[ours], 1)[0] if ours.sum() > 10 else float("nan")
    return rms, float(v_ours), float(v_ref)


@register("sedimentation", "single grain in the Glowinski channel (W6.2.1): y(t) and "
          "settling velocity vs Zhang 2019 FPM")
def sedimentation(quick: bool = False, overrides: dict | None = None):
    base = dict(t_end=0.3) if quick else {}
    scene, phys = ov.build("sedimentation", overrides or {}, base)
    t0 = time.perf_counter()
    t, x, v, u, e, res = grain_run(scene, every=scene.t_end / 10, **phys)
    wall = time.perf_counter() - t0
    ref = load_csv(SEDIMENTATION_REFERENCE)
    ref = ref[np.argsort(ref[:, 0])]
    rms, v_ours, v_ref = sedimentation_metrics(t, x[:, 1], ref, scene.builder_kwargs["y0"])
    info = _info(scene, res, quick, eps_p_mean=float(np.mean(e)),
                 fluid_spacing_over_d=scene.params.sph.dp / scene.builder_kwargs["d"])
    out = [Record("sedimentation", "RMS(y - y_ref) / fall height", rms, 0.0, rms, 0.1,
                  rms < 0.1, wall, info)]
    if not quick:
        rel = abs(v_ours - v_ref) / v_ref
        out.append(Record("sedimentation", "settling velocity 0.2-0.6 s [m/s]", v_ours, v_ref,
                          rel, 0.1, rel < 0.1, wall, info))
    return out
