"""Observers: functions ``state -> small array`` that ``simulate(observe=...)`` records
every step (inside the compiled chunk, so they must be JAX-traceable).

``phase`` names a particle set of the state: ``"solid"`` (the DEM discs) or ``"fluid"``.
An index set ``idx`` is an array of indices or a boolean mask over that phase.
"""
from __future__ import annotations

import jax.numpy as jnp
import numpy as np


def indices(idx) -> np.ndarray:
    """``idx`` as integer indices (a boolean mask becomes the indices of its True entries)."""
    idx = np.asarray(idx)
    return np.flatnonzero(idx) if idx.dtype == bool else idx.astype(int)


def mean_of(x, idx, axis: int | None = None):
    """Mean position (numpy) of the points ``idx`` of ``x`` (n, 2): (2,), or the
    component ``axis`` alone. The start value of :func:`mean_position`."""
    sel = np.asarray(x)[indices(idx)]
    return sel.mean(axis=0) if axis is None else sel[:, axis].mean()


def mean_position(idx, axis: int | None = None, phase: str = "solid"):
    """observe(state) = mean position of the particles ``idx`` of ``phase``: (2,), or the
    component ``axis`` alone."""
    # a numpy int32 constant, not a jax array: one made while a float64 run had x64 on is
    # int64, and a float32 run tracing it later warned that int64 is not available
    ii = indices(idx).astype(np.int32)
    if axis is None:
        return lambda s: jnp.mean(getattr(s, phase).x[ii], axis=0)
    return lambda s: jnp.mean(getattr(s, phase).x[ii, axis])


def mean_displacement(x0, idx, axis: int | None = None, phase: str = "solid"):
    """observe(state) = mean displacement of the particles ``idx`` of ``phase`` from their
    mean in the start positions ``x0`` (n, 2): (2,), or the component ``axis`` alone."""
    start = mean_of(x0, idx, axis)
    pos = mean_position(idx, axis, phase)
    return lambda s: pos(s) - jnp.asarray(start, getattr(s, phase).x.dtype)


def in_computation(block):
    """(n,) bool: the particles of a state block that have not left through an open side."""
    t_out = getattr(block, "t_out", None)
    return jnp.ones(block.x.shape[0], bool) if t_out is None else t_out < 0


def max_coordinate(axis: int = 0, phase: str = "fluid"):
    """observe(state) = the largest coordinate ``axis`` over the particles of ``phase`` in
    the computation (a surge front)."""
    def fn(s):
        b = getattr(s, phase)
        return jnp.max(jnp.where(in_computation(b), b.x[:, axis], -jnp.inf))
    return fn


def max_speed(s):
    """observe(state) = the largest particle speed of the phases the state has."""
    return jnp.max(jnp.stack([jnp.max(jnp.linalg.norm(b.v, axis=1))
                              for b in (s.fluid, s.solid) if b is not None]))


def energy_and_speed(gravity):
    """observe(state) = (E, max |v|) over the particles in the computation (fluid and
    discs): E = Σ ½ m |v|² + Σ ½ I ω² − Σ m g·x, the mechanical energy per unit thickness
    (J/m; the bonds' elastic energy and the fluid's compression energy are not included),
    and the largest particle speed."""
    g = jnp.asarray(gravity)

    def fn(s):
        e, vmax = 0.0, 0.0
        for b in (s.fluid, s.solid):
            if b is None:
                continue
            on = in_computation(b)
            m = jnp.where(on, b.mass, 0.0)
            v2 = jnp.sum(b.v * b.v, axis=1)
            e = e + jnp.sum(0.5 * m * v2) - jnp.sum(m * (b.x @ g.astype(b.x.dtype)))
            if hasattr(b, "omega"):
                e = e + jnp.sum(jnp.where(on, 0.5 * b.inertia * b.omega ** 2, 0.0))
            vmax = jnp.maximum(vmax, jnp.sqrt(jnp.max(jnp.where(on, v2, 0.0))))
        return jnp.stack([e, vmax])

    return fn
