"""The pair primitive (fpsi_jax.physics.pairs): the geometry of the hand-placed pairs against
plain Python, the padded slot, and the variadic neighbour sum."""
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from fpsi_jax.physics import pairs

from .sph_reference import M, NBRS, NF, RHO_OLD, V, X, Hs, Pair, _pairs

pytestmark = pytest.mark.usefixtures("float64")  # conftest: x64 for this module only


def test_norm2_is_the_squared_length_of_each_vector():
    """d_x² + d_y² over any leading shape: (3, 4) → 25, (−1.5, 2) → 6.25, a padded slot's
    far-away difference stays finite."""
    d = jnp.array([[[3.0, 4.0], [-1.5, 2.0]], [[0.0, 0.0], [pairs.FAR, -pairs.FAR]]])
    np.testing.assert_array_equal(np.asarray(pairs.norm2(d)),
                                  [[25.0, 6.25], [0.0, 2.0 * pairs.FAR ** 2]])
    e = jnp.array([[[1.0, -2.0], [0.5, 4.0]], [[7.0, 3.0], [0.0, 1.0]]])
    np.testing.assert_array_equal(np.asarray(pairs.dot2(d, e)), [[-5.0, 7.25], [0.0, -pairs.FAR]])


def test_pair_geometry():
    pr = _pairs()
    for i, nb in NBRS.items():
        for k, j in enumerate(nb):
            ref = Pair(i, j, X, V, Hs)
            np.testing.assert_allclose(np.asarray(pr.dx[i, k]), ref.xij, rtol=1e-14)
            np.testing.assert_allclose(np.asarray(pr.vij[i, k]), ref.vij, rtol=1e-14)
            assert float(pr.r2[i, k]) == pytest.approx(ref.r2, rel=1e-13)
            assert float(pr.hij[i, k]) == pytest.approx(ref.h, rel=1e-14)
            assert float(pr.w[i, k]) == pytest.approx(ref.w, rel=1e-12)
            assert float(pr.f[i, k]) == pytest.approx(ref.f, rel=1e-12)
            assert float(pr.m_j[i, k]) == M[j]
            assert float(pr.rho_j[i, k]) == RHO_OLD[j]
            assert bool(pr.fluid_j[i, k]) == (j < NF)
    # the padded slot
    assert np.all(np.asarray(pr.w[:, 2]) == 0.0)
    assert np.all(np.asarray(pr.f[:, 2]) == 0.0)
    assert not np.any(np.asarray(pr.fluid_j[:, 2]))


def test_sum_neighbours_equals_per_term_sums_and_differentiates_with_an_unused_output():
    """The variadic neighbour sum: the same values as jnp.sum per term, and a gradient that
    uses only some outputs (a symbolic-zero cotangent for the rest: JAX's own transpose of a
    variadic reduce failed there) equals the per-term one."""
    a = jnp.arange(12.0).reshape(3, 4) / 7.0
    b = jnp.cos(a)
    sa, sb = pairs.sum_neighbours(a, b)
    np.testing.assert_allclose(sa, jnp.sum(a, axis=1), rtol=1e-6)
    np.testing.assert_allclose(sb, jnp.sum(b, axis=1), rtol=1e-6)

    def run(c, total):
        def body(x, _):
            u, v = total(x * c, jnp.sin(x))      # v is carried out, never used
            return x + 0.01 * u[:, None], v
        x, _ = jax.lax.scan(body, a, None, length=3)
        return jnp.sum(x ** 2)

    per_term = lambda *t: tuple(jnp.sum(x, axis=1) for x in t)
    g = jax.grad(run)(2.0, pairs.sum_neighbours)       # raised TypeError without the rule
    np.testing.assert_allclose(g, jax.grad(run)(2.0, per_term), rtol=1e-6)
    jf = jax.jacfwd(lambda x: pairs.sum_neighbours(x, x * x)[1])(a)
    np.testing.assert_allclose(jf, jax.jacfwd(lambda x: jnp.sum(x * x, axis=1))(a), rtol=1e-6)


@pytest.mark.parametrize("n_rows, block", [(400, 10), (401, 10), (323, 8), (390, 10)])
def test_over_row_blocks_equals_one_pass(n_rows, block):
    """Row blocks give the one-pass result row for row, including a last block that starts
    early (its overlapping rows are not taken twice) and a count too small to block."""
    a = jnp.arange(3.0 * n_rows).reshape(n_rows, 3)

    def fn(row0, rows):
        own = pairs.rows_of(a, row0, rows)
        return own * 2.0 + 1.0, jnp.sum(own, axis=1)
    want = fn(0, n_rows)
    assert (n_rows >= pairs.MIN_BLOCKS * block) == (n_rows != 390)    # 390: one pass
    got = pairs.over_row_blocks(fn, n_rows, block)
    for g, w in zip(got, want):
        np.testing.assert_array_equal(np.asarray(g), np.asarray(w))


def test_pairs_of_rows_from_an_offset_equal_those_rows_of_the_whole_table():
    """pairs.pairs for the rows from row0 on (a traced row0, as inside the row blocks)
    equals those rows of the pairs of all rows."""
    from .sph_reference import IDX, KERN, RHO_OLD, _a
    whole = _pairs()
    rho = _a(RHO_OLD)
    idx = jnp.asarray(IDX, jnp.int32)
    part = jax.jit(lambda r0: pairs.pairs(
        KERN, NF, _a(X), _a(V), _a(Hs), _a(M), rho,
        jax.lax.dynamic_slice_in_dim(idx, r0, 1), r0))(1)
    for name in ("dx", "r2", "hij", "w", "f", "vij", "m_j", "rho_j"):
        np.testing.assert_allclose(np.asarray(getattr(part, name)),      # jit vs eager:
                                   np.asarray(getattr(whole, name))[1:2], rtol=1e-14)
    np.testing.assert_array_equal(np.asarray(part.own(rho)), np.asarray(rho)[1:2])
