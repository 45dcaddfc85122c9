"""Reverse-mode gradients as the fits compile them, in float32 (the other calibrate tests
run in x64)."""
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from calibrate import cases


@pytest.mark.slow
def test_gate_gradient_is_finite_in_float32_over_a_tenth_of_a_second():
    """The coarse elastic gate's calibration loss and its reverse-mode gradient over 0.1 s
    of flow, float32, compiled together: finite and not zero. It came out NaN while an
    empty slot of a structure row was evaluated as a real fluid–structure pair and masked
    afterwards (solver.stages.structure_reaction makes it the padding pair)."""
    c = cases.elastic_gate(resolution="coarse", t_fit=0.1)
    cal, pr = c.calibration, c.calibration.problem
    z = jnp.asarray(cal.space.z0, cal.dtype)
    assert jnp.dtype(cal.dtype) == jnp.float32
    loss, g = jax.jit(jax.value_and_grad(lambda *a: cal.loss_fn(*a)[0]))(
        z, pr.state0, pr.params)
    g = np.asarray(g)
    assert np.isfinite(float(loss))
    assert np.all(np.isfinite(g)) and np.any(g != 0)
