"""Health checks inside the compiled step: per-particle status codes
(:data:`fpsi_jax.model.state.STATUS_CODES`), the first bad particle remembered in
:class:`~fpsi_jax.model.state.Status` for the host's error message."""
from __future__ import annotations

import jax.numpy as jnp

from ..model.config import Physics
from ..model.params import Params
from ..model.state import FluidState, SolidState, Status
from ..physics import dem


def _box(phys: Physics, dtype_):
    """The domain rectangle (lo, hi) every particle in the computation stays inside."""
    if phys.domain_lo is not None:
        return jnp.asarray(phys.domain_lo, dtype_), jnp.asarray(phys.domain_hi, dtype_)
    nb = phys.neighbors or phys.dem_neighbors
    lo = jnp.asarray(nb.origin, dtype_)
    return lo, lo + jnp.asarray(nb.box, dtype_)


def _in_computation(code, t_out):
    """Codes of parked particles (t_out ≥ 0: they left through an open side) set to 0."""
    return code if t_out is None else jnp.where(t_out >= 0, 0, code)


def _first(status: Status, code, step) -> Status:
    bad_now = jnp.any(code > 0)
    i = jnp.argmax(code > 0).astype(jnp.int32)
    first = bad_now & ~status.bad
    return status.replace(
        bad=status.bad | bad_now,
        step=jnp.where(first, step, status.step),
        particle=jnp.where(first, i, status.particle),
        code=jnp.where(first, code[i].astype(jnp.int32), status.code))


def check_fluid(phys: Physics, params: Params, fluid: FluidState, step, status: Status) -> Status:
    """Per-particle health codes of the fluid (see state.STATUS_CODES); remember the first."""
    lo, hi = _box(phys, fluid.x.dtype)
    rho0 = params.sph.rho0
    code = jnp.where(~jnp.all(jnp.isfinite(fluid.x), axis=1), 1,
           jnp.where(~jnp.all(jnp.isfinite(fluid.v), axis=1), 2,
           jnp.where(~jnp.isfinite(fluid.rho), 3,
           jnp.where(jnp.abs(fluid.rho / rho0 - 1.0) > phys.rho_tolerance, 4,
           jnp.where(jnp.any((fluid.x < lo) | (fluid.x >= hi), axis=1), 5, 0)))))
    return _first(status, _in_computation(code, fluid.t_out), step)


def check_solid(phys: Physics, solid: SolidState, step, status: Status) -> Status:
    """Health codes 6–8 of the discs (the particle index is the disc's)."""
    lo, hi = _box(phys, solid.x.dtype)
    code = jnp.where(~jnp.all(jnp.isfinite(solid.x), axis=1), 6,
           jnp.where(~(jnp.all(jnp.isfinite(solid.v), axis=1) & jnp.isfinite(solid.omega)), 7,
           jnp.where(jnp.any((solid.x < lo) | (solid.x >= hi), axis=1), 8, 0)))
    return _first(status, _in_computation(code, solid.t_out), step)


def _orient(a, b, c):
    """Sign of the turn a → b → c (> 0 counter-clockwise), broadcast over leading axes."""
    return ((b[..., 0] - a[..., 0]) * (c[..., 1] - a[..., 1])
            - (b[..., 1] - a[..., 1]) * (c[..., 0] - a[..., 0]))


def crossed_walls(x0, x1, a, b, shift=None):
    """(n,) bool: the path x0 → x1 of each disc crosses one of the wall segments a → b
    (proper crossing: the end points lie strictly on opposite sides of the wall's line and
    the wall's end points strictly on opposite sides of the path). ``shift`` (n, W, 2)
    moves each disc's path per wall (to test against a wall moved by −shift)."""
    p0, p1 = x0[:, None, :], x1[:, None, :]
    if shift is not None:
        p0, p1 = p0 + shift, p1 + shift
    wa, wb = a[None], b[None]
    side0, side1 = _orient(wa, wb, p0), _orient(wa, wb, p1)
    ends_a, ends_b = _orient(p0, p1, wa), _orient(p0, p1, wb)
    return jnp.any((side0 * side1 < 0) & (ends_a * ends_b < 0), axis=1)


def check_wall_crossings(solid: SolidState, x0, walls, step, status: Status) -> Status:
    """Health code 9: a free disc whose path over the step, from ``x0`` to its position
    now, went through a DEM wall: across a two-sided wall's line, or deeper than 2R past
    a one-sided wall's line (where that wall stops pushing it back; dem.wall_pair_geometry)."""
    shift = None
    if walls.side is not None:
        n_in = dem.inward_normals(walls.a, walls.b, walls.side)
        shift = 2.0 * solid.radius[:, None, None] * n_in[None]
    crossed = crossed_walls(x0, solid.x, walls.a, walls.b, shift)
    code = jnp.where(crossed & ~solid.fixed, 9, 0)
    return _first(status, _in_computation(code, solid.t_out), step)
