"""``fpsi validate``: the registered validation cases, each with its reference and tolerance.

A case is a function ``(quick, overrides) -> list[Record]``. Analytic references are
computed from the (possibly overridden) parameters, so ``--set`` checks a user's variant.
``quick`` is the coarse version the test suite runs; its resolution and tolerance are part
of the record (``params``), never hidden.
"""
from __future__ import annotations

import time

import jax.numpy as jnp
import numpy as np

from ..physics import eos
from ..run.simulate import simulate
from . import overrides as ov
from .registry import CASES, DESCRIPTIONS, Record, load_csv, register


# --- hydrostatic tank --------------------------------------------------------------------
@register("hydrostatic_tank", "still water: pressure vs ρ0 g (H − y), residual velocity")
def hydrostatic_tank(quick: bool = False, overrides: dict | None = None):
    base = {"dx": 0.01} if quick else {}
    scene, phys = ov.build("hydrostatic_tank", overrides or {}, base)
    t0 = time.perf_counter()
    res = simulate(scene, progress=False, **phys)
    wall = time.perf_counter() - t0
    kw = scene.builder_kwargs
    H, dx = kw["depth"], kw["dx"]
    sp = res.params.sph
    g = float(-np.asarray(res.params.gravity)[1])
    f = res.state.fluid
    y = np.asarray(f.x[:, 1])
    p = np.asarray(eos.pressure(f.rho, sp.rho0, sp.c0, sp.gamma))
    below = y < H - 3 * dx
    p_ref = float(sp.rho0) * g * (H - y[below])
    err_p = float(np.abs(p[below] - p_ref).sum() / p_ref.sum())
    vmax = float(np.max(np.linalg.norm(np.asarray(f.v), axis=1)))
    scale = float(np.sqrt(g * H))
    info = {**kw, "quick": quick, "n_particles": scene.n_particles, "steps": res.n_steps}
    return [
        Record("hydrostatic_tank", "pressure L1 error below top 3 layers",
               float(np.abs(p[below]).sum() / below.sum()), float(p_ref.mean()), err_p, 0.02,
               err_p < 0.02, wall, info),
        Record("hydrostatic_tank", "max |v| / sqrt(gH) at t_end", vmax / scale, 0.0,
               vmax / scale, 0.01, vmax / scale < 0.01, wall, info),
    ]


# --- dam break ---------------------------------------------------------------------------
def front_observer(state):
    """Front position: the rightmost fluid particle centre (half a spacing is added later)."""
    return jnp.max(state.fluid.x[:, 0])


def dam_break_front(scene, res):
    """(T, Z) of the run: Z = (x_front + dx/2)/a, T = t √(2g/a) (K&O nondimensionalisation)."""
    kw = scene.builder_kwargs
    a, dx = kw["column_width"], kw["dx"]
    g = float(-np.asarray(res.params.gravity)[1])
    t = np.arange(1, len(res.observations) + 1) * float(res.params.dt)
    return t * np.sqrt(2 * g / a), (np.asarray(res.observations) + 0.5 * dx) / a


@register("dam_break", "front position Z(T) vs Koshizuka & Oka (1996), T <= 2.5")
def dam_break(quick: bool = False, overrides: dict | None = None):
    base = {"dx": 0.01} if quick else {}
    scene, phys = ov.build("dam_break", overrides or {}, base)
    kw = scene.builder_kwargs
    a = kw["column_width"]
    g = float(-np.asarray(scene.params.gravity)[1])
    t_end = 2.5 / np.sqrt(2 * g / a) * 1.02
    t0 = time.perf_counter()
    res = simulate(scene, t_end=t_end, progress=False, observe=front_observer,
                   every=t_end / 20, **phys)
    wall = time.perf_counter() - t0
    T, Z = dam_break_front(scene, res)
    ref = load_csv("koshizuka_oka1996_surge_front.csv")
    ref = ref[(ref[:, 0] <= 2.5) & (ref[:, 0] > 0)]
    z = np.interp(ref[:, 0], T, Z)
    rel = np.abs(z - ref[:, 1]) / ref[:, 1]
    k = int(np.argmax(rel))
    info = {**kw, "quick": quick, "n_particles": scene.n_particles, "steps": res.n_steps,
            "T_worst": float(ref[k, 0])}
    return [Record("dam_break", "front Z at worst T <= 2.5", float(z[k]), float(ref[k, 1]),
                   float(rel[k]), 0.05, bool(rel.max() < 0.05), wall, info)]


from . import validate_fpi, validate_fsi, validate_solids  # noqa: E402,F401  (register their cases)


def run(names=None, quick=False, overrides=None) -> list[Record]:
    names = list(CASES) if not names else names
    out = []
    for n in names:
        if n not in CASES:
            from .params import ParameterError
            raise ParameterError(f"unknown validation case {n!r}; available: "
                                 f"{', '.join(CASES)}")
    for n in names:
        out += CASES[n](quick=quick, overrides=dict(overrides or {}))
    return out


def format_table(records) -> str:
    head = ("case", "quantity", "value", "reference", "rel_error", "tol", "pass", "wall_s")
    rows = [head] + [(r.case, r.quantity, f"{r.value:.5g}", f"{r.reference:.5g}",
                      f"{r.rel_error:.3%}", f"{r.tolerance:.2%}",
                      "PASS" if r.passed else "FAIL", f"{r.wall_s:.1f}") for r in records]
    widths = [max(len(str(r[i])) for r in rows) for i in range(len(head))]
    return "\n".join("  ".join(str(c).ljust(w) for c, w in zip(r, widths)) for r in rows)
