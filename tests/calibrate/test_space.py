"""calibrate.space: the transforms between physical values and the optimiser's z."""
import jax
import jax.numpy as jnp
import pytest

from calibrate import space as sp
from fpsi_jax.model.errors import ParameterError
from fpsi_jax.model.params import BondParams, DemParams, Params

pytestmark = pytest.mark.usefixtures("float64")

BASE = Params(dem=DemParams(kn=2.0e5, ks=1.0e5, damping=3.0),
              bond=BondParams(kn=4.0e9, ks=2.0e9))


@pytest.mark.parametrize("f, v", [(sp.param("dem.damping"), 3.0),
                                  (sp.param("dem.damping", 0.1, 100.0), 3.0),
                                  (sp.param("dem.mu", 0.0, 1.0, log=False), 0.3),
                                  (sp.param("gravity.y", log=False), -9.81)])
def test_round_trip_and_bounds(f, v):
    z = f.to_z(v)
    assert float(f.to_value(jnp.asarray(z, jnp.float64))) == pytest.approx(v, rel=1e-6)
    if f.lo is not None:        # any z maps inside the bounds
        for zz in (-50.0, 50.0):
            val = float(f.to_value(jnp.asarray(zz)))
            assert f.lo * (1 - 1e-6) <= val <= f.hi * (1 + 1e-6)


def test_log_bounded_map_is_log_uniform():
    """σ(0) is the geometric mean of the bounds."""
    f = sp.param("dem.damping", 0.1, 1000.0)
    assert float(f.to_value(0.0)) == pytest.approx(10.0, rel=1e-6)


def test_scale_sets_every_leaf_in_proportion_and_is_differentiable():
    space = sp.ParamSpace(BASE, [sp.stiffness(0.25, 4.0)], start={"stiffness": 2.0})
    p = space.params(space.z0)
    for leaf in sp.STIFFNESS_LEAVES:
        assert float(p.get(leaf)) == pytest.approx(2.0 * float(BASE.get(leaf)), rel=1e-6)
    assert float(p.dem.damping) == 3.0
    g = jax.grad(lambda z: space.params(z).bond.kn)(space.z0)
    f = space.fitted[0]
    dv = float(jax.grad(lambda z: f.to_value(z))(space.z0[0]))
    assert float(g[0]) == pytest.approx(dv * 4.0e9, rel=1e-5)


def test_report_and_extreme():
    space = sp.ParamSpace(BASE, [sp.stiffness(0.5, 2.0), sp.param("damping", 0.1, 10.0)])
    assert space.names == ["stiffness", "dem.damping"]      # bare names resolve
    rep = space.report(space.z0)
    assert rep["stiffness"] == pytest.approx(1.0, rel=1e-6)
    assert rep["bond.kn"] == pytest.approx(4.0e9, rel=1e-6)
    hi = space.extreme("hi")
    assert hi.bond.kn == pytest.approx(8.0e9, rel=1e-5) and hi.dem.damping == pytest.approx(10.0)


@pytest.mark.parametrize("fitted, start, msg", [
    ([sp.param("dem.beta_n")], None, "must be > 0"),                  # 0 cannot go to log
    ([sp.param("dem.damping", 5.0, 10.0)], None, "out of range"),     # start outside bounds
    ([sp.param("nope")], None, "unknown parameter"),
    ([sp.param("dem.damping"), sp.param("dem.damping")], None, "fitted twice"),
    ([sp.param("dem.damping")], {"stiffness": 2.0}, "not fitted"),
    ([], None, "nothing to fit")])
def test_bad_input_names_the_parameter(fitted, start, msg):
    with pytest.raises(ParameterError, match=msg):
        sp.ParamSpace(BASE, fitted, start=start)


def test_parse_cli_spec():
    assert sp.parse("stiffness:0.25:4") == sp.stiffness(0.25, 4.0)
    assert sp.parse("dem.damping:0.1:100") == sp.param("dem.damping", 0.1, 100.0)
    with pytest.raises(ParameterError, match="name:lo:hi"):
        sp.parse("dem.damping:1")
