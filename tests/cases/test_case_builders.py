"""Scene builders (fpsi_jax.cases): bad values and bad options are refused by name before
anything is compiled."""
import numpy as np
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


def test_plate_of_any_disc_size_spans_the_span_asked_for():
    """78.75 mm at d = 2 mm (39.4 discs): the clamped columns stand on x = 0 and x = 78.75 mm,
    the columns between them 78.75/39 mm apart, bonded across the gaps; at d = 1.25 mm
    (63 d) the plate is the d-spaced lattice itself."""
    sc = cases.build("hydrostatic_plate", d=0.002)
    x, fixed = sc.solid.x, sc.solid.fixed
    inner = np.unique(np.round(x[~fixed, 0], 12))
    assert x[fixed & (x[:, 0] < 0.01), 0].max() == 0.0
    assert x[fixed & (x[:, 0] > 0.01), 0].min() == pytest.approx(0.07875, rel=1e-12)
    np.testing.assert_allclose(np.diff(inner), 0.07875 / 39, rtol=1e-9)
    assert sc.builder_kwargs["span_built"] == 0.07875
    n_cols = np.unique(np.round(x[:, 0], 12)).size
    assert sc.bonds.n == (n_cols - 1) * 2 + n_cols * 1          # 2 rows of 2 mm discs
    base = cases.build("hydrostatic_plate")
    assert np.allclose(np.diff(np.unique(np.round(base.solid.x[:, 0], 12))), 0.00125)
