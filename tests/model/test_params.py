"""The differentiable parameters (fpsi_jax.model.params): set and resolve by name, and the
refusals of Params.validate for the solid phase."""
import pytest

from fpsi_jax import cases
from fpsi_jax.model.errors import ParameterError
from fpsi_jax.model.params import BondParams, DemParams, Params


def test_params_set_and_resolve():
    sc = cases.build("hydrostatic_tank", dx=0.02, depth=0.1, width=0.1)
    p = sc.params.set("mu", 2e-3)
    assert p.sph.mu == 2e-3 and p.get("sph.mu") == 2e-3
    with pytest.raises(ParameterError, match="eps_xsph"):
        sc.params.set("eps_xsph", 1.5)
    with pytest.raises(ParameterError, match="unknown parameter"):
        sc.params.set("nope", 1.0)


@pytest.mark.parametrize("params, word", [
    (Params(dem=DemParams(kn=-1.0)), "dem.kn"),
    (Params(dem=DemParams(kn=0.0)), "dem.kn"),
    (Params(dem=DemParams(beta_n=1.0)), "dem.beta_n"),
    (Params(dem=DemParams(beta_s=1.5)), "dem.beta_s"),
    (Params(dem=DemParams(mu=-0.1)), "dem.mu"),
    (Params(dem=DemParams(alpha=1.0)), "dem.alpha"),
    (Params(dem=DemParams(load_ramp=-1.0)), "dem.load_ramp"),
    (Params(dem=DemParams(), bond=BondParams(thickness=0.0)), "bond.thickness"),
    (Params(dem=DemParams(), bond=BondParams(kn=0.0)), "bond.kn"),
    (Params(dem=DemParams(), bond=BondParams(sigma_c=-1.0)), "bond.sigma_c"),
    (Params(dem=DemParams(), bond=BondParams(beta_bar=1.5)), "bond.beta_bar"),
    (Params(dem=DemParams(), bond=BondParams(lam=1.2)), "bond.lam"),
])
def test_params_validate_refuses(params, word):
    with pytest.raises(ParameterError, match=word.replace(".", r"\.")):
        params.validate()


def test_params_validate_accepts_defaults():
    p = Params(dem=DemParams(beta_n=0.999), bond=BondParams())
    assert p.validate() is p
    assert p.set("dem.kn", 2.0e6).dem.kn == 2.0e6
    with pytest.raises(ParameterError, match=r"dem\.beta_n"):
        p.set("dem.beta_n", 1.0)
