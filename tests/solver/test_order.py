"""The fluid re-stored in cell order for a chunk (fpsi_jax.solver.order): a relabelling that
keeps every pair, changes no sum, and hands the caller the fluid in its own order."""
import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from fpsi_jax import cases, solver
from fpsi_jax.model.config import SORT_MIN_FLUID, Physics
from fpsi_jax.run.driver import setup
from fpsi_jax.solver import forward, order

_rollout = jax.jit(forward.rollout, static_argnums=(0, 3, 4))


def _scrambled_dam_break(seed=0):
    """A coarse dam break with its fluid stored in a random order."""
    sc = cases.build("dam_break", dx=0.01)
    p = np.random.default_rng(seed).permutation(sc.fluid.n)
    f = sc.fluid
    sc.fluid = dataclasses.replace(f, x=f.x[p], v=f.v[p], rho=f.rho[p], mass=f.mass[p],
                                   h=f.h[p])
    return sc


def _start(sc, sort):
    phys, params = setup(sc, sort_fluid=sort)
    p = params.as_arrays(jnp.float32)
    return phys, p, solver.init_state(sc, phys, p)


def test_cell_order_sorts_by_the_lists_cells():
    phys, _, st = _start(_scrambled_dam_break(), True)
    perm = np.asarray(order.cell_order(phys, st))
    assert sorted(perm.tolist()) == list(range(phys.n_fluid))
    cfg = phys.neighbors
    _, key = order.neighbors.cell_hash(cfg, order.neighbors.shift(cfg, st.fluid.x))
    key = np.asarray(key)[perm]
    assert np.all(np.diff(key) >= 0)
    # hand value: a particle's cell is floor(x / cell size), rows of cells along x
    x = np.asarray(st.fluid.x)[perm[0]] - np.asarray(cfg.origin)
    size = cfg.list_radius
    per_row = int(np.floor(cfg.box[0] / size))
    assert key[0] == int(x[1] // size) * per_row + int(x[0] // size)
    inv = np.asarray(order.inverse(jnp.asarray(perm)))
    np.testing.assert_array_equal(inv[perm], np.arange(phys.n_fluid))


def test_relabelling_keeps_every_pair_and_round_trips_exactly():
    phys, _, st = _start(_scrambled_dam_break(), True)
    perm = order.cell_order(phys, st)
    inv = order.inverse(perm)
    s = order.relabel(phys, st, perm, inv)
    pm, n_f = np.asarray(perm), phys.n_fluid
    x0, x1 = np.asarray(st.fluid.x), np.asarray(s.fluid.x)
    np.testing.assert_array_equal(x1, x0[pm])
    # row k of the relabelled list lists the particles row perm[k] listed, in the same slots
    i0, i1 = np.asarray(st.nbrs.idx), np.asarray(s.nbrs.idx)
    back = np.concatenate([pm, np.arange(n_f, i0.shape[0])])
    named = np.where(i1 < n_f, pm[np.minimum(i1, n_f - 1)], i1)
    np.testing.assert_array_equal(named, i0[back])
    back_state = order.relabel(phys, s, inv, perm)
    for a, b in zip(jax.tree_util.tree_leaves(st), jax.tree_util.tree_leaves(back_state)):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))


def test_a_sorted_chunk_computes_the_same_step():
    sc = _scrambled_dam_break()
    phys, p, st = _start(sc, True)
    plain = dataclasses.replace(phys, sort_fluid=False)
    one_sorted, _ = _rollout(phys, st, p, 1, None)
    one_plain, _ = _rollout(plain, st, p, 1, None)
    # the same pairs in the same slots: the same sums (to the last bit or two, where XLA
    # vectorises a row's arithmetic differently)
    for a, b in zip(jax.tree_util.tree_leaves(one_sorted.fluid),
                    jax.tree_util.tree_leaves(one_plain.fluid)):
        np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=5e-7, atol=1e-12)
    # over list rebuilds (slots filled in another order): equal to float32 round-off,
    # and what observe sees is the fluid in the caller's order
    obs = lambda s: s.fluid.x[:7]
    a, oa = _rollout(phys, st, p, 300, obs)
    b, ob = _rollout(plain, st, p, 300, obs)
    assert int(a.status.rebuilds) > 5 and not bool(a.status.bad)
    np.testing.assert_allclose(np.asarray(a.fluid.x), np.asarray(b.fluid.x), atol=2e-6)
    np.testing.assert_allclose(np.asarray(a.fluid.rho), np.asarray(b.fluid.rho), rtol=2e-6)
    np.testing.assert_allclose(np.asarray(oa), np.asarray(ob), atol=2e-6)
    ia, ib = np.asarray(a.nbrs.idx), np.asarray(b.nbrs.idx)
    assert all(set(ia[r]) == set(ib[r]) for r in range(ia.shape[0]))


def test_a_bad_particle_is_named_in_the_callers_order():
    phys, p, st = _start(_scrambled_dam_break(), True)
    bad = 17
    x = st.fluid.x.at[bad].set(jnp.nan)
    st = st.replace(fluid=st.fluid.replace(x=x))
    end, _ = _rollout(phys, st, p, 1, None)
    assert bool(end.status.bad) and int(end.status.code) == 1
    assert int(end.status.particle) == bad


def test_sorting_is_on_for_large_fluids_only():
    small = cases.build("dam_break", dx=0.01)
    assert small.fluid.n < SORT_MIN_FLUID
    assert not Physics.for_scene(small).sort_fluid
    assert Physics.for_scene(small, sort_fluid=True).sort_fluid
    large = cases.build("dam_break", dx=0.0012)
    assert large.fluid.n >= SORT_MIN_FLUID and Physics.for_scene(large).sort_fluid


@pytest.mark.parametrize("value", ["yes", 2])
def test_sort_fluid_takes_a_switch(value):
    from fpsi_jax.model.errors import ParameterError
    with pytest.raises(ParameterError, match="sort_fluid"):
        Physics.for_scene(cases.build("dam_break", dx=0.01), sort_fluid=value)
