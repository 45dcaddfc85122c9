"""Neighbour lists, wrapped around jax-md's ``partition.neighbor_list``.

One list per interaction family (here: the SPH family, fluid + boundary particles) in the
Dense format (N × K), which measured faster than Sparse on CPU for SPH sums.

* Scenes live in a rectangle [origin, origin + box); positions are shifted into [0, box)
  because jax-md's cell list assumes that.
* A skin (jax-md ``dr_threshold``) makes rebuilds rare: the list is rebuilt only when
  the particles' displacements since the last build no longer fit in a circle of radius
  skin/2 (:func:`moved_past_half_skin`).
* jax-md's Dense format; the allocation (:func:`allocate`) and the rebuild inside the
  step (:func:`rebuild`) are ours, jitted, without recompiling for every fresh list. With
  jax-md's 3 × 3 cells (the DEM family) they give jax-md's lists row for row (tested); the
  SPH family's candidates come from five strips of cells of half the list radius,
  contiguous in the particles' cell order (``NeighborConfig.strips``, :func:`_strip_rows`):
  the same neighbours in each row, in another order, from 32–44 % fewer candidates.
* Rows that list only fluid neighbours (the walls', ``NeighborConfig.fluid_only_rows``) hold
  them in their first slots; the sums read those rows at a narrower width
  (``NeighborConfig.wall_width``, :func:`wall_rows`), which a rebuild checks like K.
* Inside a compiled chunk an overflow only sets a flag; :func:`overflowed` reads it on the
  host, which then reallocates with more room (:func:`grow`) and redoes the chunk. No pair
  is ever silently dropped.
"""
from __future__ import annotations

import dataclasses
import functools
import importlib
import importlib.util
import os
import sys
import types
import warnings

import jax
import jax.numpy as jnp
import numpy as np

from ..model.config import NeighborConfig
from ..physics.pairs import over_row_blocks, rows_of


class _Deferred:
    """A module imported on first attribute access (:func:`import_lean`), so that ``setup``
    can refuse bad input (and ``fpsi list`` answer) before any of jax-md is loaded."""

    def __init__(self, name):
        self._name, self._module = name, None

    def __getattr__(self, attr):
        if self._module is None:
            self._module = import_lean(self._name)
        return getattr(self._module, attr)


def import_lean(name: str):
    """Import the jax-md submodule ``name`` without running the package's ``__init__``.

    jax_md/__init__.py imports all of jax-md, and some of its modules run JAX at import
    (rigid_body computes shape moments, nn builds its models): 6–8 s and ~120 small
    compiled programs in every fresh process, of which only ``partition`` and ``space``
    (and what they import) are used here (0.06 s alone). While they load, a bare package
    module with jax-md's search path stands in for ``jax_md`` in ``sys.modules``; it is
    removed afterwards, so a later ``import jax_md`` (by the user) runs the real
    ``__init__``, which finds these submodules already loaded and uses the same module
    objects. If jax_md is already imported, this is a plain import."""
    if "jax_md" in sys.modules or name in sys.modules:
        return importlib.import_module(name)
    spec = importlib.util.find_spec("jax_md")
    stand_in = types.ModuleType("jax_md")
    stand_in.__path__ = list(spec.submodule_search_locations)
    stand_in.__spec__ = spec
    sys.modules["jax_md"] = stand_in
    try:
        return importlib.import_module(name)
    finally:
        if sys.modules.get("jax_md") is stand_in:
            del sys.modules["jax_md"]


partition = _Deferred("jax_md.partition")
space = _Deferred("jax_md.space")


def _key(cfg: NeighborConfig) -> NeighborConfig:
    """``cfg`` without :attr:`NeighborConfig.wall_width`, which only the step's sums and the
    overflow check read: the cell list, jax-md's functions and the allocation's programs
    are the same for every width."""
    return dataclasses.replace(cfg, wall_width=0) if cfg.wall_width else cfg


def _family(cfg: NeighborConfig):
    return _family_of(_key(cfg))


@functools.lru_cache(maxsize=64)
def _family_of(cfg: NeighborConfig):
    """(jax-md's allocate/update pair for ``cfg``, the cell list its lists use or None when
    the domain is too small for one, the box array both were given); cached, so the same
    cfg gives the same functions. The cell list is made from the same float32 box, cut-off
    and multiplier as the one jax-md's allocate makes, so it has the same grid."""
    displacement, _ = space.free()
    box = np.asarray(cfg.box, dtype=np.float64)
    cut = cfg.list_radius
    small = _small(cfg)
    if small:
        warnings.warn(
            f"domain {tuple(box)} is smaller than 3 x cut-off {cut:.4g} in some direction: "
            "jax-md falls back to an O(N^2) neighbour search", stacklevel=_caller_level())
    box_arr = jnp.asarray(box, jnp.float32)       # jax-md's neighbor_list casts it so
    fns = partition.neighbor_list(
        displacement, box_arr, cfg.r_cut, dr_threshold=cfg.skin,
        capacity_multiplier=cfg.capacity_multiplier, format=partition.Dense)
    cells = None if small else partition.cell_list(box_arr, cut, cfg.capacity_multiplier)
    return fns, cells, box_arr


def _caller_level() -> int:
    """``stacklevel`` for a warning raised by the function that calls this one, naming the
    first frame outside fpsi_jax (the user's line that started the run), however deep in
    the package the warning is raised."""
    package = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    frame, level = sys._getframe(2), 2
    while frame is not None and os.path.abspath(frame.f_code.co_filename).startswith(package):
        frame, level = frame.f_back, level + 1
    return level


def _small(cfg: NeighborConfig) -> bool:
    """jax-md's condition for no cell list: the domain under 3 cut-offs in a direction."""
    return bool(np.any(np.asarray(cfg.box, np.float64) < 3.0 * cfg.list_radius))


def neighbor_fns(cfg: NeighborConfig) -> partition.NeighborListFns:
    """The jax-md allocate/update pair for ``cfg`` (cached: same cfg → same functions, so a
    reallocated list does not trigger a recompile unless its capacity changed)."""
    return _family(cfg)[0]


def shift(cfg: NeighborConfig, x):
    """Scene coordinates → the list's [0, box) frame."""
    return x - jnp.asarray(cfg.origin, dtype=x.dtype)


def allocate(cfg: NeighborConfig, x) -> partition.NeighborList:
    """Build a list for positions ``x`` (host side, not jittable): jax-md's Dense list with
    jax-md's capacities (tested equal to ``neighbor_fns(cfg).allocate``).

    jax-md's allocate runs eagerly, so each new particle count compiled its ~60 primitives
    one by one (1.4 s for a dam break); here the cell occupancy and the rows are computed by
    two jitted programs. jax-md also makes a new cell-list closure each call and the list
    carries it as static pytree data, so every fresh list looked new to ``jax.jit`` and each
    ``simulate`` call traced and compiled its programs again; every list of ``cfg`` now
    carries the one cached cell list. A domain under 3 cut-offs keeps jax-md's allocate."""
    fns, cells, _ = _family(cfg)
    xs = shift(cfg, x)
    if cells is None:
        return fns.allocate(xs, extra_capacity=cfg.extra_capacity)
    n = xs.shape[0]
    # jax-md's cell capacity: the fullest cell (or strip) × multiplier, + extra
    fullest = _fullest_strip(_key(cfg), xs) if cfg.strips else _fullest_cell(_key(cfg), xs)
    cell_cap = max(int(int(fullest) * (cfg.cell_multiplier or cfg.capacity_multiplier))
                   + cfg.extra_capacity, cfg.min_cell_capacity)
    idx, occupancy, wall, cell_over = _allocation_rows(_key(cfg), cells, xs, cell_cap)
    occupancy, wall = int(occupancy), int(wall)
    k = min(max(int(occupancy * cfg.capacity_multiplier + cfg.extra_capacity),
                cfg.min_neighbors), idx.shape[1], n - 1)
    err = partition.PartitionError(jnp.zeros((), jnp.uint8))
    err = err.update(partition.PartitionErrorCode.CELL_LIST_OVERFLOW, cell_over)
    err = err.update(partition.PartitionErrorCode.NEIGHBOR_LIST_OVERFLOW,
                     jnp.asarray(occupancy > k or _wall_over(cfg, wall)))
    return partition.NeighborList(idx[:, :k], xs, err, cell_cap, k, partition.Dense,
                                  cfg.list_radius, cells, fns.update)


def _wall_count(cfg: NeighborConfig, idx, n: int) -> int:
    """The most listed neighbours of a ``fluid_only_rows`` row of ``idx`` (host side)."""
    if not cfg.fluid_only_rows:
        return 0
    first, stop, _ = cfg.fluid_only_rows
    return int(np.max(np.sum(np.asarray(idx[first:stop]) < n, axis=1), initial=0))


def _wall_over(cfg: NeighborConfig, wall):
    """Whether a wall row has more neighbours than the sums read (:attr:`wall_width`)."""
    return (wall > cfg.wall_width) if cfg.wall_width and not _small(cfg) else False


def wall_width(cfg: NeighborConfig, x) -> int:
    """The width the sums over ``cfg.fluid_only_rows`` should read for positions ``x``
    (scene frame): the most fluid neighbours (within the list radius) of such a row × the
    capacity multiplier, and at least half the room a fluid row gets (its most neighbours
    × the multiplier, as the allocation sizes K). A wall particle sees fluid on one side
    of its wall, and the first lattice is more even than a flow, which crowds the fluid
    against the walls and the structure: the widest wall row grew from 12 to 19 fluid
    neighbours in the elastic gate and from 14 to 31 in the two-phase dam break, and a
    width from the first positions alone was regrown in every such run (a recompile and a
    redone chunk). 0 for a config without such rows or without a cell list (jax-md's O(N²)
    list puts wall neighbours in those rows too). Host side, numpy, nothing compiled
    (run.driver.setup calls it on the scene's first positions)."""
    if not cfg.fluid_only_rows or _small(cfg):
        return 0
    first, stop, n_f = cfg.fluid_only_rows
    x = np.asarray(x, np.float64)
    r, mult, extra = cfg.list_radius, cfg.capacity_multiplier, cfg.extra_capacity
    wall = int(np.max(_count_within(x[:n_f], x[first:stop], r), initial=0))
    listed = x[:cfg.n_columns or None]
    row = int(np.max(_count_within(listed, x[:n_f], r), initial=1)) - 1     # not itself
    half_row = int(row * mult + extra) // 2                 # half of K as allocate sizes it
    return max(int(np.ceil(wall * mult)) + extra, half_row, 1)


def room_for_broken_discs(cfg: NeighborConfig) -> NeighborConfig:
    """The DEM list ``cfg`` with the room a structure's broken discs need when they pile up,
    as a regrowth would give it (:data:`CHEAP_REGROWTH` × the need): rows for the six
    touching neighbours of a close-packed heap, cells for the most disc centres a cell
    holds at spacing 2R, (⌊side/2R⌋ + 1)², R the largest radius (r_cut = 2R × reach). A
    bonded square lattice lists four neighbours and four centres a cell, and a breaking
    wall's list regrew to 9 and 6 (a recompile in the middle of the run)."""
    two_r = cfg.r_cut                     # ≥ 2R: the contact reach of the largest discs
    per_cell = (int(np.floor(cfg.list_radius / two_r)) + 1) ** 2
    return dataclasses.replace(
        cfg, min_neighbors=max(cfg.min_neighbors, int(np.ceil(6 * CHEAP_REGROWTH))),
        min_cell_capacity=max(cfg.min_cell_capacity, int(np.ceil(per_cell * CHEAP_REGROWTH))))


def _count_within(xc, xq, r):
    """(q,) how many points of ``xc`` lie within ``r`` of each point of ``xq`` (host side,
    numpy): ``xc`` is binned in cells of side r and each query counts its 3 × 3 cells."""
    lo = np.minimum(np.min(xc, axis=0, initial=np.inf), np.min(xq, axis=0, initial=np.inf))
    cell_c = np.floor((xc - lo) / r).astype(np.int64)
    cell_q = np.floor((xq - lo) / r).astype(np.int64)
    side = int(max(cell_c[:, 0].max(initial=0), cell_q[:, 0].max(initial=0))) + 3
    key_c = (cell_c[:, 1] + 1) * side + cell_c[:, 0] + 1
    order = np.argsort(key_c, kind="stable")
    keys, xs = key_c[order], xc[order]
    count = np.zeros(len(xq), np.int64)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            k = (cell_q[:, 1] + 1 + dy) * side + cell_q[:, 0] + 1 + dx
            a, b = np.searchsorted(keys, k), np.searchsorted(keys, k, side="right")
            width = int(np.max(b - a, initial=0))
            if width == 0:
                continue
            j = np.minimum(a[:, None] + np.arange(width)[None, :], max(len(xc) - 1, 0))
            d2 = np.sum((xs[j] - xq[:, None, :]) ** 2, axis=-1)
            count += np.sum((d2 < r * r) & (np.arange(width)[None, :] < (b - a)[:, None]),
                            axis=1)
    return count


def wall_rows(cfg: NeighborConfig, idx, first: int, n: int):
    """Rows ``first`` … ``first`` + n − 1 of the list ``idx``, all of which lie in
    ``cfg.fluid_only_rows``, at the width the sums read (:attr:`NeighborConfig.wall_width`;
    the slots past it are padding while the list has not overflowed). All K slots when the
    domain has no cell list (jax-md's O(N²) list also holds the walls there)."""
    return idx[first:first + n, :(None if _small(cfg) else cfg.wall_width or None)]


@functools.partial(jax.jit, static_argnums=0)
def _fullest_cell(cfg: NeighborConfig, xs):
    """The particle count of the fullest cell, counted as jax-md's allocation estimates it
    (partition._estimate_cell_capacity: on the grid of its actual cell size, which rounding
    can make one cell per side coarser than the list's own grid); only the particles the
    cells hold (below ``cfg.n_columns``: :func:`cell_list`)."""
    box = np.array(_family(cfg)[2]).reshape(1, -1)           # as partition.cell_list does
    _, cell_size, _, _ = partition._cell_dimensions(xs.shape[1], box, cfg.list_radius)
    return jnp.max(partition.count_cell_filling(xs[:cfg.n_columns or None], box, cell_size))


@functools.partial(jax.jit, static_argnums=0)
def _fullest_strip(cfg: NeighborConfig, xs):
    """The particle count of the fullest strip of the strip search (:func:`_strip_bounds`)."""
    _, lo, hi = _strip_bounds(cfg, xs)
    return jnp.max(hi - lo)


@functools.partial(jax.jit, static_argnums=(0, 1, 3))
def _allocation_rows(cfg, cells, xs, cell_capacity):
    """Every neighbour of every particle (the full 3^d·C candidate width), their largest
    count, that of a ``fluid_only_rows`` row and the cell-list overflow flag. ``cells``: jax-md's cell list of ``cfg``, whose
    own update is used when every particle is listed (ours equals it, tested)."""
    if cfg.strips:
        width = cell_capacity * (2 * STRIP_REACH + 1)
        idx, occupancy, wall, fullest = _strip_rows(cfg, xs, cell_capacity, width)
        return idx, occupancy, wall, fullest > cell_capacity
    cl = (cell_list(cfg, xs, cell_capacity) if 0 < cfg.n_columns < xs.shape[0]
          else cells.update(xs, cell_capacity))
    dim = xs.shape[1]
    width = cl.id_buffer.shape[dim] * 3 ** dim          # id_buffer: (cells…, C, 1)
    idx, occupancy, wall = _dense_rows(cl, xs, cfg.list_radius, width,
                                       n_columns=cfg.n_columns, fluid_only=cfg.fluid_only_rows)
    return idx, occupancy, wall, cl.did_buffer_overflow


def moved_past_half_skin(skin, d, about_centre=True):
    """Whether a list built ``skin`` wider than the cut-off may have lost a pair, given
    every particle's displacement ``d`` (N, dim) since the build.

    A pair (i, j) left out at the build was farther apart than r_cut + skin, so it is
    still beyond r_cut while |d_i − d_j| ≤ skin. For any point c,
    |d_i − d_j| ≤ |d_i − c| + |d_j − c|, so the list holds while every displacement lies
    within skin/2 of one common c. jax-md takes c = 0 (no particle moved more than
    skin/2); the list is also kept while the displacements lie within skin/2 of the
    centre of their bounding box. When the particles move together (a column falling,
    a jet leaving a tank whose walls stand still) they then move up to twice as far
    between rebuilds. The list is the same set of pairs either way; only when it is
    rebuilt changes. ``about_centre=False``: jax-md's test alone (one fused reduction
    fewer, for the DEM sub-steps, where a few hundred discs make every operation's fixed
    cost count and grains move no common drift)."""
    half = (0.5 * skin) ** 2
    past = jnp.any(jnp.sum(d ** 2, axis=-1) > half)
    if not about_centre:
        return past
    c = 0.5 * (jnp.min(d, axis=0) + jnp.max(d, axis=0))
    return past & jnp.any(jnp.sum((d - c) ** 2, axis=-1) > half)


def update(cfg: NeighborConfig, nbrs: partition.NeighborList, x, about_centre=True):
    """Update inside a compiled step; returns (list, rebuilt?, need). As jax-md's
    ``nbrs.update``, but rebuilt (:func:`rebuild`) only once the particles' displacements
    since the last build no longer fit in a circle of radius skin/2
    (:func:`moved_past_half_skin`; jax-md: once one has moved more than skin/2, which
    ``about_centre=False`` keeps).
    ``need`` (int32, shape (3,)) is what the rebuild found,
    before anything was cut to capacity: the most neighbours of a particle, the most
    particles in a cell and the most neighbours of a ``fluid_only_rows`` row (zeros when
    nothing was rebuilt, or without a cell list); an overflowed list is regrown to fit it
    (:func:`grow`)."""
    xs = shift(cfg, x)
    zero = jnp.zeros((3,), jnp.int32)
    if nbrs.cell_list_fn is None:        # domain < 3 cut-offs: jax-md's O(N²) search
        new = nbrs.update(xs)
        return new, jnp.any(new.reference_position != nbrs.reference_position), zero
    rebuilt = moved_past_half_skin(cfg.skin, xs - nbrs.reference_position, about_centre)
    new, need = jax.lax.cond(rebuilt, lambda: _rebuild(cfg, nbrs, xs),
                             lambda: (nbrs, zero))
    return new, rebuilt, need


def rebuild_if(cfg: NeighborConfig, nbrs: partition.NeighborList, x, now):
    """:func:`update` with the rebuild decided by the caller: rebuilt at ``x`` (scene
    frame) where the traced bool ``now`` holds. Returns (list, rebuilt?, need)."""
    xs = shift(cfg, x)
    zero = jnp.zeros((3,), jnp.int32)
    if nbrs.cell_list_fn is None:        # domain < 3 cut-offs: jax-md's O(N²) search
        new = jax.lax.cond(now, lambda: nbrs.update(xs), lambda: nbrs)
        return new, jnp.any(new.reference_position != nbrs.reference_position), zero
    new, need = jax.lax.cond(now, lambda: _rebuild(cfg, nbrs, xs), lambda: (nbrs, zero))
    return new, now, need


def rebuild(cfg: NeighborConfig, nbrs: partition.NeighborList, xs):
    """The Dense list of jax-md from positions ``xs`` already in the list's frame, with
    one distance pass instead of two: with jax-md's cells the same rows in the same order;
    with ``cfg.strips`` the same rows from the strip search (:func:`_strip_rows`).

    jax-md's cell list gives each particle the 3×3 cells' 9·C candidates; jax-md then
    masks them by distance, *gathers the positions again* to recompute the same distances,
    and compacts the (N, 9C) rows with a scatter of the same width. Here the first mask is
    kept and the valid candidates are scattered straight into the K slots (slot K, cut
    off, takes the rest); more than K valid neighbours set the overflow flag as jax-md
    does, and the running count is :func:`_running_count`. 6.9k-particle dam break, as a
    jitted call of its own: 7.4–7.8 ms against jax-md's 29–35 ms (docs/performance.md)."""
    return _rebuild(cfg, nbrs, xs)[0]


def _rebuild(cfg: NeighborConfig, nbrs: partition.NeighborList, xs):
    """:func:`rebuild` and what it needed: (the most neighbours of a particle, the most
    particles in a cell, the most neighbours of a ``fluid_only_rows`` row), int32."""
    cap = nbrs.cell_list_capacity
    if cfg.strips:
        idx, occupancy, wall, fullest = _strip_rows(cfg, xs, cap, nbrs.idx.shape[1],
                                                    cfg.row_block)
        cell_over = fullest > cap
    else:
        cl, fullest = _cell_list(cfg, xs, cap)
        idx, occupancy, wall = _dense_rows(cl, xs, cfg.list_radius, nbrs.idx.shape[1],
                                           cfg.row_block, cfg.n_columns, cfg.fluid_only_rows)
        cell_over = cl.did_buffer_overflow
    err = nbrs.error.update(partition.PartitionErrorCode.CELL_LIST_OVERFLOW, cell_over)
    err = err.update(partition.PartitionErrorCode.NEIGHBOR_LIST_OVERFLOW,
                     (occupancy > nbrs.idx.shape[1]) | _wall_over(cfg, wall))
    need = jnp.stack([occupancy.astype(jnp.int32), fullest.astype(jnp.int32),
                      wall.astype(jnp.int32)])
    return nbrs.set(idx=idx, reference_position=xs, error=err), need


_PACKED_LIMIT = 2 ** 31      # packed keys hash·N + i must fit an int32


def cell_list(cfg: NeighborConfig, xs, cell_capacity: int) -> partition.CellList:
    """jax-md's cell list (``partition.cell_list(...).update``: the same grid, buffers and
    overflow flag, slot for slot) for positions ``xs`` in the list's frame.

    jax-md orders the particles by cell with a stable ``argsort`` of the cell hashes, a
    two-operand sort; when hash·N + i fits in an int32 the same permutation comes from one
    sort of those packed keys, which XLA:CPU sorts 5× faster (8 048 particles: 0.26 against
    1.4 ms, 1.25 of a 7 ms rebuild of the elastic gate's list).

    With ``cfg.n_columns`` (particles past it are nobody's neighbour) only the particles
    below it are put in the cells; the others keep their cell id, which their own rows
    read. In a packed grain bed this nearly halves the fullest cell (two-phase dam break:
    19 instead of 28 particles), so the cells need less room and a rebuild gathers fewer
    candidates."""
    return _cell_list(cfg, xs, cell_capacity)[0]


def _grid(cfg: NeighborConfig, dim: int):
    """(cell size, cells per side, cell count) of the list's grid, as jax-md sizes it."""
    box = np.asarray(cfg.box, np.float64).astype(np.float32).reshape(1, -1)  # as _family
    _, cell_size, per_side, count = partition._cell_dimensions(dim, box, cfg.list_radius)
    return cell_size, per_side, count


def cell_hash(cfg: NeighborConfig, xs):
    """(cells (N, dim), hash (N,)) of positions ``xs`` in the list's frame: the cell each
    lies in and its index in the table, rows of cells along x (jax-md's hash)."""
    cell_size, per_side, _ = _grid(cfg, xs.shape[1])
    hash_mult = partition._compute_hash_constants(xs.shape[1], per_side)
    cells = jnp.mod(jnp.array(xs / cell_size, dtype=jnp.int32), per_side)
    return cells, jnp.sum(cells * hash_mult, axis=1)


def _cell_list(cfg: NeighborConfig, xs, cell_capacity: int):
    """:func:`cell_list` and the particle count of its fullest cell."""
    n, dim = xs.shape
    cell_size, per_side, count = _grid(cfg, dim)
    cells, hashes = cell_hash(cfg, xs)
    ids = jnp.arange(n, dtype=jnp.int32)
    if 0 < cfg.n_columns < n:        # the rest sort last, into a cell past the table
        hashes = jnp.where(ids < cfg.n_columns, hashes, count)
    if (int(count) + 1) * n < _PACKED_LIMIT:
        order = jnp.mod(jax.lax.sort(hashes * n + ids), n)
    else:
        order = jnp.argsort(hashes)
    slot = hashes[order] * cell_capacity + jnp.mod(ids, cell_capacity)
    slot = jnp.where(hashes[order] < count, slot, count * cell_capacity)   # dropped
    occupancy = jnp.zeros(count, jnp.int32).at[hashes].add(1, mode="drop")
    extra = {}
    if _packs_ids(n, xs.dtype):
        # positions and ids in one (cells·C, dim + 1) table, filled by one scatter and read
        # by one gather per candidate cell (:func:`_dense_rows`)
        empty = jnp.concatenate([jnp.zeros((count * cell_capacity, dim), xs.dtype),
                                 jnp.full((count * cell_capacity, 1), n, xs.dtype)], axis=1)
        table = empty.at[slot].set(jnp.concatenate(
            [xs[order], order[:, None].astype(xs.dtype)], axis=1), mode="drop")
        pos, cid = table[:, :dim], table[:, dim:].astype(jnp.int32)
        extra = {PACKED: partition.unflatten_cell_buffer(table, per_side, dim)}
    else:
        pos = jnp.zeros((count * cell_capacity, dim), xs.dtype).at[slot].set(
            xs[order], mode="drop")
        cid = jnp.full((count * cell_capacity, 1), n, jnp.int32).at[slot].set(
            order[:, None], mode="drop")
    return partition.CellList(
        partition.unflatten_cell_buffer(pos, per_side, dim),
        partition.unflatten_cell_buffer(cid, per_side, dim), cells, extra,
        jnp.max(occupancy) > cell_capacity, cell_capacity, cell_size, None), jnp.max(occupancy)


#: the cell list's extra buffer holding [position, id] per slot (:func:`cell_list`)
PACKED = "fpsi_packed"


def _packs_ids(n: int, dtype) -> bool:
    """Whether particle ids 0 … n are exact in ``dtype`` (float32: n < 2²⁴)."""
    return n < 2 ** (24 if jnp.dtype(dtype) == jnp.float32 else 53)


def _dense_rows(cl, xs, cut, k, block_rows=0, n_columns=0, fluid_only=()):
    """The first ``k`` neighbours (in jax-md's candidate order) of every particle from the
    cell list ``cl``, padding = N, the largest number of neighbours of a particle and that
    of a ``fluid_only`` row (0: none);
    computed in row blocks of ``block_rows`` rows (0: all at once), so that the (rows, 9C)
    candidate arrays of a block stay in cache (pairs.over_row_blocks). Only candidates
    below ``n_columns`` are listed (0: all; NeighborConfig.n_columns), and rows in
    ``fluid_only`` = (first, stop, n_fluid) list only candidates below n_fluid
    (NeighborConfig.fluid_only_rows)."""
    n, dim = xs.shape
    n_cols = n_columns or n
    cap = cl.id_buffer.shape[dim]
    buf_shape = cl.id_buffer.shape[:dim]
    per_side = jnp.array(buf_shape[::-1], jnp.int32)
    shifts = jnp.asarray(_NEIGHBOUR_CELLS[dim])
    mult = jnp.array([int(np.prod(buf_shape[dim - i:])) for i in range(dim)], jnp.int32)
    ids, pos = cl.id_buffer.reshape((-1, cap)), cl.position_buffer.reshape((-1, cap, dim))
    table = (cl.named_buffer or {}).get(PACKED)
    table = None if table is None else table.reshape((-1, cap, dim + 1))

    def block(row0, rows):
        x, cell = rows_of(xs, row0, rows), rows_of(cl.particle_cell_id, row0, rows)
        cells = jnp.mod(cell[:, None, :] + shifts[None], per_side[None, None])
        flat = jnp.sum(cells * mult, axis=2).reshape(-1)
        if table is None:
            cand = ids[flat].reshape(rows, -1)
            cpos = pos[flat].reshape(rows, -1, dim)
        else:           # one gather of [x, y, id] (ours; jax-md's cell list has none)
            got = table[flat]
            cand = got[..., dim].astype(jnp.int32).reshape(rows, -1)
            cpos = got[..., :dim].reshape(rows, -1, dim)
        r2 = jnp.sum((x[:, None, :] - cpos) ** 2, axis=-1)
        me = row0 + jnp.arange(rows, dtype=jnp.int32)
        valid = (r2 < cut * cut) & (cand < n_cols) & (cand != me[:, None])
        valid, wall_row = _fluid_only(valid, cand, me, fluid_only)
        idx, count = _compact(valid, cand, cells.shape[1], cap, k, n)
        return idx, count, jnp.where(wall_row, count, 0)

    idx, counts, walls = over_row_blocks(block, n, block_rows)
    return idx, jnp.max(counts), jnp.max(walls)


def _fluid_only(valid, cand, me, fluid_only):
    """The candidate mask with the rows ``me`` that lie in ``fluid_only`` = (first, stop,
    n_fluid) keeping only candidates below n_fluid (NeighborConfig.fluid_only_rows), and
    which rows those are ((): none)."""
    if not fluid_only:
        return valid, jnp.zeros(me.shape, bool)
    first, stop, n_f = fluid_only
    wall_row = (me >= first) & (me < stop)
    return valid & (~wall_row[:, None] | (cand < n_f)), wall_row


def _compact(valid, cand, n_groups, cap, k, pad):
    """(rows, k) the valid candidates of each row in its first slots, in candidate order
    (padding ``pad``), and (rows,) how many each row has, from the (rows, n_groups·cap)
    candidate mask ``valid`` and ids ``cand``. Each valid candidate goes to slot
    (running count − 1); the rest, and any past ``k``, to slot k, which is cut off."""
    rows = valid.shape[0]
    count = _running_count(valid, n_groups, cap)
    slot = jnp.where(valid & (count <= k), count - 1, k)
    # one flat index per candidate (row·(K+1) + slot): a scatter with (row, slot) index
    # pairs first writes an (N·9C, 2) index array (gate list: 2.7 against 2.1 ms)
    at = (jnp.arange(rows, dtype=jnp.int32)[:, None] * (k + 1) + slot).reshape(-1)
    idx = jnp.full((rows * (k + 1),), pad, jnp.int32).at[at].set(cand.reshape(-1))
    return idx.reshape(rows, k + 1)[:, :k], count[:, -1]


#: the strip search's cells per list radius (:func:`_strip_rows`): cells of side r/2, so a
#: row's candidates lie in 2·STRIP_REACH + 1 strips of as many cells
STRIP_REACH = 2


def _strip_grid(cfg: NeighborConfig):
    """(cell side, cells along x, cells along y) of the strip search's grid over the box."""
    side = cfg.list_radius / STRIP_REACH
    nx, ny = (max(int(np.ceil(float(b) / side)), 1) for b in cfg.box)
    return side, nx, ny


def _strip_bounds(cfg: NeighborConfig, xs):
    """The particles in cell order and each particle's strips: (order (N,), lo, hi
    (N, 2·STRIP_REACH + 1)), where sorted positions lo … hi − 1 are the listed particles
    in the cells (cx − 2 … cx + 2, cy + s) of particle i's cell (cx, cy), s = −2 … 2.

    Cells are rows along x, so the five cells of a strip follow one another in the sorted
    order and a strip is one contiguous range (DualSPHysics reads its cells this way:
    Domínguez et al. 2011, Int. J. Numer. Meth. Fluids 67:2026). Particles past
    ``cfg.n_columns`` sort into a cell past the grid and lie in no strip."""
    n = xs.shape[0]
    side, nx, ny = _strip_grid(cfg)
    count = nx * ny
    cell = jnp.floor(xs[:, :2] / side).astype(jnp.int32)
    cx, cy = jnp.clip(cell[:, 0], 0, nx - 1), jnp.clip(cell[:, 1], 0, ny - 1)
    ids = jnp.arange(n, dtype=jnp.int32)
    key = cy * nx + cx
    if 0 < cfg.n_columns < n:
        key = jnp.where(ids < cfg.n_columns, key, count)
    if (count + 1) * n < _PACKED_LIMIT:
        order = jnp.mod(jax.lax.sort(key * n + ids), n)
    else:
        order = jnp.argsort(key)
    start = jnp.concatenate([jnp.zeros((1,), jnp.int32),
                             jnp.cumsum(jnp.zeros((count + 1,), jnp.int32).at[key].add(1))])
    m = STRIP_REACH
    row = cy[:, None] + jnp.arange(-m, m + 1, dtype=jnp.int32)[None]
    first = jnp.clip(row, 0, ny - 1) * nx
    lo = start[first + jnp.maximum(cx - m, 0)[:, None]]
    hi = start[first + jnp.minimum(cx + m, nx - 1)[:, None] + 1]
    return order, lo, jnp.where((row >= 0) & (row < ny), hi, lo)


def _strip_rows(cfg: NeighborConfig, xs, cap: int, k: int, block_rows=0):
    """The first ``k`` neighbours of every particle within the list radius, found in
    five strips of ``cap`` candidates each (:func:`_strip_bounds`); returns (idx (N, k),
    the most neighbours of a particle, the most of a ``fluid_only_rows`` row, the most
    particles in a strip). A strip holding more than ``cap`` particles loses the rest
    (the caller flags it as a cell overflow).

    Cells of half the list radius put the candidates within a 2.5 r × 2.5 r square, not
    the 3 r × 3 r of 3 × 3 cells of side r, and a strip's capacity is set by the fullest
    strip, not nine times the fullest cell: 0.05 s into each flow the dam break's rows
    read 100 candidates instead of 180 at 24k particles, the elastic gate's 135 instead
    of 198, the two-phase dam break's 280 instead of 414 (docs/performance.md, *Where a
    step's time goes*). The sorted [x, y, id] table is read
    as windows of ``cap`` rows (window i = sorted rows i … i + cap − 1), so a strip is one
    gathered row of windows, as a cell of the cell table is; the windows hold N·cap rows
    (83 MB at 344k particles and cap 20, written once a rebuild)."""
    n = xs.shape[0]
    dim = xs.shape[1]
    order, lo, hi = _strip_bounds(cfg, xs)
    n_strips = lo.shape[1]
    far = jnp.asarray(np.finfo(np.dtype(xs.dtype)).max / 4, xs.dtype)
    packs = _packs_ids(n, xs.dtype)
    cols = [xs[order]] + ([order[:, None].astype(xs.dtype)] if packs else [])
    table = jnp.concatenate(cols, axis=1)
    pad = jnp.full((cap, table.shape[1]), far, xs.dtype)
    if packs:
        pad = pad.at[:, dim].set(n)
    table = jnp.concatenate([table, pad])
    windows = jnp.stack([table[q:q + n] for q in range(cap)], axis=1)     # (N, cap, ·)
    if not packs:
        ids = jnp.concatenate([order, jnp.full((cap,), n, jnp.int32)])
        id_windows = jnp.stack([ids[q:q + n] for q in range(cap)], axis=1)
    cut2 = cfg.list_radius ** 2
    t = jnp.arange(cap, dtype=jnp.int32)

    def block(row0, rows):
        x, l, u = (rows_of(a, row0, rows) for a in (xs, lo, hi))
        at = jnp.minimum(l, n - 1).reshape(-1)
        got = windows[at].reshape(rows, n_strips * cap, -1)
        cand = (got[..., dim].astype(jnp.int32) if packs
                else id_windows[at].reshape(rows, n_strips * cap))
        inside = ((l[:, :, None] + t) < u[:, :, None]).reshape(rows, -1)
        r2 = sum((x[:, None, a] - got[..., a]) ** 2 for a in range(dim))
        me = row0 + jnp.arange(rows, dtype=jnp.int32)
        valid = inside & (r2 < cut2) & (cand != me[:, None])
        valid, wall_row = _fluid_only(valid, cand, me, cfg.fluid_only_rows)
        idx, count = _compact(valid, cand, n_strips, cap, k, n)
        return idx, count, jnp.where(wall_row, count, 0)

    idx, counts, walls = over_row_blocks(block, n, block_rows)
    return idx, jnp.max(counts), jnp.max(walls), jnp.max(hi - lo)


def _running_count(valid, n_cells, cap):
    """cumsum(valid, axis=1) of the (N, n_cells·cap) candidate mask, as int32, computed per
    cell block: a (cap × cap) upper-triangular matmul gives the counts within each cell,
    a (n_cells × n_cells) one the counts of the cells before it. Exact (float32 holds
    integers to 2²⁴; a row has at most n_cells·cap candidates) and 2–2.5× faster on
    XLA:CPU than ``jnp.cumsum``, which lowers to a multi-pass associative scan (6.9k
    particles × 180 candidates: 1.3–1.5 against 2.6–3.7 ms)."""
    n = valid.shape[0]
    blk = valid.reshape(n, n_cells, cap).astype(jnp.float32)
    exact = jax.lax.Precision.HIGHEST      # no TF32/bf16 passes on accelerators
    within = jnp.matmul(blk, jnp.triu(jnp.ones((cap, cap), jnp.float32)), precision=exact)
    before = jnp.matmul(within[:, :, -1], jnp.triu(jnp.ones((n_cells, n_cells), jnp.float32), 1),
                        precision=exact)
    return (within + before[:, :, None]).reshape(n, -1).astype(jnp.int32)


# jax-md's neighbouring-cell offsets, in its order (partition._neighboring_cells_arr)
_NEIGHBOUR_CELLS = {d: np.stack(np.meshgrid(*[np.arange(-1, 2)] * d, indexing="ij"),
                                axis=-1).reshape(-1, d).astype(np.int32) for d in (2, 3)}


def overflowed(nbrs: partition.NeighborList) -> bool:
    return bool(nbrs.did_buffer_overflow)


def capacity(nbrs: partition.NeighborList) -> int:
    return int(nbrs.idx.shape[1])


#: what a regrowth gives the DEM list (with ``both``) over the need found, and
#: :data:`WALL_REGROWTH` the wall rows' width: each regrowth is a recompile of the step
#: (5–20 s for a coupled scene) and a redone chunk, while a slot more costs those rows ~1 %
#: of a step. A breaking bonded wall hit by a dam break regrew five times in 0.5 s (69 s of
#: its 84 s stepping): the wall rows' width 15 → 20 → 28 as its discs came to lie in the
#: water, the DEM list's rows and cells 0.05 s apart (docs/performance.md, Regrowth). The
#: width is measured on the first positions with room to spare, so a row past it is a
#: structure coming apart, whose discs end up with fluid all round: it doubles.
CHEAP_REGROWTH = 1.5
WALL_REGROWTH = 2.0


def grow(cfg: NeighborConfig, nbrs: partition.NeighborList, need=(0, 0, 0),
         both: bool = False) -> NeighborConfig:
    """A config with room for what overflowed ``nbrs``.

    ``need`` is (the most neighbours of a particle, the most particles in a cell, the most
    neighbours of a ``fluid_only_rows`` row) that the run's rebuilds have found so far
    (:func:`update`, ``Status.sph_need``; zeros: unknown). What overflowed, the rows, the
    cells or the width the sums read of the wall rows (:attr:`NeighborConfig.wall_width`),
    gets room for its need times the capacity multiplier (the cells: times
    :attr:`NeighborConfig.cell_multiplier` where set; and at least one slot more than it
    had), as a fresh allocation gives, and nothing else grows: a cell's capacity sets
    the width of the rebuild's candidate pass (9 cells or 5 strips × the capacity;
    with ``cfg.strips`` the need and the capacity are a strip's), the rows' that of
    every pair pass. The wall rows' width gets :data:`WALL_REGROWTH` times its need.
    ``both`` (the DEM list of a few hundred discs, whose sums cost next to nothing per
    slot): rows and cells both grow, by :data:`CHEAP_REGROWTH` times their need, whichever
    overflowed. Without a need, or for a
    list without a cell list (jax-md's O(N²) search, whose allocation knows only
    ``extra_capacity``), every cell and row gets ~50 % more room."""
    need = tuple(int(v) for v in need) + (0,) * (3 - len(need))
    rows_need, cells_need, wall_need = need[:3]
    # an allocation that found a wide wall row flags it without a rebuild's need: its rows
    # hold every neighbour up to K, so count them
    wall_need = max(wall_need, _wall_count(cfg, nbrs.idx, nbrs.idx.shape[0]))
    code = int(nbrs.error.code)
    mult = CHEAP_REGROWTH if both else cfg.capacity_multiplier
    wall_over = bool(cfg.wall_width) and wall_need > cfg.wall_width
    rows_over = bool(code & int(partition.PartitionErrorCode.NEIGHBOR_LIST_OVERFLOW)) and (
        rows_need > capacity(nbrs) or not wall_over)
    cells_over = bool(code & int(partition.PartitionErrorCode.CELL_LIST_OVERFLOW))
    if both and (rows_over or cells_over):
        rows_over = cells_over = True
    if wall_over:
        cfg = dataclasses.replace(cfg, wall_width=max(cfg.wall_width + 1,
                                                      int(np.ceil(wall_need * WALL_REGROWTH))))
        if not (rows_over or cells_over):
            return cfg                # only the wall rows' width ran out
    if rows_need <= 0 or cells_need <= 0 or nbrs.cell_list_fn is None:
        extra = cfg.extra_capacity + max(8, capacity(nbrs) // 2)
        return dataclasses.replace(cfg, extra_capacity=int(extra))
    if rows_over:
        rows = max(capacity(nbrs) + (1 if rows_need > capacity(nbrs) or not both else 0),
                   int(np.ceil(rows_need * mult)), cfg.min_neighbors)
        cfg = dataclasses.replace(cfg, min_neighbors=rows)
    if cells_over:
        cells = max(int(nbrs.cell_list_capacity) + (1 if cells_need > nbrs.cell_list_capacity
                                                    or not both else 0),
                    int(np.ceil(cells_need * (cfg.cell_multiplier or mult))),
                    cfg.min_cell_capacity)
        cfg = dataclasses.replace(cfg, min_cell_capacity=cells)
    return cfg
