"""Physics is derived from the scene; absent mechanisms are absent from the compiled step."""
import pytest

from fpsi_jax import scenes
from fpsi_jax.params import ParameterError
from fpsi_jax.scene import Physics


def test_switched_off_terms_are_not_compiled(tiny_tank, step_hlo):
    # the named scopes of the ops, not the raw text: its locations also hold the traceback
    # of the call that first traced the step (e.g. ".../tests/test_dem.py")
    _, off, off_files = step_hlo(tiny_tank, delta_sph=False, artificial_viscosity=False,
                                 xsph=False)
    _, on, on_files = step_hlo(tiny_tank, delta_sph=True, artificial_viscosity=True, xsph=True)
    for scope in ("sph.delta", "sph.artificial_viscosity", "sph.xsph"):
        assert scope in on
        assert scope not in off
    # a fluid-only scene has no DEM, bond or coupling code at all
    for scope in ("dem.", "bonds.", "fsi.", "fpi."):
        assert not [s for s in on | off if s.startswith(scope)]
        assert scope + "py" not in on_files | off_files
    assert "sph.continuity" in off and "sph.pressure" in off


def test_fixed_boundary_has_no_extrapolation(tiny_tank, step_hlo):
    fixed = step_hlo(tiny_tank, boundary_pressure="fixed")[1]
    extra = step_hlo(tiny_tank, boundary_pressure="extrapolated")[1]
    assert "boundary.extrapolated" in extra and "boundary.extrapolated" not in fixed


def test_physics_is_hashable_and_lists_mechanisms(tiny_tank):
    a = Physics.for_scene(tiny_tank)
    b = Physics.for_scene(tiny_tank)
    assert hash(a) == hash(b) and a == b
    assert "sph.continuity" in a.mechanisms()
    assert "sph.delta" in Physics.for_scene(tiny_tank, delta_sph=True).mechanisms()


@pytest.mark.parametrize("opts, word", [
    ({"kernel": "gauss"}, "kernel"),
    ({"boundary_pressure": "magic"}, "boundary_pressure"),
    ({"h_margin": 5.0}, "h_margin"),
    ({"bogus": 1}, "bogus"),
])
def test_bad_physics_options_are_refused(tiny_tank, opts, word):
    with pytest.raises((ParameterError, ValueError), match=word):
        Physics.for_scene(tiny_tank, **opts)


def test_scene_rejects_particles_outside_domain():
    sc = scenes.hydrostatic_tank(dx=0.02, depth=0.1, width=0.1)
    sc.fluid.x[3] = (10.0, 10.0)
    with pytest.raises(ParameterError, match="fluid particle 3 .* outside the domain"):
        sc.validate()


@pytest.mark.parametrize("key, value, word", [
    ("dx", 0.0, "dx"), ("depth", -1.0, "depth"), ("rho0", float("nan"), "rho0"),
])
def test_builder_refuses_bad_values(key, value, word):
    with pytest.raises(ParameterError, match=word):
        scenes.build("hydrostatic_tank", **{key: value})


def test_params_set_and_resolve():
    sc = scenes.hydrostatic_tank(dx=0.02, depth=0.1, width=0.1)
    p = sc.params.set("mu", 2e-3)
    assert p.sph.mu == 2e-3 and p.get("sph.mu") == 2e-3
    with pytest.raises(ParameterError, match="eps_xsph"):
        sc.params.set("eps_xsph", 1.5)
    with pytest.raises(ParameterError, match="unknown parameter"):
        sc.params.set("nope", 1.0)
