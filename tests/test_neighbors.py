"""Neighbour lists: overflow → reallocate and redo (no pair dropped), leaving the domain."""
import numpy as np
import pytest

from fpsi_jax import neighbors, scenes
from fpsi_jax.simulate import SimulationError, simulate


def squeezed_block():
    """A free block of water (no walls, no gravity) whose particles converge on its centre:
    the neighbour count per particle roughly doubles within the run."""
    sc = scenes.build("hydrostatic_tank", dx=0.01, depth=0.1, width=0.1, t_end=0.02)
    sc.boundary = None
    sc.params = sc.params.replace(gravity=(0.0, 0.0))
    c = sc.fluid.x.mean(axis=0)
    sc.fluid.v = -12.0 * (sc.fluid.x - c)
    sc.fluid.rho = np.full(sc.fluid.n, 1000.0)
    return sc


def test_overflow_is_redone_and_equals_a_large_allocation():
    # a thin skin (0.1 h), so the compression outgrows the list within the 24 steps
    tight = simulate(squeezed_block(), progress=False, capacity_multiplier=1.0,
                     chunk_steps=20, rho_tolerance=0.9, skin=0.1)
    roomy = simulate(squeezed_block(), progress=False, capacity_multiplier=4.0,
                     chunk_steps=20, rho_tolerance=0.9, skin=0.1)
    assert tight.reallocations >= 1          # the tight list did overflow ...
    assert roomy.reallocations == 0
    assert tight.n_steps == roomy.n_steps
    # ... and the redone chunks give the same answer as a list that never overflowed
    np.testing.assert_allclose(np.asarray(tight.state.fluid.x),
                               np.asarray(roomy.state.fluid.x), rtol=0, atol=1e-6)
    np.testing.assert_allclose(np.asarray(tight.state.fluid.rho),
                               np.asarray(roomy.state.fluid.rho), rtol=1e-5)


def test_particle_leaving_the_domain_is_a_clear_error(tmp_path):
    sc = scenes.build("hydrostatic_tank", dx=0.02, depth=0.1, width=0.1, t_end=0.05)
    top = int(np.argmax(sc.fluid.x[:, 1] + 1e-3 * sc.fluid.x[:, 0]))
    sc.fluid.v = np.zeros_like(sc.fluid.x)
    sc.fluid.v[top] = (0.0, 20.0)          # shoots out of the open top of the domain
    with pytest.raises(SimulationError,
                       match=f"fluid particle {top}: particle left the domain"):
        simulate(sc, progress=False, output=str(tmp_path / "out.h5"), rho_tolerance=0.9)


def test_grow_adds_room():
    sc = scenes.build("hydrostatic_tank", dx=0.02, depth=0.1, width=0.1)
    from fpsi_jax.scene import Physics
    import jax.numpy as jnp
    phys = Physics.for_scene(sc)
    x = jnp.concatenate([jnp.asarray(sc.fluid.x), jnp.asarray(sc.boundary.x)])
    nb = neighbors.allocate(phys.neighbors, x)
    bigger = neighbors.allocate(neighbors.grow(phys.neighbors, nb), x)
    assert neighbors.capacity(bigger) > neighbors.capacity(nb)
    assert not neighbors.overflowed(nb)
