"""Neighbour lists, wrapped around jax-md's ``partition.neighbor_list``.

One list per interaction family (here: the SPH family, fluid + boundary particles) in the
Dense format (N × K), which measured faster than Sparse on CPU for SPH sums.

* Scenes live in a rectangle [origin, origin + box); positions are shifted into [0, box)
  because jax-md's cell list assumes that.
* A skin (jax-md ``dr_threshold``) makes rebuilds rare: the list is rebuilt only when a
  particle has moved more than skin/2 since the last build.
* Inside a compiled chunk an overflow only sets a flag; :func:`overflowed` reads it on the
  host, which then reallocates with more room (:func:`grow`) and redoes the chunk. No pair
  is ever silently dropped.
"""
from __future__ import annotations

import dataclasses
import functools
import warnings

import jax.numpy as jnp
import numpy as np
from jax_md import partition, space

from .scene import NeighborConfig


@functools.lru_cache(maxsize=64)
def neighbor_fns(cfg: NeighborConfig) -> partition.NeighborListFns:
    """The jax-md allocate/update pair for ``cfg`` (cached: same cfg → same functions, so a
    reallocated list does not trigger a recompile unless its capacity changed)."""
    displacement, _ = space.free()
    box = np.asarray(cfg.box, dtype=np.float64)
    if np.any(box < 3.0 * (cfg.r_cut + cfg.skin)):
        warnings.warn(
            f"domain {tuple(box)} is smaller than 3 x cut-off {cfg.r_cut + cfg.skin:.4g} in "
            "some direction: jax-md falls back to an O(N^2) neighbour search", stacklevel=2)
    return partition.neighbor_list(
        displacement, jnp.asarray(box), cfg.r_cut, dr_threshold=cfg.skin,
        capacity_multiplier=cfg.capacity_multiplier, format=partition.Dense)


def shift(cfg: NeighborConfig, x):
    """Scene coordinates → the list's [0, box) frame."""
    return x - jnp.asarray(cfg.origin, dtype=x.dtype)


def allocate(cfg: NeighborConfig, x) -> partition.NeighborList:
    """Build a list for positions ``x`` (host side, not jittable)."""
    return neighbor_fns(cfg).allocate(shift(cfg, x), extra_capacity=cfg.extra_capacity)


def update(cfg: NeighborConfig, nbrs: partition.NeighborList, x):
    """Update inside a compiled step; returns (list, rebuilt?)."""
    new = nbrs.update(shift(cfg, x))
    rebuilt = jnp.any(new.reference_position != nbrs.reference_position)
    return new, rebuilt


def overflowed(nbrs: partition.NeighborList) -> bool:
    return bool(nbrs.did_buffer_overflow)


def capacity(nbrs: partition.NeighborList) -> int:
    return int(nbrs.idx.shape[1])


def grow(cfg: NeighborConfig, nbrs: partition.NeighborList) -> NeighborConfig:
    """A config with ~50 % more room per row (and per cell) than ``nbrs`` had."""
    extra = cfg.extra_capacity + max(8, capacity(nbrs) // 2)
    return dataclasses.replace(cfg, extra_capacity=int(extra))
