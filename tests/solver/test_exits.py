"""Open sides (fpsi_jax.solver.exits): a particle that crosses one is parked, counted and
out of every pair; crossing a closed side stays an error (tests/run/test_driver.py)."""
import dataclasses

import jax.numpy as jnp
import numpy as np
import pytest

from fpsi_jax import cases
from fpsi_jax.model.config import Parking, Physics
from fpsi_jax.model.errors import ParameterError
from fpsi_jax.model.state import FluidState
from fpsi_jax.run.driver import simulate
from fpsi_jax.solver import exits


def _phys(sides, lo=(0.0, 0.0), hi=(1.0, 2.0)):
    return Physics(n_fluid=0, n_boundary=0, neighbors=None, domain_lo=lo, domain_hi=hi,
                   open_sides=sides, parking=Parking.for_domain(lo, hi, 10, 0.1))


def test_crossing_is_detected_on_open_sides_only():
    x = jnp.array([[-0.1, 1.0], [1.0, 1.0], [0.5, -0.01], [0.5, 2.0], [0.5, 1.0]])
    got = exits.crossed_open_side(_phys(("left", "top")), x)
    np.testing.assert_array_equal(np.asarray(got), [True, False, False, True, False])
    got = exits.crossed_open_side(_phys(("right", "bottom")), x)
    np.testing.assert_array_equal(np.asarray(got), [False, True, True, False, False])


def test_parking_spots_are_apart_and_above_the_domain():
    # 1 m wide domain, list radius 0.1 m: spacing 0.101 m, 9 columns
    pk = Parking.for_domain((0.0, 0.0), (1.0, 2.0), 20, 0.1)
    assert pk.columns == 9 and pk.rows == 3
    spots = np.asarray(exits.park_positions(pk, 0, 20, jnp.float32))
    np.testing.assert_allclose(spots[0], [0.0505, 2.0 + 0.101 + 0.0505], rtol=1e-6)
    np.testing.assert_allclose(spots[10], [1.5 * 0.101, 2.101 + 1.5 * 0.101], rtol=1e-6)
    d = np.linalg.norm(spots[:, None] - spots[None], axis=-1) + np.eye(20)
    assert d.min() > 0.1                               # no two parked particles are pairs
    assert spots[:, 1].min() - 2.0 > 0.1               # nor a parked and an active one
    assert spots[:, 0].max() < 1.0 and pk.top > spots[:, 1].max()


def test_open_sides_are_checked():
    sc = cases.build("hydrostatic_tank", dx=0.02, depth=0.1, width=0.1, t_end=0.05)
    sc.open_sides = ("top", "up")
    with pytest.raises(ParameterError, match="open_sides = 'up'.*left, right, bottom, top"):
        sc.validate()


def test_leavers_take_the_next_free_spots_in_the_order_they_leave():
    # four particles; the 2nd and 4th leave in one step (spots 0 and 1), the 1st in a later
    # one (spot 2); a step with nobody leaving moves nobody
    phys = _phys(("top",))
    x = jnp.array([[0.1, 1.0], [0.2, 2.5], [0.3, 1.0], [0.4, 2.2]])
    one = jnp.ones(4)
    fluid = FluidState(x=x, v=jnp.ones_like(x), rho=one, h=one, mass=one, acc=jnp.ones_like(x),
                       xsph=jnp.ones_like(x), t_out=-one)
    spot = np.asarray(exits.park_positions(phys.parking, 0, 3, jnp.float32))
    f1 = exits.park_fluid(phys, fluid, 0.5)
    np.testing.assert_allclose(np.asarray(f1.x), [x[0], spot[0], x[2], spot[1]])
    np.testing.assert_array_equal(np.asarray(f1.t_out), [-1, 0.5, -1, 0.5])
    np.testing.assert_array_equal(np.asarray(f1.v)[:, 0], [1, 0, 1, 0])
    same = exits.park_fluid(phys, f1, 0.6)
    np.testing.assert_array_equal(np.asarray(same.x), np.asarray(f1.x))
    f2 = exits.park_fluid(phys, f1.replace(x=f1.x.at[0, 1].set(2.1)), 0.7)
    np.testing.assert_allclose(np.asarray(f2.x), [spot[2], spot[0], x[2], spot[1]])
    np.testing.assert_allclose(np.asarray(f2.t_out), [0.7, 0.5, -1, 0.5], rtol=1e-7)


@pytest.fixture(scope="module")
def shot():
    """A tank (open top) whose top particle is shot upwards at 20 m/s: it leaves at once."""
    sc = cases.build("hydrostatic_tank", dx=0.02, depth=0.1, width=0.1, t_end=0.03)
    top = int(np.argmax(sc.fluid.x[:, 1] + 1e-3 * sc.fluid.x[:, 0]))
    sc.fluid.v = np.zeros_like(sc.fluid.x)
    sc.fluid.v[top] = (0.0, 20.0)
    assert sc.open_sides == ("top",)
    return sc, top, simulate(sc, progress=False, rho_tolerance=0.9)


def test_a_particle_through_an_open_side_is_parked_and_the_run_goes_on(shot):
    sc, top, res = shot
    f = res.state.fluid
    t_out = np.asarray(f.t_out)
    assert res.n_steps * float(res.params.dt) >= sc.t_end - 1e-9       # ran to the end
    assert np.flatnonzero(t_out >= 0).tolist() == [top]
    # it left when its path crossed the top: y0 + 20 t >= domain top (within a step)
    y0, hi = sc.fluid.x[top, 1], sc.domain_hi[1]
    t_cross = (hi - y0) / 20.0
    assert abs(t_out[top] - t_cross) <= 2 * float(res.params.dt)
    # the first particle to leave takes the first spot
    spot = np.asarray(exits.park_positions(res.physics.parking, 0, 1, jnp.float32))[0]
    np.testing.assert_allclose(np.asarray(f.x[top]), spot, rtol=1e-6)
    assert np.all(np.asarray(f.v[top]) == 0) and np.all(np.asarray(f.acc[top]) == 0)
    # nobody's neighbour, and its own row is empty
    idx = np.asarray(res.state.nbrs.idx)
    n = idx.shape[0]
    assert not np.any(idx[np.arange(n) != top] == top)
    assert np.all(idx[top] == n)
    # the mass that left plus the mass in the computation is the scene's
    m = np.asarray(f.mass)
    assert m[t_out >= 0].sum() + m[t_out < 0].sum() == pytest.approx(sc.fluid.mass.sum())


def test_the_rest_of_the_fluid_does_not_feel_the_parked_particle(shot):
    """The particles left behind stay at rest in the hydrostatic band: nothing is pulled
    towards the parked particle's spot or its exit point."""
    sc, top, res = shot
    f = res.state.fluid
    keep = np.asarray(f.t_out) < 0
    rho = np.asarray(f.rho)[keep]
    assert np.all(np.abs(rho / 1000.0 - 1.0) < 0.02)
    assert np.max(np.asarray(f.v)[keep, 1]) < 0.5


def test_over_the_walls_counts_as_through_the_open_top():
    # boundary particles span x in [0, 1] up to y = 1.5; the domain's top is at 2
    phys = dataclasses.replace(_phys(("top",)), rim=(0.0, 1.0, 1.5))
    x = jnp.array([[1.05, 1.6],      # beside the right wall, above its top: went over
                   [-0.05, 1.6],     # the same on the left
                   [1.05, 1.4],      # beside the wall below its top: not a way out
                   [0.5, 1.9],       # above the tank between the walls: still in
                   [0.5, 2.0]])      # through the domain's top
    got = exits.crossed_open_side(phys, x)
    np.testing.assert_array_equal(np.asarray(got), [True, True, False, False, True])


def test_the_rim_is_the_boundary_top_unless_a_particle_starts_beyond_it():
    sc = cases.build("hydrostatic_tank", dx=0.02, depth=0.1, width=0.1, t_end=0.03)
    xb = sc.boundary.x
    assert Physics.for_scene(sc).rim == pytest.approx(
        (xb[:, 0].min(), xb[:, 0].max(), xb[:, 1].max()))
    sc.fluid.x[0] = (xb[:, 0].max() + 0.01, xb[:, 1].max() + 0.01)
    assert Physics.for_scene(sc).rim is None
    sc.open_sides = ()
    assert Physics.for_scene(sc).rim is None


def test_a_splash_over_a_wall_leaves_through_the_open_top():
    """A particle thrown sideways above the wall's top lands outside the tank: it is
    parked when it passes the wall, not an error when it reaches the domain's floor."""
    sc = cases.build("hydrostatic_tank", dx=0.02, depth=0.1, width=0.1, t_end=0.08)
    top = int(np.argmax(sc.fluid.x[:, 1] + 1e-3 * sc.fluid.x[:, 0]))
    x_hi, y_top = sc.boundary.x[:, 0].max(), sc.boundary.x[:, 1].max()
    sc.fluid.x[top] = (sc.fluid.x[top, 0], y_top + 0.05)
    sc.fluid.v = np.zeros_like(sc.fluid.x)
    sc.fluid.v[top] = (6.0, 0.0)
    res = simulate(sc, progress=False, rho_tolerance=0.9)
    t_out = np.asarray(res.state.fluid.t_out)
    assert np.flatnonzero(t_out >= 0).tolist() == [top]
    t_cross = (x_hi - sc.fluid.x[top, 0]) / 6.0        # passes the wall's outer particles
    assert abs(t_out[top] - t_cross) <= 2 * float(res.params.dt)
