"""The scene (fpsi_jax.model.scene): Scene.validate refuses particles outside the domain and
bad bonds, disc masses and missing bond parameters."""
import numpy as np
import pytest

from fpsi_jax import cases
from fpsi_jax.build import disc_block
from fpsi_jax.model.errors import ParameterError
from fpsi_jax.model.params import BondParams, DemParams, Params
from fpsi_jax.model.scene import BondBlock, Scene


def test_scene_rejects_particles_outside_domain():
    sc = cases.build("hydrostatic_tank", dx=0.02, depth=0.1, width=0.1)
    sc.fluid.x[3] = (10.0, 10.0)
    with pytest.raises(ParameterError, match=r"fluid particle 3 at \(10, 10\) lies outside "
                                             r"the domain \[\(-"):
        sc.validate()


def test_scene_names_the_array_whose_rows_disagree_with_the_positions():
    sc = cases.build("hydrostatic_tank", dx=0.02, depth=0.1, width=0.1)
    n = sc.fluid.n
    sc.fluid.v = np.zeros((n + 1, 2))
    with pytest.raises(ParameterError, match=rf"fluid.v has shape \({n + 1}, 2\) and fluid.x "
                                             rf"\({n}, 2\): allowed \({n}, 2\)"):
        sc.validate()


def _bonded(i=(0,), j=(1,), mass=None):
    x = np.array([[0.02, 0.05], [0.03, 0.05], [0.04, 0.05]])
    blk = disc_block(x, 0.005, 2700.0)
    if mass is not None:
        blk.mass[:] = mass
    return Scene(name="b", params=Params(dem=DemParams(), bond=BondParams()),
                 domain_lo=(0.0, 0.0), domain_hi=(0.1, 0.1), v_max=1.0, solid=blk,
                 bonds=BondBlock(i=np.asarray(i, np.int32), j=np.asarray(j, np.int32)))


def test_scene_validate_accepts_good_bonds():
    assert _bonded((0, 1), (1, 2)).validate().bonds.n == 2


@pytest.mark.parametrize("i, j, word", [
    ((0,), (3,), "out of range"),
    ((-1,), (1,), "out of range"),
    ((0, 1), (1, 7), "out of range"),
    ((1,), (1,), r"i == j"),
])
def test_scene_validate_refuses_bad_bonds(i, j, word):
    with pytest.raises(ParameterError, match=word):
        _bonded(i, j).validate()


def test_scene_validate_refuses_zero_disc_mass():
    with pytest.raises(ParameterError, match=r"solid\.mass\[0\]"):
        _bonded(mass=np.array([0.0, 1.0, 1.0])).validate()
    with pytest.raises(ParameterError, match=r"solid\.mass\[2\]"):
        _bonded(mass=np.array([1.0, 1.0, -1.0])).validate()


def test_scene_validate_refuses_bonds_without_bond_params():
    sc = _bonded()
    sc.params = Params(dem=DemParams())
    with pytest.raises(ParameterError, match=r"params\.bond is None"):
        sc.validate()
