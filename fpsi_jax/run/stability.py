"""Stability probes: run a scene at a multiple of its derived time step and say
whether it stayed stable, and how it failed if not.

    from fpsi_jax import cases
    from fpsi_jax.run import stability
    rows = stability.sweep(cases.build("hydrostatic_tank", dx=0.01), t_end=0.5,
                           factors=(1, 2, 3, 4))
    stability.largest_stable(rows)           # e.g. 2.0: the derived step has a margin of 2

A probe is *stable* when the run ends without :class:`~fpsi_jax.model.errors.SimulationError`
(non-finite values, density out of band, a particle out of the domain) and every velocity
stays under ``v_limit`` (default 10 × the scene's velocity scale, which catches a run that
is blowing up but has not reached a NaN yet). Nothing here hides a failure: an unstable
probe records the driver's diagnosis (step, time, particle, quantity).

``factor`` multiplies the derived step of the whole scene; in a coupled scene (fluid and
discs, multi-rate) it multiplies the SPH step and the number of DEM sub-steps grows with it
(the sub-step stays at most its derived size), and ``dem_factor`` multiplies the DEM sub-step
instead (the SPH step is kept, the number of sub-steps divided).
"""
from __future__ import annotations

import dataclasses
import math
import time

import jax.numpy as jnp
import numpy as np

from ..model.config import Physics
from ..model.errors import SimulationError
from ..model.scene import Scene
from ..solver import timestep
from .driver import setup, simulate


@dataclasses.dataclass
class Probe:
    factor: float           # dt / derived dt (the DEM sub-step's, for dem_factor probes)
    dt: float               # the (SPH or single-phase) step used
    dem_substeps: int
    stable: bool
    reason: str             # '' when stable; else the driver's diagnosis or the v limit
    max_speed: float        # largest particle speed seen at the frames (m/s)
    steps: int
    wall_s: float

    def as_dict(self):
        return dataclasses.asdict(self)


def _max_speed(s):
    """Observer: the largest particle speed of the phases the state has."""
    return jnp.max(jnp.stack([jnp.max(jnp.linalg.norm(b.v, axis=1))
                              for b in (s.fluid, s.solid) if b is not None]))


def derived(scene: Scene, **opts):
    """(dt, dem_substeps) the driver derives for ``scene``."""
    phys, params = setup(scene, **opts)
    return float(params.dt), int(phys.dem_substeps)


def probe(scene: Scene, t_end: float, factor: float = 1.0, dem_factor: float | None = None,
          v_limit: float | None = None, **opts) -> Probe:
    """Run ``scene`` for ``t_end`` at ``factor`` × its derived step (or, coupled, with the
    DEM sub-step at ``dem_factor`` × its bound) and report (see module docstring)."""
    dt0, n0 = derived(scene, **opts)
    dt, kw = dt0, dict(opts)
    if dem_factor is not None:
        if n0 < 1 or not (scene.fluid is not None and scene.solid is not None):
            raise ValueError("dem_factor is for coupled (fluid + discs) scenes")
        bound = timestep.dem_dt(scene, scene.params, Physics.for_scene(scene, **opts))
        n = max(1, int(math.ceil(dt0 / (dem_factor * bound) - 1e-9)))
        kw["dem_substeps"] = n
        f = dt0 / n / bound
    else:
        dt = factor * dt0
        f = factor
        if scene.fluid is not None and scene.solid is not None:   # DEM sub-step kept
            kw["dem_substeps"] = max(1, int(math.ceil(n0 * factor - 1e-9)))
    v_scale = max(float(scene.v_max or 0.0), 1e-3)
    v_limit = 10.0 * v_scale if v_limit is None else v_limit
    t0 = time.perf_counter()
    try:
        res = simulate(scene, t_end, dt=dt, progress=False, unsafe_dt=True,
                       observe=_max_speed, every=t_end / 20, **kw)
    except SimulationError as e:
        return Probe(f, dt, kw.get("dem_substeps", 1), False, str(e),
                     float("nan"), int(e.step), time.perf_counter() - t0)
    vmax = float(np.max(np.asarray(res.observations)))
    ok = bool(np.isfinite(vmax) and vmax < v_limit)
    reason = "" if ok else f"speed {vmax:.3g} m/s above the limit {v_limit:.3g} m/s"
    return Probe(f, dt, res.physics.dem_substeps, ok, reason, vmax, res.n_steps,
                 time.perf_counter() - t0)


def sweep(scene: Scene, t_end: float, factors=(0.5, 1, 1.5, 2, 3, 4, 6, 8), dem=False,
          stop_after: int = 2, refine: int = 0, **opts) -> list[Probe]:
    """Probes at increasing factors; stops after ``stop_after`` unstable ones in a row.
    ``refine`` > 0 then bisects between the largest stable factor and the first unstable one
    that many times (so the blow-up threshold is known to a factor 2^-refine of that gap)."""
    def one(f):
        return probe(scene, t_end, dem_factor=f, **opts) if dem else probe(scene, t_end, f,
                                                                          **opts)
    rows, bad = [], 0
    for f in sorted(factors):
        p = one(f)
        rows.append(p)
        bad = 0 if p.stable else bad + 1
        if bad >= stop_after:
            break
    for _ in range(refine):
        lo = largest_stable(rows)
        hi = min((p.factor for p in rows if not p.stable and p.factor > lo), default=None)
        if hi is None or lo == 0:
            break
        rows.append(one(0.5 * (lo + hi)))
    return sorted(rows, key=lambda r: r.factor)


def largest_stable(rows: list[Probe]) -> float:
    """The largest factor below the first unstable one (0 if even the smallest failed)."""
    best = 0.0
    for p in sorted(rows, key=lambda r: r.factor):
        if not p.stable:
            break
        best = p.factor
    return best
