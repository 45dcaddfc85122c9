"""Observers (run/observers.py): what they record, and that an observer built under x64
traces cleanly without it."""
import warnings

import jax
import jax.numpy as jnp
import numpy as np

from fpsi_jax.model.state import SolidState
from fpsi_jax.run import observers


def _solid(x):
    x = jnp.asarray(x, jnp.float32)
    n = x.shape[0]
    z = jnp.zeros(n, jnp.float32)
    return SolidState(x=x, v=jnp.zeros_like(x), theta=z, omega=z, acc=jnp.zeros_like(x),
                      alpha=z, radius=z, mass=z, inertia=z, fixed=jnp.zeros(n, bool),
                      f_ext=jnp.zeros_like(x), shear=None, wall_shear=None)


class _State:
    def __init__(self, solid):
        self.solid = solid


def test_mean_position_and_displacement_by_hand():
    x = np.array([[0.0, 0.0], [1.0, 2.0], [3.0, 4.0]])
    s = _State(_solid(x))
    np.testing.assert_allclose(observers.mean_position([1, 2])(s), [2.0, 3.0])
    np.testing.assert_allclose(observers.mean_position([False, True, True], axis=1)(s), 3.0)
    moved = _State(_solid(x + [0.5, -1.0]))
    np.testing.assert_allclose(observers.mean_displacement(x, [0, 2])(moved), [0.5, -1.0],
                               rtol=1e-6)


def test_an_observer_built_under_x64_traces_without_it():
    """``simulate`` sets x64 for its own run (Physics.x64); an observer built while a
    float64 run had it on, and traced in a float32 run after it, must not ask for int64
    (it warned 'Explicitly requested dtype int64 ... truncated to int32')."""
    prev = jax.config.jax_enable_x64
    try:
        jax.config.update("jax_enable_x64", True)
        obs = observers.mean_position([0, 2], axis=0)
        jax.config.update("jax_enable_x64", False)
        s = _State(_solid([[0.0, 1.0], [5.0, 5.0], [2.0, 3.0]]))
        with warnings.catch_warnings(record=True) as w:
            warnings.simplefilter("always")
            value = float(jax.jit(lambda st: obs(_State(st)))(s.solid))
    finally:
        jax.config.update("jax_enable_x64", prev)
    assert value == 1.0
    assert not [m for m in w if "int64" in str(m.message)], [str(m.message) for m in w]
