"""Neighbour lists (fpsi_jax.solver.neighbors): the list rebuild and allocation equal
jax-md's own, growing adds room, the rebuild happens past half the skin, and jax-md is
imported only when a list is built, without the rest of jax-md. The driver's redo of an overflowed chunk is tested in
tests/run/test_simulate.py."""
import subprocess
import sys

import numpy as np
import pytest

from fpsi_jax import cases
from fpsi_jax.model.config import Physics
from fpsi_jax.physics.pairs import MIN_BLOCKS
from fpsi_jax.solver import neighbors


def test_grow_adds_room():
    sc = cases.build("hydrostatic_tank", dx=0.02, depth=0.1, width=0.1)
    import jax.numpy as jnp
    phys = Physics.for_scene(sc)
    x = jnp.concatenate([jnp.asarray(sc.fluid.x), jnp.asarray(sc.boundary.x)])
    nb = neighbors.allocate(phys.neighbors, x)
    bigger = neighbors.allocate(neighbors.grow(phys.neighbors, nb), x)
    assert neighbors.capacity(bigger) > neighbors.capacity(nb)
    assert not neighbors.overflowed(nb)


def test_cells_take_their_own_multiplier_and_grain_scenes_double_them():
    """NeighborConfig.cell_multiplier sizes the cells (the fullest × it), the rows keep
    capacity_multiplier; a scene with grains in the fluid gets 2 (pore fluid packs), a
    fluid-only scene 0 (the rows' multiplier)."""
    import dataclasses

    import jax.numpy as jnp
    cfg, xs, nbrs = _dam_break_list(every_column=False)
    fullest = int(neighbors._fullest_cell(cfg, xs))
    assert cfg.cell_multiplier == 0.0
    assert nbrs.cell_list_capacity == int(fullest * cfg.capacity_multiplier)
    x = jnp.asarray(xs) + jnp.asarray(cfg.origin, jnp.float32)
    wide = neighbors.allocate(dataclasses.replace(cfg, cell_multiplier=2.0), x)
    assert wide.cell_list_capacity == 2 * fullest
    assert neighbors.capacity(wide) == neighbors.capacity(nbrs)
    np.testing.assert_array_equal(np.sort(np.asarray(wide.idx), axis=1),
                                  np.sort(np.asarray(nbrs.idx), axis=1))
    grains = Physics.for_scene(cases.build("grain_bed")).neighbors
    assert grains.cell_multiplier == 2.0


def _dam_break_list(every_column=True, strips=False):
    """The dam break's SPH list; ``every_column``: with the boundary rows listing every
    particle, as jax-md does (NeighborConfig.fluid_only_rows off); ``strips``: the strip
    search (the SPH family's default) instead of jax-md's 3 × 3 cells, which the DEM
    family keeps and the tests that compare with jax-md slot for slot use."""
    import dataclasses

    import jax.numpy as jnp
    sc = cases.build("dam_break", dx=0.01)
    cfg = dataclasses.replace(Physics.for_scene(sc).neighbors, strips=strips)
    if every_column:
        cfg = dataclasses.replace(cfg, fluid_only_rows=())
    x = jnp.asarray(np.concatenate([sc.fluid.x, sc.boundary.x]), jnp.float32)
    return cfg, neighbors.shift(cfg, x), neighbors.allocate(cfg, x)


def test_the_sph_family_searches_strips_and_the_dem_family_cells():
    phys = Physics.for_scene(cases.build("fpsi_failure"))
    assert phys.neighbors.strips and not phys.dem_neighbors.strips


def test_boundary_rows_list_only_the_fluid():
    """With NeighborConfig.fluid_only_rows (the SPH family's default) the fluid rows are
    jax-md's and each boundary row is jax-md's row with the wall particles taken out, in
    the same order."""
    cfg_all, xs, full = _dam_break_list()
    cfg, _, narrow = _dam_break_list(every_column=False)
    first, stop, n_f = cfg.fluid_only_rows
    n = xs.shape[0]
    assert first == n_f and stop == n
    a, b = np.asarray(full.idx), np.asarray(narrow.idx)
    assert np.sum(b[first:] < n) < 0.5 * np.sum(a[first:] < n)   # guard: walls were listed
    for i in range(n):
        row = [j for j in a[i] if j < n and (i < first or j < n_f)]
        assert list(b[i][b[i] < n]) == row


def test_rebuild_equals_jax_md_dense_list():
    """neighbors.rebuild gives jax-md's own Dense list, row for row and in order, for
    positions moved by up to a few skins (its one-mask compaction replaces jax-md's
    second distance pass and wide scatter)."""
    import jax
    import jax.numpy as jnp
    cfg, xs, nbrs = _dam_break_list()
    rng = np.random.default_rng(3)
    stale = nbrs.set(reference_position=nbrs.reference_position + 1e3)  # forces a rebuild
    jax_md = jax.jit(lambda p: neighbors.neighbor_fns(cfg).update(p, stale))
    ours = jax.jit(lambda p: neighbors.rebuild(cfg, nbrs, p))
    for scale in (0.3, 1.0, 3.0):
        xp = xs + jnp.asarray(rng.normal(0.0, scale * cfg.skin, xs.shape), xs.dtype)
        want, got = jax_md(xp), ours(xp)
        np.testing.assert_array_equal(np.asarray(got.idx), np.asarray(want.idx))
        assert bool(got.did_buffer_overflow) == bool(want.did_buffer_overflow)
        np.testing.assert_array_equal(np.asarray(got.reference_position), np.asarray(xp))


@pytest.mark.parametrize("packed", [True, False])
def test_cell_list_equals_jax_md_cell_list(packed, monkeypatch):
    """neighbors.cell_list fills jax-md's buffers slot for slot, with the packed-key sort
    and with the argsort it falls back to when hash·N + i would not fit an int32, and flags
    a full cell as jax-md does."""
    import jax
    import jax.numpy as jnp
    cfg, xs, nbrs = _dam_break_list()
    if not packed:
        monkeypatch.setattr(neighbors, "_PACKED_LIMIT", 0)
    rng = np.random.default_rng(5)
    xp = xs + jnp.asarray(rng.normal(0.0, cfg.skin, xs.shape), xs.dtype)
    for cap in (nbrs.cell_list_capacity, 2):
        want = jax.jit(lambda p: nbrs.cell_list_fn.update(p, cap))(xp)
        got = jax.jit(lambda p: neighbors.cell_list(cfg, p, cap))(xp)
        for name in ("id_buffer", "position_buffer", "particle_cell_id"):
            np.testing.assert_array_equal(np.asarray(getattr(got, name)),
                                          np.asarray(getattr(want, name)), err_msg=name)
        assert bool(got.did_buffer_overflow) == bool(want.did_buffer_overflow)
        assert bool(got.did_buffer_overflow) == (cap == 2)


def test_rebuild_flags_overflow_like_jax_md():
    """Squeezing the particles towards the column's centre overflows the K slots: both
    jax-md and neighbors.rebuild raise the flag (the host then grows the list)."""
    import jax.numpy as jnp
    cfg, xs, nbrs = _dam_break_list()
    c = xs.mean(axis=0)
    xp = c + 0.6 * (xs - c)
    want = neighbors.neighbor_fns(cfg).update(
        xp, nbrs.set(reference_position=nbrs.reference_position + 1e3))
    got = neighbors.rebuild(cfg, nbrs, xp)
    assert bool(want.did_buffer_overflow) and bool(got.did_buffer_overflow)


def _most_in_a_cell(cfg, xs):
    """The most particles in one cell of the list's grid, counted on the host with numpy
    (cell = ⌊x / cell size⌋ on jax-md's grid for the list radius)."""
    from jax_md import partition
    box = np.asarray(cfg.box, np.float32).reshape(1, -1)
    _, size, per_side, _ = partition._cell_dimensions(2, box, cfg.list_radius)
    per_side = np.asarray(per_side).ravel().astype(int)
    cell = np.mod((np.asarray(xs) / np.asarray(size)).astype(int), per_side)
    return int(np.bincount(cell[:, 0] + per_side[0] * cell[:, 1]).max())


def test_update_counts_the_neighbours_an_overflowed_list_cut_and_grow_fits_them():
    """A list with 8 slots too few per row (cells with room) overflows its rows at the
    next rebuild, not its cells: update's need is the largest row of a list with room
    for all (counted from a roomy allocation) and the fullest cell, and the list grown for
    that need holds every row with the same cells (so the rebuild's candidate pass is no
    wider)."""
    import dataclasses
    import jax.numpy as jnp
    from jax_md import partition
    cfg, xs, nbrs = _dam_break_list()
    cfg = dataclasses.replace(cfg, extra_capacity=8)      # cells with room to spare
    nbrs = neighbors.allocate(cfg, xs + jnp.asarray(cfg.origin, xs.dtype))
    short = nbrs.set(idx=nbrs.idx[:, :neighbors.capacity(nbrs) - 16])
    step = jnp.zeros_like(xs).at[0, 0].set(1.2 * cfg.skin)     # one particle past the skin
    moved = xs + jnp.asarray(cfg.origin, xs.dtype) + step
    new, rebuilt, need = neighbors.update(cfg, short, moved)
    assert bool(rebuilt)
    assert int(new.error.code) == int(partition.PartitionErrorCode.NEIGHBOR_LIST_OVERFLOW)
    roomy = neighbors.allocate(dataclasses.replace(cfg, capacity_multiplier=3.0), moved)
    want = int(np.max(np.sum(np.asarray(roomy.idx) < xs.shape[0], axis=1)))
    assert int(need[0]) == want > neighbors.capacity(short)
    assert int(need[1]) == _most_in_a_cell(cfg, neighbors.shift(cfg, moved))
    grown = neighbors.grow(cfg, new, need)
    assert grown.min_neighbors == max(neighbors.capacity(short) + 1,
                                      int(np.ceil(want * cfg.capacity_multiplier)))
    assert (grown.extra_capacity, grown.min_cell_capacity) == (cfg.extra_capacity, 0)
    fits = neighbors.allocate(grown, moved)
    assert neighbors.capacity(fits) >= grown.min_neighbors > want
    assert fits.cell_list_capacity == neighbors.allocate(cfg, moved).cell_list_capacity
    again = neighbors.rebuild(grown, fits, neighbors.shift(grown, moved))
    assert not neighbors.overflowed(again)
    _, rebuilt, need = neighbors.update(cfg, nbrs, xs + jnp.asarray(cfg.origin, xs.dtype))
    assert not bool(rebuilt) and np.all(np.asarray(need) == 0)   # nothing rebuilt


def test_grow_after_a_cell_overflow_grows_the_cells_to_their_need():
    """Squeezed particles overflow the cells: the grown config has room for the fullest
    cell × the multiplier, and rows only for what the rows counted; without a need every
    cell and row gets half a row more."""
    from jax_md import partition
    cfg, xs, nbrs = _dam_break_list()
    c = xs.mean(axis=0)
    xp = c + 0.8 * (xs - c)
    over, need = neighbors._rebuild(cfg, nbrs, xp)
    assert int(over.error.code) & int(partition.PartitionErrorCode.CELL_LIST_OVERFLOW)
    fullest = _most_in_a_cell(cfg, xp)
    assert int(need[1]) == fullest > nbrs.cell_list_capacity
    grown = neighbors.grow(cfg, over, need)
    assert grown.min_cell_capacity == int(np.ceil(fullest * cfg.capacity_multiplier))
    assert grown.extra_capacity == cfg.extra_capacity
    rows_over = int(over.error.code) & int(partition.PartitionErrorCode.NEIGHBOR_LIST_OVERFLOW)
    assert grown.min_neighbors == (max(neighbors.capacity(nbrs) + 1,
                                       int(np.ceil(int(need[0]) * cfg.capacity_multiplier)))
                                   if rows_over else 0)
    fits = neighbors.allocate(grown, xp + np.asarray(cfg.origin, np.float32))
    assert fits.cell_list_capacity >= grown.min_cell_capacity
    code = int(neighbors.rebuild(grown, fits, xp).error.code)
    assert not code & int(partition.PartitionErrorCode.CELL_LIST_OVERFLOW)
    # a scene whose cells are allocated wider (grains in the fluid) regrows them as wide
    import dataclasses
    wide = dataclasses.replace(cfg, cell_multiplier=2.0)
    assert neighbors.grow(wide, over, need).min_cell_capacity == 2 * fullest
    blind = neighbors.grow(cfg, over, (0, 0))
    assert blind.extra_capacity == cfg.extra_capacity + max(8, neighbors.capacity(nbrs) // 2)
    # the DEM list (both=True): rows and cells grow together, to 1.5× their need, so the
    # rows' overflow that follows a cells' one does not cost a second recompile
    dem = neighbors.grow(cfg, over, need, both=True)
    assert dem.min_cell_capacity == int(np.ceil(fullest * neighbors.CHEAP_REGROWTH))
    assert dem.min_neighbors == max(neighbors.capacity(nbrs),
                                    int(np.ceil(int(need[0]) * neighbors.CHEAP_REGROWTH)))


def test_update_rebuilds_only_past_half_the_skin():
    """One particle moved while the others stand still: the displacements fit in a circle
    of radius skin/2 (about their bounding box's centre) until it has moved a whole skin."""
    import jax.numpy as jnp
    cfg, xs, nbrs = _dam_break_list()
    d = jnp.zeros_like(xs).at[7, 0].set(0.99 * cfg.skin)
    same, rebuilt, _ = neighbors.update(cfg, nbrs, xs + d + jnp.asarray(cfg.origin, xs.dtype))
    assert not bool(rebuilt)
    np.testing.assert_array_equal(np.asarray(same.reference_position), np.asarray(xs))
    d = d.at[7, 0].set(1.01 * cfg.skin)
    new, rebuilt, _ = neighbors.update(cfg, nbrs, xs + d + jnp.asarray(cfg.origin, xs.dtype))
    assert bool(rebuilt)
    np.testing.assert_array_equal(np.asarray(new.reference_position), np.asarray(xs + d))


def test_moved_past_half_skin_by_hand():
    """The list holds while every displacement lies within skin/2 of 0 (jax-md's test) or
    of the centre of the displacements' bounding box."""
    import jax.numpy as jnp
    s = 1.0
    at = lambda *d: bool(neighbors.moved_past_half_skin(s, jnp.asarray(d, jnp.float32)))
    assert not at([0.0, 0.0], [0.99, 0.0])              # centre (0.495, 0)
    assert at([0.0, 0.0], [1.01, 0.0])
    assert not at([0.0, 0.0], [0.7, 0.0], [0.0, 0.7])  # centre (0.35, 0.35): 0.495 from all
    assert at([0.0, 0.0], [0.72, 0.0], [0.0, 0.72])
    assert not at([5.0, 3.0], [5.9, 3.0])               # all moved together
    # three displacements 120° apart on a circle of 0.49: the bounding box's centre
    # (0.1225, 0) is 0.57 from two of them, but all are within 0.5 of 0
    r = 0.49
    assert not at([r, 0.0], [-r / 2, r * 3 ** 0.5 / 2], [-r / 2, -r * 3 ** 0.5 / 2])
    # jax-md's test alone (the DEM sub-steps): past as soon as one moved more than 0.5
    jax_md = lambda *d: bool(neighbors.moved_past_half_skin(s, jnp.asarray(d, jnp.float32),
                                                             about_centre=False))
    assert not jax_md([0.0, 0.0], [0.49, 0.0])
    assert jax_md([0.0, 0.0], [0.51, 0.0]) and jax_md([5.0, 3.0], [5.0, 3.0])


def test_a_kept_list_holds_every_pair_within_the_cut_off():
    """Displacements that keep the list (a common drift of 3 skins plus scatter that fits
    the circle) leave no pair within r_cut out of it: the kept list's pairs within r_cut
    are those of a fresh rebuild."""
    import jax.numpy as jnp
    cfg, xs, nbrs = _dam_break_list()
    rng = np.random.default_rng(3)
    n = xs.shape[0]
    ang = rng.uniform(0, 2 * np.pi, n)
    rad = 0.499 * cfg.skin * np.sqrt(rng.uniform(0, 1, n))
    d = np.stack([np.cos(ang), np.sin(ang)], 1) * rad[:, None] + np.array([3 * cfg.skin, -cfg.skin])
    x_new = xs + jnp.asarray(d, xs.dtype)
    kept, rebuilt, _ = neighbors.update(cfg, nbrs, x_new + jnp.asarray(cfg.origin, xs.dtype))
    assert not bool(rebuilt)
    fresh = neighbors.rebuild(cfg, nbrs, x_new)
    xn = np.asarray(x_new)

    def close_pairs(idx):
        i, k = np.nonzero(idx < n)
        j = idx[i, k]
        keep = np.sum((xn[i] - xn[j]) ** 2, axis=1) < cfg.r_cut ** 2
        return set(zip(i[keep].tolist(), j[keep].tolist()))

    want = close_pairs(np.asarray(fresh.idx))
    assert len(want) > 10 * n
    assert close_pairs(np.asarray(kept.idx)) == want


def test_update_without_a_cell_list_uses_jax_md():
    """A domain under 3 cut-offs has no cell list (jax-md's O(N²) search): update falls
    back to jax-md's own and still rebuilds past half the skin."""
    import warnings
    import jax.numpy as jnp
    sc = cases.build("hydrostatic_tank", dx=0.02, depth=0.06, width=0.06)
    import dataclasses
    cfg = dataclasses.replace(Physics.for_scene(sc).neighbors, skin=0.06)  # 3 cut-offs > box
    x = jnp.asarray(np.concatenate([sc.fluid.x, sc.boundary.x]), jnp.float32)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        nbrs = neighbors.allocate(cfg, x)
    assert nbrs.cell_list_fn is None
    d = jnp.zeros_like(x).at[0, 0].set(0.6 * cfg.skin)
    new, rebuilt, need = neighbors.update(cfg, nbrs, x + d)
    assert bool(rebuilt) and np.all(np.asarray(need) == 0)
    want = neighbors.neighbor_fns(cfg).update(neighbors.shift(cfg, x + d), nbrs)
    np.testing.assert_array_equal(np.asarray(new.idx), np.asarray(want.idx))
    # growing it adds extra capacity, the one setting its allocation reads, even with a
    # need from earlier rebuilds
    grown = neighbors.grow(cfg, nbrs, (5, 3))
    assert grown.extra_capacity > cfg.extra_capacity
    assert (grown.min_neighbors, grown.min_cell_capacity) == (0, 0)


def test_running_count_equals_cumsum_exactly():
    """The per-cell-block matmul count used by the rebuild is jnp.cumsum, integer-exact,
    for sparse, dense, empty and full rows."""
    import jax.numpy as jnp
    import numpy as np

    from fpsi_jax.solver.neighbors import _running_count
    rng = np.random.default_rng(3)
    for frac in (0.0, 0.2, 0.7, 1.0):
        valid = jnp.asarray(rng.random((50, 9 * 20)) < frac)
        got = _running_count(valid, 9, 20)
        assert got.dtype == jnp.int32
        np.testing.assert_array_equal(got, jnp.cumsum(valid, axis=1, dtype=jnp.int32))


@pytest.mark.parametrize("scene, kw, extra, x64", [
    ("dam_break", {"dx": 0.01}, 0, False),
    ("dam_break", {"dx": 0.01}, 7, False),
    ("dam_break", {"dx": 0.01}, 0, True),
    ("hydrostatic_plate", {"dx": 0.0035, "d": 0.0025, "dx_boundary": 0.0025}, 0, False),
])
def test_allocate_equals_jax_md_allocate(scene, kw, extra, x64):
    """neighbors.allocate (two jitted programs) gives jax-md's eager allocation: the same
    rows in the same order, the same capacities, the same flags; for the SPH family and
    the DEM contacts, with and without extra capacity, and with float64 enabled (jax-md
    builds its grid from a float32 box whatever the mode)."""
    import jax
    prev = jax.config.jax_enable_x64
    jax.config.update("jax_enable_x64", x64)
    try:
        _check_allocate_equals_jax_md(scene, kw, extra)
    finally:
        jax.config.update("jax_enable_x64", prev)


def _check_allocate_equals_jax_md(scene, kw, extra):
    import dataclasses

    import jax.numpy as jnp
    sc = cases.build(scene, **kw)
    phys = Physics.for_scene(sc)
    fams = [(phys.neighbors, np.concatenate([sc.fluid.x, sc.boundary.x]
                                            + ([] if sc.solid is None else [sc.solid.x])))]
    if phys.dem_neighbors is not None:
        fams.append((phys.dem_neighbors, sc.solid.x))
    for cfg, x in fams:
        cfg = dataclasses.replace(cfg, extra_capacity=extra, fluid_only_rows=(), strips=False)
        x = jnp.asarray(x, jnp.float32)
        got = neighbors.allocate(cfg, x)
        want = neighbors.neighbor_fns(cfg).allocate(neighbors.shift(cfg, x),
                                                   extra_capacity=extra)
        assert got.idx.shape == want.idx.shape and got.max_occupancy == want.max_occupancy
        np.testing.assert_array_equal(np.asarray(got.idx), np.asarray(want.idx))
        assert got.cell_list_capacity == want.cell_list_capacity
        assert bool(got.did_buffer_overflow) == bool(want.did_buffer_overflow)
        np.testing.assert_array_equal(np.asarray(got.reference_position),
                                      np.asarray(want.reference_position))


def test_jax_md_is_not_imported_before_a_list_is_built():
    """Bad input is refused before jax-md's ~5 s package import (a fresh interpreter, so
    other tests' imports do not count; that lists still get built, importing it, is what
    every simulation test shows)."""
    import subprocess
    import sys
    code = (
        "import sys\n"
        "from fpsi_jax import cases\n"
        "from fpsi_jax.model.errors import ParameterError\n"
        "from fpsi_jax.run.driver import setup\n"
        "sc = cases.build('hydrostatic_tank', dx=0.02, depth=0.1, width=0.1)\n"
        "try:\n"
        "    setup(sc, dt=-1.0)\n"
        "    raise SystemExit('dt = -1 was accepted')\n"
        "except ParameterError:\n"
        "    pass\n"
        "assert 'jax_md' not in sys.modules, 'jax_md imported before any list'\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr[-2000:]
    assert neighbors.partition.Dense is not None        # the deferred import resolves


def test_rebuild_in_row_blocks_equals_jax_md_dense_list():
    """The rebuild's candidate pass in row blocks (NeighborConfig.row_block, the CPU
    default for large scenes) gives jax-md's list row for row, overflow flag included."""
    import dataclasses

    import jax
    import jax.numpy as jnp
    cfg, xs, nbrs = _dam_break_list()
    blocked = dataclasses.replace(cfg, row_block=23)     # uneven: the last block overlaps
    assert xs.shape[0] >= MIN_BLOCKS * 23 and xs.shape[0] % 23
    rng = np.random.default_rng(5)
    stale = nbrs.set(reference_position=nbrs.reference_position + 1e3)
    jax_md = jax.jit(lambda p: neighbors.neighbor_fns(cfg).update(p, stale))
    ours = jax.jit(lambda p: neighbors.rebuild(blocked, nbrs, p))
    for scale in (0.3, 3.0):
        xp = xs + jnp.asarray(rng.normal(0.0, scale * cfg.skin, xs.shape), xs.dtype)
        want, got = jax_md(xp), ours(xp)
        np.testing.assert_array_equal(np.asarray(got.idx), np.asarray(want.idx))
        assert bool(got.did_buffer_overflow) == bool(want.did_buffer_overflow)


def _rows_below_the_column_limit(cfg, nbrs, xs, limit):
    """(the config with n_columns = limit, the full list's rows, the limited list's rows),
    having checked that each limited row holds its full row's neighbours below the limit,
    first, and padding after them."""
    import dataclasses
    n = xs.shape[0]
    cut = dataclasses.replace(cfg, n_columns=limit)
    full = np.asarray(neighbors.rebuild(cfg, nbrs, xs).idx)
    got = np.asarray(neighbors.rebuild(cut, nbrs, xs).idx)
    for row_full, row in zip(full, got):
        kept = [j for j in row_full if j < limit]
        np.testing.assert_array_equal(np.sort(row[:len(kept)]), np.sort(kept))
        assert np.all(row[len(kept):] == n)
    return cut, full, got


def test_column_limit_leaves_out_only_the_columns_past_it():
    """NeighborConfig.n_columns (a scene's grains, last in the SPH family, are nobody's
    column): each row lists the full list's neighbours below the limit and nothing else;
    only the columns are put in the cells, so the cells need no room for the rest. (Within
    a cell the order may rotate: a cell's particles take the slots of their sorted
    positions modulo the capacity, as in jax-md, and the positions shift.)"""
    import jax.numpy as jnp
    cfg, xs, nbrs = _dam_break_list()
    n = xs.shape[0]
    limit = n - 200
    cut, full, got = _rows_below_the_column_limit(cfg, nbrs, xs, limit)
    removed = int(((full >= limit) & (full < n)).sum())
    assert removed > 0 and int((got == n).sum() - (full == n).sum()) == removed
    small = neighbors.allocate(cut, jnp.asarray(np.asarray(xs) + np.asarray(cfg.origin)))
    assert neighbors.capacity(small) <= neighbors.capacity(nbrs)
    np.testing.assert_array_equal(np.asarray(neighbors.rebuild(cut, small, xs).idx),
                                  np.asarray(small.idx))
    # the cells hold each column once and nothing else; the rows past the limit keep
    # their cell id
    cl = neighbors.cell_list(cut, xs, nbrs.cell_list_capacity)
    held = np.asarray(cl.id_buffer).ravel()
    np.testing.assert_array_equal(np.sort(held[held < n]), np.arange(limit))
    whole = neighbors.cell_list(cfg, xs, nbrs.cell_list_capacity)
    np.testing.assert_array_equal(np.asarray(cl.particle_cell_id),
                                  np.asarray(whole.particle_cell_id))
    assert small.cell_list_capacity <= nbrs.cell_list_capacity


def test_wall_rows_are_read_at_the_width_setup_measured():
    """setup measures the wall rows' width on the scene's first positions (the most fluid
    neighbours of a boundary row × the capacity multiplier, at least half the list's
    width K); every listed neighbour of a boundary row lies in its first ``wall_width``
    slots, so wall_rows drops padding only."""
    from fpsi_jax.run.driver import setup
    cfg, xs, nbrs = _dam_break_list(every_column=False)
    phys, _ = setup(cases.build("dam_break", dx=0.01))
    first, stop, _ = cfg.fluid_only_rows
    idx = np.asarray(nbrs.idx)
    n = xs.shape[0]
    most = int(np.max(np.sum(idx[first:stop] < n, axis=1)))
    assert phys.neighbors.wall_width == max(int(np.ceil(most * cfg.capacity_multiplier)),
                                            neighbors.capacity(nbrs) // 2)
    assert phys.neighbors.wall_width < neighbors.capacity(nbrs)     # guard: it narrows
    rows = np.asarray(neighbors.wall_rows(phys.neighbors, nbrs.idx, first, stop - first))
    assert rows.shape == (stop - first, phys.neighbors.wall_width)
    assert np.sum(rows < n) == np.sum(idx[first:stop] < n)
    assert not neighbors.overflowed(neighbors.allocate(phys.neighbors,
                                                       xs + np.asarray(cfg.origin, np.float32)))


def test_a_structure_that_can_break_starts_with_the_room_its_broken_discs_take():
    """With bonds that can break, setup gives the DEM list rows for six touching neighbours
    and cells for (⌊side/2R⌋ + 1)² centres, each × CHEAP_REGROWTH; unbreakable bonds keep
    the measured room, and so do scenes with grains (their packed bed sizes the list); the
    SPH list's wall rows keep their measured width either way."""
    import dataclasses
    from fpsi_jax.run.driver import setup
    from fpsi_jax.solver import init
    scene = cases.build("elastic_gate", dx=0.005)
    whole, params = setup(scene)
    assert not init.breakable(whole, params)
    strong = params.bond
    weak = params.replace(bond=dataclasses.replace(strong, sigma_c=2.0e5))
    broken, _ = setup(scene, params=weak)
    assert init.breakable(broken, weak)
    assert init.breakable(broken, params.replace(bond=dataclasses.replace(strong, tau_c=1e5)))
    assert whole.neighbors.wall_width == broken.neighbors.wall_width
    dem = broken.dem_neighbors
    per_cell = (int(np.floor(dem.list_radius / dem.r_cut)) + 1) ** 2      # 2R: r_cut
    assert per_cell == 4                                                  # skin 0.5 R
    assert (dem.min_neighbors, dem.min_cell_capacity) == (9, 6)           # × 1.5
    assert (whole.dem_neighbors.min_neighbors, whole.dem_neighbors.min_cell_capacity) == (0, 0)
    # with grains the packed bed sizes the list: no more room than measured
    fpsi, p = setup(cases.build("fpsi_failure", dx=0.01))
    assert init.breakable(fpsi, p) and fpsi.n_grain
    assert (fpsi.dem_neighbors.min_neighbors, fpsi.dem_neighbors.min_cell_capacity) == (0, 0)


def test_a_wall_row_past_its_width_overflows_and_grow_widens_only_it():
    """A width one short of the widest boundary row: the allocation and a rebuild flag a
    neighbour overflow, the rebuild's need[2] is that row's count, and grow widens the
    wall rows to need × WALL_REGROWTH while K and the cells stay as they were."""
    import dataclasses
    import jax.numpy as jnp
    from jax_md import partition
    cfg, xs, nbrs = _dam_break_list(every_column=False)
    first, stop, _ = cfg.fluid_only_rows
    n = xs.shape[0]
    most = int(np.max(np.sum(np.asarray(nbrs.idx)[first:stop] < n, axis=1)))
    tight = dataclasses.replace(cfg, wall_width=most - 1)
    x = xs + jnp.asarray(cfg.origin, xs.dtype)
    alloc = neighbors.allocate(tight, x)
    assert neighbors.overflowed(alloc)
    assert neighbors.capacity(alloc) == neighbors.capacity(nbrs)
    over, need = neighbors._rebuild(tight, alloc.set(error=nbrs.error), xs)
    assert int(over.error.code) == int(partition.PartitionErrorCode.NEIGHBOR_LIST_OVERFLOW)
    assert int(need[2]) == most and int(need[0]) <= neighbors.capacity(nbrs)
    for grown in (neighbors.grow(tight, over, need), neighbors.grow(tight, alloc)):
        assert grown.wall_width == int(np.ceil(most * neighbors.WALL_REGROWTH))
        assert (grown.min_neighbors, grown.min_cell_capacity, grown.extra_capacity) == (
            cfg.min_neighbors, cfg.min_cell_capacity, cfg.extra_capacity)
        fits = neighbors.allocate(grown, x)
        assert not neighbors.overflowed(fits)
        assert not neighbors.overflowed(neighbors.rebuild(grown, fits, xs))


def test_jax_md_lists_load_without_the_rest_of_jax_md():
    """neighbors.import_lean loads jax-md's partition and space without its package
    __init__ (which runs JAX at import for modules we never use); a later ``import jax_md``
    still gives the whole package, with the same partition module."""
    code = (
        "import sys\n"
        "from fpsi_jax.solver import neighbors\n"
        "dense = neighbors.partition.Dense\n"
        "assert 'jax_md' not in sys.modules and 'jax_md.energy' not in sys.modules\n"
        "assert 'jax_md.partition' in sys.modules\n"
        "import jax_md\n"
        "assert jax_md.partition is sys.modules['jax_md.partition']\n"
        "assert jax_md.partition.Dense is dense and hasattr(jax_md, 'energy')\n"
        "print('ok')\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.strip().endswith("ok")


def test_small_domain_warning_names_the_callers_line():
    """A domain under 3 cut-offs (jax-md's O(N^2) fallback) is reported once per list
    configuration, at the first line outside fpsi_jax that asked for the list."""
    from fpsi_jax.model.config import NeighborConfig
    cfg = NeighborConfig(r_cut=0.0137, skin=0.001, origin=(0.0, 0.0), box=(0.0371, 0.0373))
    x = np.random.default_rng(3).uniform(0.0, 0.037, (40, 2)).astype(np.float32)
    with pytest.warns(UserWarning, match=r"O\(N\^2\)") as record:
        neighbors.allocate(cfg, x)
    assert record[0].filename == __file__


def _most_in_a_strip(cfg, xs):
    """The most particles in one strip of the strip search (five cells of side r/2 along
    x, rows of cells along y), for any particle's cell, counted on the host with numpy."""
    side, nx, ny = neighbors._strip_grid(cfg)
    xs = np.asarray(xs, np.float64)[:cfg.n_columns or None]
    cx = np.clip(np.floor(xs[:, 0] / side).astype(int), 0, nx - 1)
    cy = np.clip(np.floor(xs[:, 1] / side).astype(int), 0, ny - 1)
    grid = np.zeros((ny, nx + 4), int)
    np.add.at(grid, (cy, cx + 2), 1)
    strips = sum(grid[:, i:i + nx] for i in range(5))        # strip centred on each cell
    return int(strips.max())


@pytest.mark.parametrize("every_column", [True, False])
@pytest.mark.parametrize("block", [0, 23])
def test_strip_rebuild_lists_the_same_pairs_as_jax_md_cells(every_column, block):
    """The strip search (NeighborConfig.strips) lists, row by row, the same neighbours as
    the 3 × 3 cells (which equal jax-md's list, above), in another order, for positions
    moved by up to a skin (a full row keeps another K of its neighbours), in one pass and in row blocks, with the wall rows listing
    only fluid or every column; a row's neighbours fill its first slots, and squeezed
    particles overflow the list."""
    import dataclasses

    import jax.numpy as jnp
    cfg, xs, cells = _dam_break_list(every_column)
    strips = dataclasses.replace(cfg, strips=True, row_block=block)
    nbrs = neighbors.allocate(strips, xs + jnp.asarray(cfg.origin, xs.dtype))
    assert neighbors.capacity(nbrs) == neighbors.capacity(cells)
    n = xs.shape[0]
    rng = np.random.default_rng(7)
    for scale in (0.0, 0.3, 1.0):
        xp = xs + jnp.asarray(rng.normal(0.0, scale * cfg.skin, xs.shape), xs.dtype)
        got, want = neighbors.rebuild(strips, nbrs, xp), neighbors.rebuild(cfg, cells, xp)
        a, b = np.asarray(got.idx), np.asarray(want.idx)
        assert int(got.error.code) == int(want.error.code) == (scale > 0.5)   # rows full
        room = (a < n).sum(axis=1) < a.shape[1]          # a full row keeps any K of its own
        assert room.mean() > 0.95
        np.testing.assert_array_equal(np.sort(a[room], axis=1), np.sort(b[room], axis=1))
        assert not np.array_equal(a, b)                        # guard: another order
        held = a < n
        assert np.all(held[:, :-1] >= held[:, 1:])             # filled from the first slot
    squeezed = xs.mean(axis=0) + 0.6 * (xs - xs.mean(axis=0))
    assert neighbors.overflowed(neighbors.rebuild(strips, nbrs, squeezed))


@pytest.mark.parametrize("packed", [True, False])
def test_strip_capacity_is_the_fullest_strip_and_grows_to_its_need(packed, monkeypatch):
    """The strip search's cell capacity is the fullest strip × the multiplier (counted by
    hand); squeezed particles overflow it (the cell flag), the rebuild's need is the
    fullest strip, and the list grown for it lists every pair again. With the packed-key
    sort and with the argsort it falls back to for large grids, the same lists."""
    import dataclasses

    import jax.numpy as jnp
    from jax_md import partition
    if not packed:
        monkeypatch.setattr(neighbors, "_PACKED_LIMIT", 0)
    cfg, xs, cells = _dam_break_list(every_column=False)
    cfg = dataclasses.replace(cfg, strips=True)
    origin = jnp.asarray(cfg.origin, xs.dtype)
    nbrs = neighbors.allocate(cfg, xs + origin)
    fullest = _most_in_a_strip(cfg, xs)
    assert nbrs.cell_list_capacity == int(fullest * cfg.capacity_multiplier)
    c = xs.mean(axis=0)
    xp = c + 0.6 * (xs - c)
    over, need = neighbors._rebuild(cfg, nbrs, xp)
    assert int(over.error.code) & int(partition.PartitionErrorCode.CELL_LIST_OVERFLOW)
    assert int(need[1]) == _most_in_a_strip(cfg, xp) > nbrs.cell_list_capacity
    grown = neighbors.grow(cfg, over, need)
    assert grown.min_cell_capacity == int(np.ceil(int(need[1]) * cfg.capacity_multiplier))
    fits = neighbors.allocate(grown, xp + origin)
    again = neighbors.rebuild(grown, fits, xp)
    assert not neighbors.overflowed(again)
    roomy = dataclasses.replace(cfg, strips=False, capacity_multiplier=3.0)
    want = neighbors.allocate(roomy, xp + origin).idx
    k = neighbors.capacity(fits)
    np.testing.assert_array_equal(np.sort(np.asarray(again.idx), axis=1),
                                  np.sort(np.asarray(want), axis=1)[:, :k])


def test_strip_column_limit_leaves_out_only_the_columns_past_it():
    """NeighborConfig.n_columns with the strip search: each row lists the full list's
    neighbours below the limit and nothing else, and the strips hold only the columns (the
    fullest strip counted without the rest)."""
    import dataclasses

    import jax.numpy as jnp
    cfg, xs, nbrs = _dam_break_list(strips=True)
    n = xs.shape[0]
    _rows_below_the_column_limit(cfg, nbrs, xs, n - 200)
    few = dataclasses.replace(cfg, n_columns=n // 3)
    small = neighbors.allocate(few, jnp.asarray(np.asarray(xs) + np.asarray(cfg.origin)))
    assert small.cell_list_capacity == int(_most_in_a_strip(few, xs) * cfg.capacity_multiplier)
    order, lo, hi = neighbors._strip_bounds(few, xs)        # the columns sort first
    assert int(np.max(np.asarray(hi))) == few.n_columns
    np.testing.assert_array_equal(np.sort(np.asarray(order)[:few.n_columns]),
                                  np.arange(few.n_columns))
