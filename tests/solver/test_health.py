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
