"""Stepper and rollouts: stability of the leapfrog, time-step bound, observations."""
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from fpsi_jax import integrate, scenes
from fpsi_jax.params import ParameterError
from fpsi_jax.simulate import setup


def _kick_both_half_steps(w_dt, n=2000):
    """The rejected scheme: ρ and v both half-kicked with stored rates (see integrate.py)."""
    u, r = 1.0, 0.0
    a, d = -r, u
    for _ in range(n):
        uh, rh = u + w_dt / 2 * a, r + w_dt / 2 * d
        a, d = -rh, uh
        u, r = uh + w_dt / 2 * a, rh + w_dt / 2 * d
    return np.hypot(u, r)


def _staggered(w_dt, n=2000):
    """The scheme of integrate.step: v half kick, ρ drift with v½, v half kick."""
    u, r = 1.0, 0.0
    a = -r
    for _ in range(n):
        uh = u + w_dt / 2 * a
        r = r + w_dt * uh
        a = -r
        u = uh + w_dt / 2 * a
    return np.hypot(u, r)


@pytest.mark.parametrize("w_dt", [0.1, 0.5, 1.0, 1.5])
def test_density_update_is_stable_for_acoustic_oscillator(w_dt):
    assert _staggered(w_dt) < 1.0 / np.sqrt(1 - (w_dt / 2) ** 2) + 1e-9  # leapfrog ellipse
    grown = _kick_both_half_steps(w_dt)
    assert not np.isfinite(grown) or grown > 10.0   # why the density is not half-kicked


def test_closed_box_without_dissipation_stays_bounded():
    """Acoustic sloshing in a closed tank, all dissipation off, at the derived dt."""
    sc = scenes.build("hydrostatic_tank", dx=0.01, depth=0.1, width=0.1, mu=0.0,
                      delta_sph=False, artificial_viscosity=False)
    sc.params = sc.params.replace(gravity=(0.0, 0.0))
    sc.fluid.rho = 1000.0 * (1.0 + 0.005 * np.sin(np.pi * sc.fluid.x[:, 0] / 0.1))
    phys, params = setup(sc, xsph=False)
    p = params.as_arrays(jnp.float32)
    st = integrate.init_state(sc, phys, p)
    run = jax.jit(integrate.rollout, static_argnums=(0, 3, 4))
    speeds = []
    for _ in range(4):
        st, _ = run(phys, st, p, 250, None)
        speeds.append(float(jnp.max(jnp.linalg.norm(st.fluid.v, axis=1))))
    assert not bool(st.status.bad)
    assert np.all(np.isfinite(speeds))
    # a bounded oscillation: the velocity does not grow from chunk to chunk
    assert speeds[-1] < 3.0 * max(speeds[0], 1e-3)


def test_user_dt_above_bound_is_refused_with_the_bound(tiny_tank):
    bound = integrate.stable_dt(tiny_tank)
    with pytest.raises(ParameterError, match=f"{bound:.4g}"):
        setup(tiny_tank, dt=2 * bound)
    phys, params = setup(tiny_tank, dt=0.5 * bound)
    assert params.dt == pytest.approx(0.5 * bound)


def test_stable_dt_is_the_minimum_of_the_bounds(tiny_tank):
    sp = tiny_tank.params.sph
    h = float(tiny_tank.fluid.h.min())
    acoustic = integrate.SPH_CFL * h / (sp.c0 + tiny_tank.v_max)
    viscous = 0.125 * h * h / (sp.mu / sp.rho0)
    force = 0.25 * np.sqrt(h / 9.81)
    assert integrate.stable_dt(tiny_tank) == pytest.approx(min(acoustic, viscous, force))


def test_rollout_records_observations(tiny_tank):
    phys, params = setup(tiny_tank)
    p = params.as_arrays(jnp.float32)
    st = integrate.init_state(tiny_tank, phys, p)
    final, obs = integrate.rollout(phys, st, p, 7, lambda s: jnp.mean(s.fluid.x[:, 1]))
    assert obs.shape == (7,)
    assert int(final.step) == 7
    assert float(final.t) == pytest.approx(7 * float(p.dt), rel=1e-6)


def test_fluid_coupled_structure_keeps_physics_md_step_coefficients():
    """Issue 7: fluid-only and DEM-only scenes take SPH_CFL and DEM_DT_FACTOR; a scene with
    option fsi keeps physics.md's 0.25 h/(c0+|v|) and 0.2 √(m/k) (accuracy of the coupling),
    and the same scene without the coupling takes the larger step."""
    import dataclasses
    sc = scenes.build("hydrostatic_plate", dx=0.0035, d=0.0025, dx_boundary=0.0025)
    assert sc.options.get("fsi") is not None
    bare = dataclasses.replace(sc, options={k: v for k, v in sc.options.items() if k != "fsi"})
    h = float(sc.fluid.h.min())
    acoustic = lambda cfl: cfl * h / (float(sc.params.sph.c0) + sc.v_max)
    assert integrate.FSI_SPH_CFL == 0.25 and integrate.FSI_DEM_DT_FACTOR == 0.2
    assert integrate.sph_dt(sc, sc.params) == pytest.approx(acoustic(0.25))
    assert integrate.sph_dt(bare, bare.params) == pytest.approx(acoustic(integrate.SPH_CFL))
    ratio = integrate.dem_dt(sc, sc.params) / integrate.dem_dt(bare, bare.params)
    assert ratio == pytest.approx(0.2 / integrate.DEM_DT_FACTOR)
    # the neighbour skin follows the step: 0.4 h at the larger step, 0.25 h with fsi
    from fpsi_jax.scene import Physics
    skin = lambda s: Physics.for_scene(s).neighbors.skin / float(np.max(s.fluid.h))
    assert skin(sc) == pytest.approx(0.25) and skin(bare) == pytest.approx(0.4)
