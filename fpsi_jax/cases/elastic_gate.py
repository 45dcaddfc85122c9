"""Fluid–structure validation cases: the plate under still water (K6.3.3) and the Antoci
elastic gate (K6.3, W6.1), registered with ``fpsi validate``; plus the gate's tip metrics
and plot used by ``make run`` and ``experiments/elastic_gate.py``."""
from __future__ import annotations

import time

import jax.numpy as jnp
import numpy as np

from ..run.simulate import simulate
from . import overrides as ov
from .fsi_cases import GATE_COARSE, gate_tip, plate_deflection, plate_midpoint, plate_reference
from .registry import Record, load_csv, register

GATE_EXPERIMENT = "antoci2007_gate_tip_displacement_experiment_consensus.csv"
GATE_OTHERS = {   # label: (ux file, uy file); Yang 2012 is left out (its digitisations conflict)
    "Antoci et al. 2007 SPH": "antoci2007_sph",
    "Khayyer et al. 2018 ISPH-SPH": "khayyer2018_isph_sph",
    "Ng et al. 2020 SPH-VCPM": "ng2020_sph_vcpm",
}
RMS_WINDOW = (0.0, 0.36)


# --- plate -------------------------------------------------------------------------------
def midpoint_observer(scene):
    mid = jnp.asarray(plate_midpoint(scene.solid.x))
    return lambda s: jnp.mean(s.solid.x[mid, 1])


def plate_run(scene, settle_fraction=0.25, **kw):
    """Run the plate; returns (deflection series w(t) [m], times, mean deflection over the
    last ``settle_fraction`` of the run, result)."""
    mid = plate_midpoint(scene.solid.x)
    y0 = float(scene.solid.x[mid, 1].mean())
    res = simulate(scene, progress=False, observe=midpoint_observer(scene), **kw)
    w = -(np.asarray(res.observations, float) - y0)
    t = (np.arange(w.size) + 1) * float(res.params.dt)
    late = w[int((1 - settle_fraction) * w.size):]
    return w, t, float(late.mean()), res


@register("hydrostatic_plate", "plate clamped at both ends under still water: midpoint "
          "deflection vs K44 (+ shear)")
def hydrostatic_plate(quick: bool = False, overrides: dict | None = None):
    # reference: K44 + the Timoshenko shear deflection of the strip's shear modulus (the
    # rubber's G by default); the K44-only error is in the record's params
    base = {}
    if quick:
        base.update(dx=0.0035, d=0.0025, dx_boundary=0.0025, t_end=0.8)
    scene, phys = ov.build("hydrostatic_plate", overrides or {}, base)
    t0 = time.perf_counter()
    w, _, w_late, res = plate_run(scene, **phys)
    wall = time.perf_counter() - t0
    kw = scene.builder_kwargs
    ref = plate_reference(kw)
    k44 = plate_deflection(kw["span_built"], kw["thickness_built"], kw["water_height_built"],
                           kw["E"], kw["nu"], kw["rho_water"], kw["rho_plate"])
    info = {**kw, "quick": quick, "n_particles": scene.n_particles, "steps": res.n_steps,
            "dem_substeps": res.physics.dem_substeps, "K44_thin_plate_m": k44,
            "rel_error_vs_K44": w_late / k44 - 1.0,
            "note": "mean over the last quarter of the run; reference = K44 + q L^2/(8 kappa "
                    "G shear_factor e)"}
    tol = 0.05 if quick else 0.02
    err = w_late / ref - 1.0
    return [Record("hydrostatic_plate", "midpoint deflection [m]", w_late, ref, err, tol,
                   abs(err) <= tol, wall, info)]


# --- elastic gate ------------------------------------------------------------------------
def tip_observer(scene):
    tip = jnp.asarray(gate_tip(scene))
    return lambda s: jnp.mean(s.solid.x[tip], axis=0)


def tip_displacement(scene, res):
    """(t, ux, uy) of the gate's free end from a run observed with :func:`tip_observer`."""
    tip = gate_tip(scene)
    x0 = scene.solid.x[tip].mean(axis=0)
    u = np.asarray(res.observations, float) - x0
    t = (np.arange(u.shape[0]) + 1) * float(res.params.dt)
    return t, u[:, 0], u[:, 1]


def gate_metrics(t, ux, uy):
    """Peak ux and its time, RMS of ux and uy against the experiment over 0–0.36 s (at the
    experiment's frames), each also relative to the experiment's peak."""
    ref = load_csv(GATE_EXPERIMENT)
    tr, uxr, uyr = ref[:, 0], ref[:, 1], ref[:, 3]
    k = int(np.argmax(ux))
    inside = (tr >= RMS_WINDOW[0]) & (tr <= min(RMS_WINDOW[1], t[-1]) + 1e-9)
    sx = np.interp(tr[inside], t, ux, left=0.0)
    sy = np.interp(tr[inside], t, uy, left=0.0)
    rms_x = float(np.sqrt(np.mean((sx - uxr[inside]) ** 2)))
    rms_y = float(np.sqrt(np.mean((sy - uyr[inside]) ** 2)))
    kr = int(np.argmax(uxr))
    return {"peak_ux_m": float(ux[k]), "t_peak_s": float(t[k]),
            "exp_peak_ux_m": float(uxr[kr]), "exp_t_peak_s": float(tr[kr]),
            "peak_ux_rel_error": float(ux[k] / uxr[kr] - 1.0),
            "t_peak_error_s": float(t[k] - tr[kr]),
            "rms_ux_m": rms_x, "rms_uy_m": rms_y,
            "rms_ux_rel_peak": rms_x / float(uxr.max()),
            "rms_uy_rel_peak": rms_y / float(uyr.max()),
            "frames": int(inside.sum())}


def plot_gate(curves, out_png, title="Elastic gate (Antoci et al. 2007)"):
    """Tip ux and uy: each (label, t, ux, uy) in ``curves`` against the experiment, with the
    other codes' curves for context."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ref = load_csv(GATE_EXPERIMENT)
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    for ax, comp, col in ((axes[0], "ux", 1), (axes[1], "uy", 3)):
        for label, stem in GATE_OTHERS.items():
            d = load_csv(f"antoci2007_gate_tip_{comp}_numerical_{stem}.csv")
            ax.plot(d[:, 0], d[:, 1] * 1e3, lw=0.9, alpha=0.6, ls="--", label=label)
        for label, t, ux, uy in curves:
            ax.plot(t, (ux if comp == "ux" else uy) * 1e3, lw=1.8, label=label)
        ax.errorbar(ref[:, 0], ref[:, col] * 1e3, yerr=ref[:, col + 1] * 1e3, fmt="ko",
                    ms=5, capsize=2, label="experiment (consensus of 2 digitisations)")
        ax.set_xlabel("t [s]")
        ax.set_ylabel(f"tip {comp} [mm]")
        ax.set_xlim(0, 0.4)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=7, loc="lower right")
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(out_png, dpi=120)
    plt.close(fig)


@register("elastic_gate", "Antoci elastic gate: tip peak ux and its time vs experiment, "
          "RMS of ux, uy")
def elastic_gate(quick: bool = False, overrides: dict | None = None):
    base = dict(GATE_COARSE) if quick else {}
    scene, phys = ov.build("elastic_gate", overrides or {}, base)
    t0 = time.perf_counter()
    res = simulate(scene, progress=False, observe=tip_observer(scene), **phys)
    wall = time.perf_counter() - t0
    m = gate_metrics(*tip_displacement(scene, res))
    info = {**scene.builder_kwargs, **m, "quick": quick, "n_particles": scene.n_particles,
            "steps": res.n_steps, "dem_substeps": res.physics.dem_substeps}
    info.pop("tip", None)
    return [
        Record("elastic_gate", "peak tip ux [m]", m["peak_ux_m"], m["exp_peak_ux_m"],
               m["peak_ux_rel_error"], 0.15, abs(m["peak_ux_rel_error"]) <= 0.15, wall, info),
        Record("elastic_gate", "time of peak ux [s]", m["t_peak_s"], m["exp_t_peak_s"],
               m["t_peak_error_s"] / m["exp_t_peak_s"], 0.03 / m["exp_t_peak_s"],
               abs(m["t_peak_error_s"]) <= 0.03, wall, info),
    ]
