"""Health checks (fpsi_jax.solver.health) that the step runs every step."""
import jax.numpy as jnp
import numpy as np
import pytest

from fpsi_jax import cases
from fpsi_jax.model.errors import SimulationError
from fpsi_jax.run.driver import simulate
from fpsi_jax.solver import health


def test_crossed_walls_by_hand():
    a = jnp.array([[0.0, 0.0]])
    b = jnp.array([[1.0, 0.0]])                            # the floor y = 0, x in [0, 1]
    x0 = jnp.array([[0.5, 0.1], [0.5, 0.1], [1.5, 0.1], [0.5, 0.1], [0.2, 0.3]])
    x1 = jnp.array([[0.6, -0.1], [0.6, 0.05], [1.5, -0.1], [0.5, 0.0], [0.9, -0.4]])
    # through / stays above / passes beyond the end / touches only / through, slanted
    got = health.crossed_walls(x0, x1, a, b)
    np.testing.assert_array_equal(np.asarray(got), [True, False, False, False, True])


def test_a_disc_tunnelling_through_a_wall_stops_the_run():
    """A grain fired at the floor with a contact spring far too soft for the impact
    (δ_max ≈ v √(m/k_n) = 10 m/s × √(0.21 kg / 10 N/m) ≫ R) goes through it: the run stops
    at the step it crossed, naming the disc, not later when it leaves the domain."""
    sc = cases.build("wall_impact", kn=10.0)
    with pytest.raises(SimulationError, match="solid particle 0: solid particle crossed a wall"):
        simulate(sc, progress=False)


def test_a_one_sided_wall_returns_a_disc_that_went_past_its_line():
    """A spring that lets the grain overlap 1.5 R (k_n = m v²/(1.5 R)²): through a two-sided
    floor it is an error; a floor active on its upper side pushes it back out, with the
    spring–dashpot's restitution e = exp(−πβ/√(1−β²)) on the normal speed."""
    R, v, beta = 0.005, 10.0, 0.1
    m = 2700.0 * np.pi * R * R
    kn = m * v * v / (1.5 * R) ** 2
    sc = cases.build("wall_impact", kn=kn, beta=beta)
    with pytest.raises(SimulationError, match="crossed a wall"):
        simulate(sc, progress=False)
    sc = cases.build("wall_impact", kn=kn, beta=beta)
    sc.walls.side = np.array([1.0])
    res = simulate(sc, progress=False, dt=2e-5)
    e = np.exp(-np.pi * beta / np.sqrt(1 - beta ** 2))
    np.testing.assert_allclose(float(res.state.solid.v[0, 1]), e * v, rtol=0.01)
