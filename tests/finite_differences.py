"""Gradient checks shared by the test modules."""
import jax
import jax.numpy as jnp
import numpy as np


def fd_check(loss, theta, rel_step=1e-5, tol=1e-5):
    """jax.grad of ``loss`` at ``theta`` vs a central difference with steps rel_step·θ_k
    (the 2·len(θ) forward evaluations run as one vmapped, compiled call)."""
    theta = jnp.asarray(theta, jnp.float64)
    n = theta.shape[0]
    g = np.asarray(jax.jit(jax.grad(loss))(theta))
    steps = rel_step * np.asarray(theta)
    pts = theta + jnp.concatenate([jnp.diag(steps), -jnp.diag(steps)])
    f = np.asarray(jax.jit(jax.vmap(loss))(pts))
    fd = (f[:n] - f[n:]) / (2.0 * steps)
    assert np.all(np.isfinite(g)) and np.all(g != 0.0), g
    np.testing.assert_allclose(g, fd, rtol=tol, atol=0)
    return g
