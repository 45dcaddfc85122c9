"""Open sides: particles that leave the domain through one are taken out of the computation.

As DualSPHysics does with its excluded particles, a particle (fluid or disc) whose position
crosses an open side of the domain (``Scene.open_sides``), or with an open top goes over
the walls (beside the boundary particles, above the highest of them), is *parked*: it
keeps its slot in every array (the compiled shapes never change) but is moved to its own
spot on the parking lattice above the domain (:class:`~fpsi_jax.model.config.Parking`),
farther than any list radius from everything, so it drops out of every neighbour list and
pair sum; its velocity and accelerations are zeroed and kept so. A fluid particle takes
the next free spot in the order the particles leave (not its storage slot: the fluid may
be re-stored in cell order, :mod:`fpsi_jax.solver.order`), a disc its own. ``t_out``
records when it left (−1: still in); its mass is the scene's, so the mass that left is
Σ m over ``t_out ≥ 0``. A disc that leaves becomes kinematic (``fixed``) and its intact
bonds break with mode 3. Crossing a closed side stays an error (solver.health). Scenes
without an open side trace none of this.
"""
from __future__ import annotations

import jax
import jax.numpy as jnp

from ..model.config import Parking, Physics
from ..model.options import Side


def crossed_open_side(phys: Physics, x):
    """(n,) bool: the position lies beyond one of the domain's open sides, or, with an open
    top, beside the walls above their top (``Physics.rim``: it went over them)."""
    lo = jnp.asarray(phys.domain_lo, x.dtype)
    hi = jnp.asarray(phys.domain_hi, x.dtype)
    beyond = {Side.LEFT: x[:, 0] < lo[0], Side.RIGHT: x[:, 0] >= hi[0],
              Side.BOTTOM: x[:, 1] < lo[1], Side.TOP: x[:, 1] >= hi[1]}
    out = jnp.zeros(x.shape[0], bool)
    for side in phys.open_sides:
        out = out | beyond[side]
    if phys.rim is not None:
        x_lo, x_hi, y_top = phys.rim
        out = out | (((x[:, 0] < x_lo) | (x[:, 0] > x_hi)) & (x[:, 1] > y_top))
    return out


def park_positions(parking: Parking, first_slot: int, n: int, dtype):
    """(n, 2) parking spots of slots first_slot … first_slot + n − 1."""
    return spots(parking, jnp.arange(n) + first_slot, dtype)


def spots(parking: Parking, k, dtype):
    """(len(k), 2) parking spots of the slots ``k``."""
    s = parking.spacing
    col = (k % parking.columns).astype(dtype)
    row = (k // parking.columns).astype(dtype)
    return jnp.stack([parking.x0 + (col + 0.5) * s, parking.y0 + (row + 0.5) * s], axis=1)


def leave(phys: Physics, x, t_out, t):
    """(t_out updated, parked mask): particles in the computation that crossed an open
    side at time ``t`` get t_out = t."""
    new = (t_out < 0) & crossed_open_side(phys, x)
    t_out = jnp.where(new, t, t_out)
    return t_out, t_out >= 0


def park_fluid(phys: Physics, fluid, t):
    """The fluid with the particles that crossed an open side parked: the k-th particle to
    leave takes slot k − 1 (slots 0 … n − 1) and stays there (its velocity and
    acceleration zeroed every step, so the drift never moves it)."""
    t_out, out = leave(phys, fluid.x, fluid.t_out, t)

    def park(fluid):
        new = out & (fluid.t_out < 0)
        slot = jnp.sum(fluid.t_out >= 0) + jnp.cumsum(new) - 1
        spot = spots(phys.parking, slot, fluid.x.dtype)
        o2 = out[:, None]
        return fluid.replace(x=jnp.where(new[:, None], spot, fluid.x),
                             v=jnp.where(o2, 0.0, fluid.v), acc=jnp.where(o2, 0.0, fluid.acc),
                             xsph=jnp.where(o2, 0.0, fluid.xsph), t_out=t_out)
    # while no particle is out (most steps of most scenes) nothing is moved or zeroed
    return jax.lax.cond(jnp.any(out), park, lambda f: f, fluid)


def park_discs(phys: Physics, solid, bonds, t):
    """Discs that crossed an open side parked (slots n_fluid …), made kinematic at rest,
    and their intact bonds broken (mode 3)."""
    t_out, out = leave(phys, solid.x, solid.t_out, t)
    spot = park_positions(phys.parking, phys.n_fluid, solid.x.shape[0], solid.x.dtype)
    o2 = out[:, None]
    solid = solid.moved_to(jnp.where(o2, spot, solid.x))
    solid = solid.replace(v=jnp.where(o2, 0.0, solid.v),
                          acc=jnp.where(o2, 0.0, solid.acc), omega=jnp.where(out, 0.0, solid.omega),
                          alpha=jnp.where(out, 0.0, solid.alpha), fixed=solid.fixed | out,
                          t_out=t_out)
    if bonds is not None:
        cut = bonds.intact & (out[bonds.i] | out[bonds.j])
        bonds = bonds.replace(intact=bonds.intact & ~cut,
                              t_break=jnp.where(cut, t, bonds.t_break),
                              mode=jnp.where(cut, 3, bonds.mode))
    return solid, bonds

