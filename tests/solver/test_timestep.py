"""Time-step bounds (fpsi_jax.solver.timestep): the derived step is the minimum of the
phases' bounds, a step above it is refused naming the bound, a fluid-coupled structure keeps
physics.md's coefficients, the wall backstop bounds the step, and a coupled scene's DEM
sub-steps are derived from the two bounds."""
import dataclasses

import numpy as np
import pytest

from fpsi_jax import cases
from fpsi_jax.model.errors import ParameterError
from fpsi_jax.model.config import Physics
from fpsi_jax.run.driver import setup
from fpsi_jax.solver import timestep

from ..small_scenes import coarse_plate


def test_user_dt_above_bound_is_refused_with_the_bound(tiny_tank):
    bound = timestep.stable_dt(tiny_tank)
    with pytest.raises(ParameterError, match=f"{bound:.4g}"):
        setup(tiny_tank, dt=2 * bound)
    phys, params = setup(tiny_tank, dt=0.5 * bound)
    assert params.dt == pytest.approx(0.5 * bound)


def test_stable_dt_is_the_minimum_of_the_bounds(tiny_tank):
    sp = tiny_tank.params.sph
    h = float(tiny_tank.fluid.h.min())
    acoustic = timestep.SPH_CFL * h / (sp.c0 + tiny_tank.v_max)
    viscous = 0.125 * h * h / (sp.mu / sp.rho0)
    force = 0.25 * np.sqrt(h / 9.81)
    assert timestep.stable_dt(tiny_tank) == pytest.approx(min(acoustic, viscous, force))


def test_fluid_coupled_structure_takes_its_own_sph_coefficient():
    """Fluid-only and DEM-only scenes take SPH_CFL and DEM_DT_FACTOR; a scene with option
    fsi takes FSI_SPH_CFL = 0.375 h/(c0+|v|) (accuracy of the force-holding coupling) and the
    DEM's own 0.55 √(m/k), and the same scene without the coupling the larger SPH step."""
    sc = coarse_plate()
    assert sc.options.get("fsi") is not None
    bare = dataclasses.replace(sc, options={k: v for k, v in sc.options.items() if k != "fsi"})
    h = float(sc.fluid.h.min())
    acoustic = lambda cfl: cfl * h / (float(sc.params.sph.c0) + sc.v_max)
    assert timestep.FSI_SPH_CFL == 0.375 and timestep.FSI_DEM_DT_FACTOR == 0.55
    assert timestep.sph_dt(sc, sc.params) == pytest.approx(acoustic(0.375))
    assert timestep.sph_dt(bare, bare.params) == pytest.approx(acoustic(timestep.SPH_CFL))
    assert timestep.dem_dt(sc, sc.params) == pytest.approx(timestep.dem_dt(bare, bare.params))


def test_kinematic_structure_takes_the_fluid_only_step_coefficients():
    """A structure whose discs are all kinematic never reads the fluid force held over the
    sub-steps, so option fsi alone does not shorten the step: the plate with every disc
    held takes SPH_CFL and the 0.4 h skin; one free disc brings back FSI_SPH_CFL and
    0.25 h."""
    sc = coarse_plate()
    held = dataclasses.replace(sc, solid=dataclasses.replace(
        sc.solid, fixed=np.ones(sc.solid.n, bool)))
    assert sc.fsi_coupled and not held.fsi_coupled
    h = float(sc.fluid.h.min())
    acoustic = lambda cfl: cfl * h / (float(sc.params.sph.c0) + sc.v_max)
    assert timestep.sph_dt(held, held.params) == pytest.approx(acoustic(timestep.SPH_CFL))
    h_max = max(float(np.max(sc.fluid.h)), float(np.max(sc.boundary.h)))
    assert Physics.for_scene(held).neighbors.skin == pytest.approx(0.4 * h_max)
    assert Physics.for_scene(sc).neighbors.skin == pytest.approx(0.25 * h_max)
    one_free = np.ones(sc.solid.n, bool)
    one_free[np.nonzero(np.asarray(sc.solid.structure if sc.solid.structure is not None
                                   else np.ones(sc.solid.n, bool)))[0][0]] = False
    again = dataclasses.replace(sc, solid=dataclasses.replace(sc.solid, fixed=one_free))
    assert again.fsi_coupled
    assert timestep.sph_dt(again, again.params) == pytest.approx(acoustic(timestep.FSI_SPH_CFL))


def test_wall_range_from_the_scene_and_its_time_step_bound():
    """r0 = 0.8 min(√(m_b/ρ0), Δp); the derived step respects Δt ≤ r0/(c0 √β). The tank's
    boundary spacing is 5 mm fitted to its 0.584 m: 0.584/117 m."""
    sc = cases.build("dam_break", dx=0.01, dx_boundary=0.005)
    np.testing.assert_allclose(sc.wall_range(), 0.8 * 0.584 / 117, rtol=1e-12)
    assert Physics.for_scene(sc).wall_range == sc.wall_range()
    sc = cases.build("dam_break", dx=0.01)
    np.testing.assert_allclose(sc.wall_range(), 0.8 * 0.01, rtol=1e-12)
    sp = sc.params.sph
    strong = sc.params.replace(sph=sp.replace(wall_beta=1.0))     # binding for β = 1
    bound = sc.wall_range() / float(sp.c0)
    assert timestep.sph_dt(sc, strong) <= bound * (1 + 1e-12)
    np.testing.assert_allclose(timestep.sph_dt(sc, strong), bound, rtol=1e-12)


def test_substeps_are_derived_from_the_two_bounds_and_checked():
    sc = coarse_plate()
    phys, params = setup(sc)
    sph_b = timestep.sph_dt(sc, sc.params)
    dem_b = timestep.dem_dt(sc, sc.params)
    assert params.dt == pytest.approx(sph_b)
    assert phys.dem_substeps == int(np.ceil(sph_b / dem_b)) > 1
    assert params.dt / phys.dem_substeps <= dem_b
    phys1, p1 = setup(sc, dem_substeps=1)              # single rate: the smaller bound
    assert phys1.dem_substeps == 1 and p1.dt == pytest.approx(dem_b)
    with pytest.raises(ParameterError, match="dem_substeps = 2"):
        setup(sc, dt=sph_b, dem_substeps=2)
    with pytest.raises(ParameterError, match="dem_substeps"):
        setup(sc, dem_substeps=0)


def test_a_bad_coupled_step_is_told_the_range_it_may_use():
    """With the sub-steps chosen from dt, a step that is not positive is told the SPH bound
    (the DEM sub-step bound does not limit it), and that bound is accepted; with the
    sub-steps fixed, the DEM bound × their count."""
    sc = coarse_plate()
    sph_b = timestep.sph_dt(sc, sc.params)
    with pytest.raises(ParameterError, match=rf"allowed \(0, {sph_b:.4g}\] s \(the DEM sub-steps"):
        setup(sc, dt=-1.0)
    assert setup(sc, dt=sph_b)[1].dt == pytest.approx(sph_b)
    dem_b = timestep.dem_dt(sc, sc.params)
    with pytest.raises(ParameterError, match=rf"allowed \(0, {2 * dem_b:.4g}\] s$"):
        setup(sc, dt=0.0, dem_substeps=2)
