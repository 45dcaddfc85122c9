"""Fluid–particle closure laws (fpi.py) against hand-computed values, the reaction law and a
gradient check."""
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from fpsi_jax import fpi

pytestmark = pytest.mark.usefixtures("float64")

RHO, MU, D = 1000.0, 1e-3, 2.5e-3


def test_drag_coefficient_schiller_naumann_and_newton():
    re = jnp.asarray([0.5, 10.0, 999.0, 2000.0])
    want = [24 / 0.5 * (1 + 0.15 * 0.5 ** 0.687), 2.4 * (1 + 0.15 * 10 ** 0.687),
            24 / 999 * (1 + 0.15 * 999 ** 0.687), 0.44]
    np.testing.assert_allclose(np.asarray(fpi.drag_coefficient(re)), want, rtol=1e-12)


def test_beta_ergun_below_and_wen_yu_above_the_switch():
    slip = 0.05
    for eps in (0.5, 0.8):
        want = 150 * (1 - eps) ** 2 * MU / (eps * D * D) + 1.75 * (1 - eps) * RHO * slip / D
        assert float(fpi.interphase_beta(eps, slip, RHO, D, MU)) == pytest.approx(want, 1e-12)
    eps = 0.9
    re = slip * eps * RHO * D / MU
    cd = 24 / re * (1 + 0.15 * re ** 0.687)
    want = 0.75 * cd * eps * (1 - eps) * RHO * slip * eps ** -2.65 / D
    assert float(fpi.interphase_beta(eps, slip, RHO, D, MU)) == pytest.approx(want, 1e-12)


def test_drag_force_is_along_the_slip_with_W19_magnitude():
    eps = jnp.asarray([0.95])
    u, v = jnp.asarray([[0.1, 0.0]]), jnp.asarray([[0.0, -0.2]])
    vol = jnp.asarray([np.pi * (D / 2) ** 2])
    f = np.asarray(fpi.drag_force(eps, u, v, vol, RHO, D, MU))[0]
    rel = np.array([0.1, 0.2])
    beta = float(fpi.interphase_beta(0.95, np.linalg.norm(rel), RHO, D, MU))
    np.testing.assert_allclose(f, beta / 0.05 * float(vol[0]) * rel, rtol=1e-12)


def test_buoyancy_is_eps_rho_v_g_upwards():
    f = np.asarray(fpi.buoyancy(jnp.asarray([0.9]), jnp.asarray([2e-6]), RHO, (0.0, -9.81)))
    np.testing.assert_allclose(f[0], [0.0, 0.9 * RHO * 2e-6 * 9.81], rtol=1e-12)


def test_lubrication_value_regularisation_cutoff_and_pair_symmetry():
    x = jnp.asarray([[[D + 1e-4, 0.0]], [[-(D + 1e-4), 0.0]]])      # i–j and j–i
    v = jnp.asarray([[[-0.01, 0.0]], [[0.01, 0.0]]])                 # approaching
    f = np.asarray(fpi.lubrication(x, v, D, MU, gap_min=0.01 * D, cutoff=0.5 * D))
    r = D + 1e-4
    want = -3 * np.pi * MU * D ** 2 / (8 * 1e-4) * (-0.01 * r) / r ** 2 * r
    np.testing.assert_allclose(f[0, 0], [want, 0.0], rtol=1e-12)
    np.testing.assert_allclose(f[0, 0] + f[1, 0], 0.0, atol=1e-18)   # Newton's third law
    assert want > 0                                                   # resists the approach
    touching = fpi.lubrication(jnp.asarray([[[D * 0.99, 0.0]]]), v[:1], D, MU, 0.01 * D, D)
    assert np.all(np.isfinite(np.asarray(touching)))                  # overlap: regularised
    far = fpi.lubrication(jnp.asarray([[[2 * D, 0.0]]]), v[:1], D, MU, 0.01 * D, 0.5 * D)
    assert float(jnp.abs(far).sum()) == 0.0


def test_voidage_and_shepard_averages():
    w = jnp.asarray([[2.0, 1.0, 5.0]])
    vol = jnp.asarray([[0.1, 0.3, 9.0]])
    valid = jnp.asarray([[True, True, False]])
    eps = fpi.fluid_voidage(w, vol, valid)
    assert float(eps[0]) == pytest.approx(1 - 0.5)
    vals = jnp.asarray([[[1.0, 0.0], [0.0, 2.0], [7.0, 7.0]]])
    avg, den = fpi.shepard(vals, w, vol, valid)
    np.testing.assert_allclose(np.asarray(avg[0]), [0.2 / 0.5, 0.6 / 0.5])
    assert float(den[0]) == pytest.approx(0.5)


def test_reaction_sums_to_minus_the_grain_force():
    rng = np.random.default_rng(3)
    n_f, n_p, k = 30, 6, 5
    idx = jnp.asarray(rng.integers(0, n_f, (n_p, k)))
    valid = jnp.asarray(rng.random((n_p, k)) > 0.2).at[:, 0].set(True)
    w = jnp.asarray(rng.random((n_p, k)))
    vol = jnp.asarray(rng.random((n_p, k)))
    weights = fpi.reaction_weights(w, vol, valid)
    np.testing.assert_allclose(np.asarray(weights.sum(1)), 1.0, rtol=1e-14)
    force = jnp.asarray(rng.normal(size=(n_p, 2)))
    out = fpi.reaction_on_fluid(force, weights, idx, n_f)
    np.testing.assert_allclose(np.asarray(out.sum(0)), -np.asarray(force.sum(0)), atol=1e-14)


def test_drag_gradient_wrt_viscosity_matches_finite_differences():
    eps = jnp.asarray([0.7, 0.9])
    u = jnp.asarray([[0.1, 0.0], [0.0, 0.05]])
    v = jnp.zeros((2, 2))
    vol = jnp.full(2, 5e-6)

    def total(mu):
        return jnp.sum(fpi.drag_force(eps, u, v, vol, RHO, D, mu))

    g = float(jax.grad(total)(MU))
    e = 1e-8
    fd = (float(total(MU + e)) - float(total(MU - e))) / (2 * e)
    np.testing.assert_allclose(g, fd, rtol=1e-6)
