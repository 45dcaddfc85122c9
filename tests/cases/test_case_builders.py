"""Scene builders (fpsi_jax.cases): bad values and bad options are refused by name before
anything is compiled."""
import pytest

from fpsi_jax import cases
from fpsi_jax.model.config import Physics
from fpsi_jax.model.errors import ParameterError

from ..small_scenes import coarse_plate


@pytest.mark.parametrize("key, value, word", [
    ("dx", 0.0, "dx"), ("depth", -1.0, "depth"), ("rho0", float("nan"), "rho0"),
])
def test_builder_refuses_bad_values(key, value, word):
    with pytest.raises(ParameterError, match=word):
        cases.build("hydrostatic_tank", **{key: value})


def test_bad_coupling_is_refused_before_compiling():
    with pytest.raises(ParameterError, match="coupling = 'glue' is not a choice; allowed: "
                                             "stationary, pressure_gradient"):
        coarse_plate(coupling="glue")
    with pytest.raises(ParameterError, match="gap"):
        cases.build("elastic_gate", gap=-0.001)
    with pytest.raises(ParameterError, match="fsi"):
        Physics.for_scene(coarse_plate(), fsi="glue")
