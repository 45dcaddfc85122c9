"""Unit tests of the 2D SPH kernels (fpsi_jax.physics.kernels; physics.md §SPH, K28/W41).

Every kernel is checked against its closed form and its defining properties: value at
q = 0, compact support 2h, ∫W dA = 1 in 2D, dW/dr consistent with W, and the gradient
factor F = (1/r) dW/dr consistent with dW/dr and finite at r = 0.
"""
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from fpsi_jax.model.errors import ParameterError
from fpsi_jax.model.options import KernelKind
from fpsi_jax.physics import kernels


pytestmark = pytest.mark.usefixtures("float64")  # conftest: x64 for this module only


NAMES = ("wendland", "cubic")
H = 0.0137  # an arbitrary smoothing length (not 1, so h-scalings are exercised)


def _np(a):
    return np.asarray(a, dtype=np.float64)


# --- closed forms, written independently of the package ----------------------------------
def wendland_ref(r, h):
    q = np.asarray(r, float) / h
    return np.where(q < 2, 7.0 / (4 * math.pi * h * h) * (1 - q / 2) ** 4 * (2 * q + 1), 0.0)


def cubic_ref(r, h):
    q = np.asarray(r, float) / h
    s = 10.0 / (7 * math.pi * h * h)
    return s * np.where(q < 1, 1 - 1.5 * q ** 2 + 0.75 * q ** 3,
                        np.where(q < 2, 0.25 * (2 - q) ** 3, 0.0))


REF = {"wendland": wendland_ref, "cubic": cubic_ref}


def test_get_known_and_unknown():
    assert kernels.get("wendland").name == "wendland"
    assert kernels.get("cubic").name == "cubic"
    assert kernels.get(KernelKind.WENDLAND).name == "wendland"
    with pytest.raises(ParameterError, match="kernel = 'gaussian' is not a choice; allowed: "
                                             "wendland, cubic"):
        kernels.get("gaussian")


def test_wendland_value_at_origin():
    for h in (0.005, 1.0, 2.5):
        w0 = float(kernels.get("wendland").w(jnp.float64(0.0), jnp.float64(h)))
        assert w0 == pytest.approx(7.0 / (4.0 * math.pi * h * h), rel=1e-14)


def test_cubic_value_at_origin():
    for h in (0.005, 1.0, 2.5):
        w0 = float(kernels.get("cubic").w(jnp.float64(0.0), jnp.float64(h)))
        assert w0 == pytest.approx(10.0 / (7.0 * math.pi * h * h), rel=1e-14)


@pytest.mark.parametrize("name", NAMES)
def test_value_matches_closed_form(name):
    k = kernels.get(name)
    r = np.linspace(0.0, 2.5 * H, 1001)
    np.testing.assert_allclose(_np(k.w(jnp.asarray(r), H)), REF[name](r, H),
                               rtol=1e-12, atol=1e-12 * REF[name](0.0, H))


@pytest.mark.parametrize("name", NAMES)
def test_compact_support(name):
    k = kernels.get(name)
    r = jnp.asarray([2.0, 2.0 + 1e-12, 2.3, 3.0, 10.0, 1e6]) * H
    assert np.all(_np(k.w(r, H)) == 0.0)
    assert np.all(_np(k.dw_dr(r, H)) == 0.0)
    assert np.all(_np(k.grad_factor(r * r, H)) == 0.0)
    # ... and positive / strictly decreasing inside the support
    rin = jnp.linspace(0.0, 1.999, 500) * H
    w = _np(k.w(rin, H))
    assert np.all(w > 0)
    assert np.all(np.diff(w) < 0)
    assert np.all(_np(k.dw_dr(rin[1:], H)) < 0)
    # it approaches zero continuously at q = 2
    assert float(k.w(jnp.float64(2.0 * H * (1 - 1e-6)), H)) < 1e-12 * float(k.w(0.0, H))


@pytest.mark.parametrize("name", NAMES)
def test_normalisation_polar(name):
    """∫ W dA = ∫_0^{2h} W(r) 2πr dr = 1 (Gauss–Legendre on each smooth piece)."""
    k = kernels.get(name)
    xg, wg = np.polynomial.legendre.leggauss(64)
    total = 0.0
    for a, b in ((0.0, H), (H, 2.0 * H)):       # cubic has a kink in W'' at q = 1
        r = 0.5 * (b - a) * xg + 0.5 * (b + a)
        total += 0.5 * (b - a) * np.sum(wg * _np(k.w(jnp.asarray(r), H)) * 2 * math.pi * r)
    assert total == pytest.approx(1.0, abs=1e-10)


@pytest.mark.parametrize("name", NAMES)
def test_normalisation_cartesian(name):
    """Σ W ΔA over a fine Cartesian grid (midpoint rule) = 1 within 1e-4."""
    k = kernels.get(name)
    n = 800
    d = 4.0 * H / n
    c = -2.0 * H + (np.arange(n) + 0.5) * d
    X, Y = np.meshgrid(c, c, indexing="ij")
    r = jnp.asarray(np.hypot(X, Y))
    total = float(jnp.sum(k.w(r, H))) * d * d
    assert abs(total - 1.0) < 1e-4


@pytest.mark.parametrize("name", NAMES)
def test_dw_dr_matches_finite_difference(name):
    k = kernels.get(name)
    q = np.linspace(0.01, 1.99, 397)
    q = q[np.abs(q - 1.0) > 1e-3]
    r = q * H
    eps = 1e-6 * H
    fd = (_np(k.w(jnp.asarray(r + eps), H)) - _np(k.w(jnp.asarray(r - eps), H))) / (2 * eps)
    dw = _np(k.dw_dr(jnp.asarray(r), H))
    scale = float(np.max(np.abs(dw)))
    np.testing.assert_allclose(dw, fd, rtol=0, atol=1e-7 * scale)
    # and against JAX's own derivative of w (exact up to round-off)
    auto = _np(jax.vmap(jax.grad(lambda rr: k.w(rr, H)))(jnp.asarray(r)))
    np.testing.assert_allclose(dw, auto, rtol=1e-12, atol=1e-13 * scale)


def test_wendland_dw_dr_closed_form():
    k = kernels.get("wendland")
    q = np.linspace(0.0, 1.99, 200)
    want = 7.0 / (4 * math.pi * H ** 3) * (-5 * q) * (1 - q / 2) ** 3
    np.testing.assert_allclose(_np(k.dw_dr(jnp.asarray(q * H), H)), want, rtol=1e-12,
                               atol=1e-14 * np.max(np.abs(want)))


@pytest.mark.parametrize("name", NAMES)
def test_grad_factor_times_r_is_dw_dr(name):
    k = kernels.get(name)
    r = np.linspace(1e-4, 2.2, 600) * H
    gf = _np(k.grad_factor(jnp.asarray(r * r), H))
    dw = _np(k.dw_dr(jnp.asarray(r), H))
    np.testing.assert_allclose(gf * r, dw, rtol=1e-11, atol=1e-13 * np.max(np.abs(dw)))


@pytest.mark.parametrize("name", NAMES)
def test_grad_factor_finite_at_origin(name):
    k = kernels.get(name)
    f0 = float(k.grad_factor(jnp.float64(0.0), H))
    assert math.isfinite(f0) and f0 < 0
    # F(0) = lim_{r→0} (1/r) dW/dr = W''(0)
    want = {"wendland": -35.0 / (4 * math.pi * H ** 4),
            "cubic": -3.0 * 10.0 / (7 * math.pi * H ** 4)}[name]
    assert f0 == pytest.approx(want, rel=1e-13)
    r = 1e-7 * H
    assert float(k.dw_dr(jnp.float64(r), H)) / r == pytest.approx(f0, rel=1e-6)
    # two coincident particles: ∇W = x_ij F = 0, not NaN
    assert float(jnp.zeros(2).dot(jnp.ones(2)) * k.grad_factor(0.0, H)) == 0.0


@pytest.mark.parametrize("name", NAMES)
def test_h_scaling(name):
    """W(r, h) = W(r/h, 1)/h² in 2D; dW/dr = dW/dq(r/h, 1)/h³."""
    k = kernels.get(name)
    q = jnp.linspace(0.0, 2.1, 50)
    np.testing.assert_allclose(_np(k.w(q * H, H)), _np(k.w(q, 1.0)) / H ** 2, rtol=1e-12,
                               atol=1e-14 / H ** 2)
    np.testing.assert_allclose(_np(k.dw_dr(q * H, H)), _np(k.dw_dr(q, 1.0)) / H ** 3,
                               rtol=1e-12, atol=1e-14 / H ** 3)
