"""calibrate.targets: each measurement against an analytic signal."""
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from calibrate import targets as tg

pytestmark = pytest.mark.usefixtures("float64")


def damped(t, f_n, zeta, amp=0.01):
    wn = 2 * math.pi * f_n
    wd = wn * math.sqrt(1 - zeta ** 2)
    return amp * np.exp(-zeta * wn * t) * np.sin(wd * t)


@pytest.mark.parametrize("zeta", [0.005, 0.05, 0.2])
def test_free_vibration_recovers_frequency_and_damping_ratio(zeta):
    """On y = A e^(−ζωt) sin(ω_d t): zero crossings give ω_d exactly, and the log-peaks
    decay by πζ/√(1−ζ²) per half cycle (peaks are where tan(ω_d t) = ω_d/(ζω), all equally
    spaced, so the slope is exact)."""
    t = np.arange(1, 40001) * 1e-5
    y = damped(t, 12.0, zeta)
    f, z, n = tg.free_vibration(jnp.asarray(t), jnp.asarray(y))
    assert int(n) >= 7
    assert float(f) == pytest.approx(12.0, rel=1e-5)
    assert float(z) == pytest.approx(zeta, rel=1e-4)


def test_free_vibration_is_differentiable_in_the_signal():
    """d f/d(signal) by AD equals a finite difference (through the interpolated crossings)."""
    t = jnp.asarray(np.arange(1, 20001) * 1e-5)
    y0 = jnp.asarray(damped(np.asarray(t), 12.0, 0.05))
    dy = jnp.asarray(np.cos(37 * np.asarray(t))) * 1e-3

    def g(s):
        f, z, _ = tg.free_vibration(t, y0 + s * dy)
        return f + 100 * z

    ad = float(jax.grad(g)(0.0))
    h = 1e-4
    fd = float((g(h) - g(-h)) / (2 * h))
    assert ad == pytest.approx(fd, rel=1e-4)


def test_static_deflection_and_trajectory():
    t = np.arange(1, 101) * 0.01
    u = np.stack([np.sin(t), -0.002 * np.ones_like(t)], axis=1)
    st = tg.StaticDeflection(value=-0.0016, component=1, tail=0.1)
    np.testing.assert_allclose(np.asarray(st.residuals(t, jnp.asarray(u))), [0.25], rtol=1e-12)
    t_ref = (0.0, 0.105, 0.5, 0.9)
    ref = ((0.0, 0.0), (0.1, 0.0), (0.4, 0.0), (0.8, 0.0))
    tr = tg.Trajectory(t_ref=t_ref, values=ref, components=(0, 1), window=(0.0, 0.6),
                       scale=(1.0, 0.5))
    r = np.asarray(tr.residuals(t, jnp.asarray(u))).reshape(-1, 2)
    want_x = np.interp([0.105, 0.5], t, np.sin(t)) - np.array([0.1, 0.4])
    np.testing.assert_allclose(r[:, 0], want_x, rtol=1e-12)          # t = 0 is left out
    np.testing.assert_allclose(r[:, 1], -0.002 / 0.5, rtol=1e-12)
    rx, ry = tr.rms(t, u, window=(0.0, 1.0))
    assert rx == pytest.approx(np.sqrt(np.mean((np.interp([0.105, 0.5, 0.9], t, np.sin(t))
                                                - np.array([0.1, 0.4, 0.8])) ** 2)))
    with pytest.raises(ValueError, match="no reference sample"):
        tg.Trajectory(t_ref=(2.0,), values=((1.0, 1.0),)).residuals(t, jnp.asarray(u))


def test_total_residuals_weights():
    t = np.arange(1, 11) * 0.1
    u = jnp.zeros((10, 2)) - 0.003
    a = tg.StaticDeflection(value=-0.002, weight=4.0)
    r = tg.total_residuals([a, a], t, u)
    assert float(jnp.sum(r ** 2)) == pytest.approx(2 * 4.0 * 0.25, rel=1e-12)


def test_a_reference_that_is_zero_everywhere_is_refused():
    """A recorded component that never moves has no scale to compare a run against (the
    residuals would divide by 0): refused when the target is made, before any run."""
    from fpsi_jax.model.errors import ParameterError
    t = (0.1, 0.2, 0.3)
    with pytest.raises(ParameterError, match="component 1 of the reference is zero"):
        tg.Trajectory(t_ref=t, values=((1.0, 0.0), (2.0, 0.0), (3.0, 0.0)))
    with pytest.raises(ParameterError, match="NaN or inf"):
        tg.Trajectory(t_ref=t, values=((1.0, 1.0), (float("nan"), 0.0), (3.0, 1.0)))
    tg.Trajectory(t_ref=t, values=((1.0, 0.0), (2.0, 0.0), (3.0, 0.0)), scale=(1.0, 1.0))
