"""The Tait equation of state and its inverse (fpsi_jax.physics.eos; W46, K35)."""
import math

import jax.numpy as jnp
import numpy as np
import pytest

from fpsi_jax.physics import eos

pytestmark = pytest.mark.usefixtures("float64")  # conftest: x64 for this module only


def test_known_value():
    p = float(eos.pressure(jnp.float64(1010.0), 1000.0, 20.0, 7.0))
    b = 20.0 ** 2 * 1000.0 / 7.0
    assert p == pytest.approx(b * (1.01 ** 7 - 1.0), rel=1e-13)
    assert p == pytest.approx(4122.0201, rel=1e-7)   # 57142.857 × 0.0721354
    assert float(eos.pressure(jnp.float64(1000.0), 1000.0, 20.0, 7.0)) == 0.0
    assert float(eos.density(jnp.float64(p), 1000.0, 20.0, 7.0)) == pytest.approx(
        1010.0, rel=1e-13)
    assert float(eos.density(jnp.float64(0.0), 1000.0, 20.0, 7.0)) == 1000.0


def test_inverse_of_each_other():
    rho = jnp.linspace(950.0, 1080.0, 27)
    p = eos.pressure(rho, 1000.0, 35.0, 7.0)
    np.testing.assert_allclose(np.asarray(eos.density(p, 1000.0, 35.0, 7.0)),
                               np.asarray(rho), rtol=1e-13)
    pp = jnp.linspace(-5e4, 5e5, 31)
    np.testing.assert_allclose(
        np.asarray(eos.pressure(eos.density(pp, 1000.0, 35.0, 7.0), 1000.0, 35.0,
                                7.0)), np.asarray(pp), rtol=1e-10, atol=1e-8)
    # γ = 1: linear EOS P = c0²(ρ − ρ0)
    assert float(eos.pressure(jnp.float64(1002.0), 1000.0, 10.0, 1.0)) == pytest.approx(
        200.0, rel=1e-13)


def test_density_clamped_for_tension_below_minus_b():
    b = 20.0 ** 2 * 1000.0 / 7.0
    rho = float(eos.density(jnp.float64(-3.0 * b), 1000.0, 20.0, 7.0))
    assert math.isfinite(rho) and rho == pytest.approx(1000.0 * 1e-6 ** (1 / 7), rel=1e-12)
