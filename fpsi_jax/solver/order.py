"""The order the fluid particles are stored in: re-stored in cell order for a chunk of steps.

The SPH pair passes gather each neighbour's fields by index. While particles that are
close in space are close in memory these gathers read few cache lines; a flow that mixes
its particles (a jet breaking up, a long sloshing run) scatters them, and once the particle
arrays outgrow the CPU's cache every gather goes to memory: the dam break with its fluid
stored in a random order ran 43 % slower a step at 90k particles and 55 % at 344k than in
the builders' row-by-row order (docs/performance.md, *Particle order*). DualSPHysics and
the GPU SPH codes sort their particles by cell for the same reason.

:func:`sorted_chunk` runs a chunk of steps on the state re-stored by cell
(:func:`cell_order`) and stores the result back in the caller's order, so everything
outside the chunk (output frames, probes, a user's particle indices, checkpoints) sees the
particles where the scene put them. Re-storing is a relabelling: the SPH list keeps the
same pairs in the same slots (:func:`relabel`), so a chunk run sorted sums the same pairs
in the same order until its first list rebuild (equal to the last bit or two, where XLA
vectorises a row differently) and equal to float round-off after it. Only the fluid moves in memory; boundary, structure and grain rows keep their places
(the boundary never moves, and the builders lay it out in lattice order).
"""
from __future__ import annotations

import jax
import jax.numpy as jnp

from ..model.config import Physics
from ..model.state import State, Status
from . import neighbors


def cell_order(phys: Physics, state: State):
    """(n_fluid,) int32: the fluid's storage order sorted by the SPH list's cell (rows of
    cells along x, the cell table's order), ties in the current order."""
    xs = neighbors.shift(phys.neighbors, state.fluid.x)
    _, key = neighbors.cell_hash(phys.neighbors, xs)
    return jnp.argsort(key, stable=True).astype(jnp.int32)


def inverse(perm):
    """The inverse permutation: inverse(perm)[perm[k]] = k."""
    return jnp.zeros_like(perm).at[perm].set(jnp.arange(perm.shape[0], dtype=perm.dtype))


def _take(a, perm):
    return None if a is None else a[perm]


def relabel_fluid(state: State, perm) -> State:
    """``state`` with its fluid arrays (and the grains' per-fluid voidage) re-stored so
    that slot k holds what slot perm[k] held. The neighbour lists are left as they were:
    a view for reading the fluid (observers), not a state to step."""
    fpi = state.fpi
    if fpi is not None:
        fpi = fpi.replace(eps=_take(fpi.eps, perm))
    return state.replace(fluid=jax.tree_util.tree_map(lambda a: a[perm], state.fluid),
                         fpi=fpi)


def relabel(phys: Physics, state: State, perm, inv) -> State:
    """``state`` re-stored with slot k of the fluid holding what slot perm[k] held
    (``inv`` = inverse(perm)), its SPH list relabelled to match: the fluid rows move with
    their particles and every listed fluid index i becomes inv[i], so each row lists the
    same particles in the same slots."""
    state = relabel_fluid(state, perm)
    nb = state.nbrs
    n_f = perm.shape[0]
    rows = jnp.concatenate([perm, jnp.arange(n_f, nb.idx.shape[0], dtype=perm.dtype)])
    idx = nb.idx[rows]
    idx = jnp.where(idx < n_f, inv[jnp.minimum(idx, n_f - 1)], idx)
    ref = nb.reference_position[rows]
    return state.replace(nbrs=nb.set(idx=idx, reference_position=ref))


def particle_back(status: Status, bad_before, perm) -> Status:
    """The status with a fluid particle that went bad during the sorted chunk named by its
    slot in the caller's order (codes 1–5 name a fluid slot)."""
    fluid = (status.code >= 1) & (status.code <= 5)
    now = status.bad & ~bad_before & fluid & (status.particle >= 0)
    named = perm[jnp.clip(status.particle, 0, perm.shape[0] - 1)]
    return status.replace(particle=jnp.where(now, named, status.particle))


def sorted_chunk(phys: Physics, state: State, run, observe=None):
    """``run(state', observe')`` on ``state`` re-stored in cell order, its end state stored
    back in ``state``'s order. ``observe'`` is ``observe`` reading the fluid in the
    caller's order (a gather of the fields it reads, each step). Returns what ``run``
    returns, its first element stored back. Without ``phys.sort_fluid`` it is ``run``."""
    if not phys.sort_fluid:
        return run(state, observe)
    perm = cell_order(phys, state)
    inv = inverse(perm)
    view = None if observe is None else (lambda s: observe(relabel_fluid(s, inv)))
    end, *rest = run(relabel(phys, state, perm, inv), view)
    # relabelling with inv stores back: slot k gets what slot inv[k] holds, i.e. particle k
    end = relabel(phys, end, inv, perm)
    end = end.replace(status=particle_back(end.status, state.status.bad, perm))
    return (end, *rest)
