"""The step and the rollouts (fpsi_jax.solver.forward): stability of the leapfrog for the
acoustic mode, bounded sloshing, observations, conservation (momentum of a free fluid blob,
momentum and angular momentum of a frictional disc cluster, a spinning bonded pair), the
gradients through rollouts, and that the compiled step holds exactly the mechanisms of the
scene's phases and options.

The float64 fixture (conftest) is module-scoped: once a test turns it on, it stays on to
the end of the module. The tests that run in JAX's default float32 therefore come first;
those marked ``x64`` follow.
"""
import dataclasses
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from fpsi_jax import cases
from fpsi_jax.build import disc_block
from fpsi_jax.model.config import Physics
from fpsi_jax.model.params import BondParams, DemParams, Params
from fpsi_jax.model.scene import BondBlock, Scene
from fpsi_jax.physics import dem, fpi, kernels
from fpsi_jax.run.driver import setup
from fpsi_jax.solver import forward, init, timestep

from ..finite_differences import fd_check
from ..small_scenes import coarse_plate, grain_scene, init_x64

x64 = pytest.mark.usefixtures("float64")


# --- leapfrog and rollouts (float32) ----------------------------------------------------
def _kick_both_half_steps(w_dt, n=2000):
    """The rejected scheme: ρ and v both half-kicked with stored rates (see solver/stages.py)."""
    u, r = 1.0, 0.0
    a, d = -r, u
    for _ in range(n):
        uh, rh = u + w_dt / 2 * a, r + w_dt / 2 * d
        a, d = -rh, uh
        u, r = uh + w_dt / 2 * a, rh + w_dt / 2 * d
    return np.hypot(u, r)


def _staggered(w_dt, n=2000):
    """The scheme of forward.step: v half kick, ρ drift with v½, v half kick."""
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
    sc = cases.build("hydrostatic_tank", dx=0.01, depth=0.1, width=0.1, mu=0.0,
                     delta_sph=False, artificial_viscosity=False)
    sc.params = sc.params.replace(gravity=(0.0, 0.0))
    sc.fluid.rho = 1000.0 * (1.0 + 0.005 * np.sin(np.pi * sc.fluid.x[:, 0] / 0.1))
    phys, params = setup(sc, xsph=False)
    p = params.as_arrays(jnp.float32)
    st = init.init_state(sc, phys, p)
    run = jax.jit(forward.rollout, static_argnums=(0, 3, 4))
    speeds = []
    for _ in range(4):
        st, _ = run(phys, st, p, 250, None)
        speeds.append(float(jnp.max(jnp.linalg.norm(st.fluid.v, axis=1))))
    assert not bool(st.status.bad)
    assert np.all(np.isfinite(speeds))
    # a bounded oscillation: the velocity does not grow from chunk to chunk
    assert speeds[-1] < 3.0 * max(speeds[0], 1e-3)


def test_rollout_records_observations(tiny_tank):
    phys, params = setup(tiny_tank)
    p = params.as_arrays(jnp.float32)
    st = init.init_state(tiny_tank, phys, p)
    final, obs = forward.rollout(phys, st, p, 7, lambda s: jnp.mean(s.fluid.x[:, 1]))
    assert obs.shape == (7,)
    assert int(final.step) == 7
    assert float(final.t) == pytest.approx(7 * float(p.dt), rel=1e-6)


# --- the compiled step holds only what the scene has (float32) ---------------------------
def test_switched_off_terms_are_not_compiled(tiny_tank, step_hlo):
    # the named scopes of the ops, not the raw text: its locations also hold the traceback
    # of the call that first traced the step (e.g. ".../tests/solver/test_forward.py")
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


# --- SPH: momentum of a free blob, gradients (float64) ------------------------------------
_rollout = jax.jit(forward.rollout, static_argnums=(0, 3))


@x64
def test_rollout_conserves_momentum_of_free_blob():
    scene = cases.build("hydrostatic_tank", dx=0.01, depth=0.1, width=0.1)
    scene.params = scene.params.replace(gravity=(0.0, 0.0),
                                        sph=scene.params.sph.replace(alpha=0.2))
    rng = np.random.default_rng(1)
    scene.fluid.v = rng.normal(0.0, 0.2, scene.fluid.x.shape) + np.array([0.15, -0.1])
    scene.boundary = None
    # room for the clustering that random velocities cause: an overflowing list drops
    # pairs (the host driver would redo the chunk), which would break the balance
    phys = Physics.for_scene(scene, x64=True, artificial_viscosity=True, xsph=True,
                             anticlump=True, delta_sph=True, capacity_multiplier=2.0)
    assert phys.n_boundary == 0 and phys.n_fluid == 100
    params = scene.params.replace(dt=timestep.stable_dt(scene)).as_arrays(jnp.float64)
    state = init.init_state(scene, phys, params)
    m = np.asarray(state.fluid.mass)
    p0 = m @ np.asarray(state.fluid.v)
    x0 = np.asarray(state.fluid.x)
    state, _ = _rollout(phys, state, params, 200)
    assert not bool(state.status.bad) and not bool(state.status.overflow)
    v = np.asarray(state.fluid.v)
    assert np.max(np.abs(np.asarray(state.fluid.x) - x0)) > 0.2 * scene.fluid.h[0]  # it moved
    assert np.max(np.abs(v - scene.fluid.v)) > 1e-3                                  # and interacted
    p1 = m @ v
    np.testing.assert_allclose(p1, p0, rtol=0, atol=1e-12 * float(m @ np.abs(v).sum(1)))


@x64
def test_gradient_through_rollout_wrt_mu_c0_alpha():
    scene = cases.build("hydrostatic_tank", dx=0.02, depth=0.06, width=0.06)
    rng = np.random.default_rng(2)
    scene.fluid.v = rng.normal(0.0, 0.3, scene.fluid.x.shape)
    phys = Physics.for_scene(scene, x64=True, artificial_viscosity=True)
    base = scene.params.replace(dt=timestep.stable_dt(scene)).as_arrays(jnp.float64)
    state0 = init.init_state(scene, phys, base)
    m = state0.fluid.mass

    def loss(theta):
        mu, c0, alpha = theta
        params = base.replace(sph=base.sph.replace(mu=mu, c0=c0, alpha=alpha))
        s0 = init.refresh_rates(phys, state0, params)
        s, _ = forward.rollout(phys, s0, params, 20)
        return 0.5 * jnp.sum(m * jnp.sum(s.fluid.v ** 2, axis=1))

    fd_check(loss, [0.01, float(base.sph.c0), 0.1])


# --- DEM: conservation in a closed cluster (float64) -------------------------------------
R = 0.01                                     # disc radius of the DEM scenes


def A(*v):
    """A(1, 2) → array([1., 2.]); A([[..]]) → that array (float64)."""
    return jnp.asarray(np.array(v[0] if len(v) == 1 else v, float))


def _cluster_scene(seed=0):
    rng = np.random.default_rng(seed)
    X, Y = np.meshgrid(np.arange(5), np.arange(4), indexing="ij")
    x = 0.05 + 1.97 * R * np.stack([X.ravel(), Y.ravel()], 1) + rng.normal(0, 0.02 * R, (20, 2))
    radius = R * rng.uniform(0.9, 1.1, 20)
    v = rng.normal(0, 0.3, (20, 2))
    blk = disc_block(x, radius, 2700.0, v=v)
    blk.omega[:] = rng.normal(0, 20.0, 20)
    return Scene(name="cluster", params=Params(
        gravity=(0.0, 0.0), dt=2e-5, dem=DemParams(kn=1e5, ks=5e4, mu=0.3, beta_n=0.1,
                                                    beta_s=0.1)),
        domain_lo=(0.0, 0.0), domain_hi=(0.2, 0.2), v_max=1.0, solid=blk).validate()


def _momenta(s):
    m = s.solid.mass
    p = jnp.sum(m[:, None] * s.solid.v, axis=0)
    x, v = s.solid.x, s.solid.v
    L = jnp.sum(m * (x[:, 0] * v[:, 1] - x[:, 1] * v[:, 0]) + s.solid.inertia * s.solid.omega)
    n_contacts = jnp.sum(s.solid.shear != 0)
    return p, L, n_contacts


@pytest.fixture(scope="module")
def cluster_run(float64):
    sc = _cluster_scene()
    phys = Physics.for_scene(sc, x64=True, dem_skin=0.1, capacity_multiplier=2.0)
    p = sc.params.as_arrays(jnp.float64)
    st = init.init_state(sc, phys, p)
    end, obs = jax.jit(forward.rollout, static_argnums=(0, 3, 4))(phys, st, p, 300, _momenta)
    return sc, phys, p, st, end, [np.asarray(o) for o in obs]


@x64
def test_momentum_and_angular_momentum_conserved(cluster_run):
    sc, phys, p, st, end, (P, L, nc) = cluster_run
    assert not bool(end.status.overflow) and not bool(end.status.bad)
    assert nc.max() >= 10                      # many frictional contacts
    assert int(end.status.dem_rebuilds) >= 1
    m = np.asarray(st.solid.mass)
    scale = float(np.sum(m * np.linalg.norm(np.asarray(st.solid.v), axis=1)))
    P0 = (m[:, None] * np.asarray(st.solid.v)).sum(0)
    np.testing.assert_allclose(P, np.broadcast_to(P0, P.shape), rtol=0, atol=1e-13 * scale)
    # contacts also conserve angular momentum: ℓ_A + ℓ_B = d, so Σ x × F + Σ τ = 0
    x0, v0 = np.asarray(st.solid.x), np.asarray(st.solid.v)
    L0 = float(np.sum(m * (x0[:, 0] * v0[:, 1] - x0[:, 1] * v0[:, 0])
                      + np.asarray(st.solid.inertia * st.solid.omega)))
    Lscale = float(np.sum(m * np.linalg.norm(x0, axis=1) * np.linalg.norm(v0, axis=1)))
    np.testing.assert_allclose(L, L0, rtol=0, atol=1e-13 * Lscale)
    # the run did something: kinetic energy was lost to friction/dashpots
    ke = lambda s: float(dem.kinetic_energy(s.solid.v, s.solid.omega, s.solid.mass,
                                            s.solid.inertia))
    assert ke(end) < 0.99 * ke(st)


@x64
def test_newton_third_law_per_pair(cluster_run):
    """Every touching pair of the evolved cluster, alone: equal and opposite forces, torques
    −F_s ℓ on both, and the same history from both sides."""
    sc, phys, p, st, end, _ = cluster_run
    s = end.solid
    idx = np.asarray(end.solid_nbrs.idx)
    hist = np.asarray(s.shear)
    n = idx.shape[0]
    x = np.asarray(s.x)
    rad = np.asarray(s.radius)
    pairs = [(i, j, k) for i in range(n) for k, j in enumerate(idx[i])
             if j < n and i < j and np.linalg.norm(x[i] - x[j]) < rad[i] + rad[j]]
    assert len(pairs) >= 5
    pick = lambda a, i, j: jnp.stack([a[i], a[j]])
    contacts = jax.jit(dem.disc_contacts)
    for i, j, k in pairs:
        kj = int(np.argmax(idx[j] == i))
        assert hist[i, k] == pytest.approx(hist[j, kj], rel=1e-12, abs=1e-12)
        f, tq, h, delta = contacts(
            p.dem, pick(s.x, i, j), pick(s.v, i, j), pick(s.omega, i, j),
            pick(s.radius, i, j), pick(s.mass, i, j), pick(s.fixed, i, j),
            jnp.asarray([[1], [0]]), A([hist[i, k]], [hist[j, kj]]), p.dt)
        f, tq, h = np.asarray(f), np.asarray(tq), np.asarray(h)
        fscale = np.abs(f).max()
        assert fscale > 0
        np.testing.assert_allclose(f[0], -f[1], rtol=0, atol=1e-13 * fscale)
        dlt = float(delta[0, 0])
        fs = h[0, 0]          # total F_s = −(force on A)·t
        nrm = (x[j] - x[i]) / np.linalg.norm(x[j] - x[i])
        t = np.array([-nrm[1], nrm[0]])
        fs_tot = -float(f[0] @ t)
        np.testing.assert_allclose(tq, [-fs_tot * (rad[i] - dlt / 2),
                                        -fs_tot * (rad[j] - dlt / 2)],
                                   rtol=1e-10, atol=1e-14 * fscale * R)
        assert abs(fs) <= 0.3 * 1e5 * dlt * (1 + 1e-12)


@x64
def test_viscous_damping_decay_and_time_step_bound():
    """A free disc coasting with damping c follows the kick–drift–kick recursion with the
    damping evaluated at v½ exactly, and exp(−c t) to O(c²Δt²) per step; the derived DEM
    step respects c Δt ≤ 0.5."""
    blk = disc_block(np.array([[0.05, 0.05]]), R, 2700.0, v=np.array([[0.01, 0.0]]))
    c = 50.0
    sc = Scene(name="coast", params=Params(gravity=(0.0, 0.0), dt=1e-4,
                                           dem=DemParams(damping=c)),
               domain_lo=(0, 0), domain_hi=(0.1, 0.1), v_max=1.0, solid=blk).validate()
    assert timestep.dem_dt(sc, sc.params.replace(dem=DemParams(damping=1e5))) <= 0.5 / 1e5
    phys = Physics.for_scene(sc, x64=True)
    p = sc.params.as_arrays(jnp.float64)
    st = init.init_state(sc, phys, p)
    st, _ = forward.rollout(phys, st, p, 200, None)
    v, a, dt = 0.01, -c * 0.01, 1e-4
    for _ in range(200):
        vh = v + 0.5 * dt * a
        a = -c * vh
        v = vh + 0.5 * dt * a
    np.testing.assert_allclose(float(st.solid.v[0, 0]), v, rtol=1e-12)
    np.testing.assert_allclose(v, 0.01 * math.exp(-c * 0.02), rtol=200 * (c * dt) ** 2 / 2)


# --- bonds over rollouts (float64) -------------------------------------------------------
KN, KS = 1.0e9, 4.0e8                        # bond stiffnesses k̄_n, k̄_s
R_BOND = 0.005


@x64
def test_spinning_bonded_pair_keeps_small_loads_past_half_a_turn():
    """Two bonded discs spinning rigidly at Ω = 600 rad/s about their centre for 0.6 turn.
    Before θ = π the loads stay below ~800 N (centrifugal stretch and its oscillation)."""
    W = 600.0
    c = np.array([0.05, 0.05])
    x = np.array([c - [R_BOND, 0.0], c + [R_BOND, 0.0]])
    blk = disc_block(x, R_BOND, 2700.0, v=W * np.array([[0.0, -R_BOND], [0.0, R_BOND]]))
    blk.omega[:] = W
    sc = Scene(name="spin", params=Params(
        gravity=(0.0, 0.0), dt=2e-5, dem=DemParams(kn=1.0e7, ks=0.0, mu=0.0),
        bond=BondParams(kn=KN, ks=KS)),
        domain_lo=(0.0, 0.0), domain_hi=(0.1, 0.1), v_max=10.0, solid=blk,
        bonds=BondBlock(i=np.array([0], np.int32), j=np.array([1], np.int32))).validate()
    phys = Physics.for_scene(sc, x64=True)
    p = sc.params.as_arrays(jnp.float64)
    st = init.init_state(sc, phys, p)
    n = int(math.ceil(1.2 * math.pi / (W * 2e-5)))
    end, (fn, fs, th) = jax.jit(forward.rollout, static_argnums=(0, 3, 4))(
        phys, st, p, n, lambda s: (s.bonds.fn[0], s.bonds.fs[0], s.solid.theta[0]))
    fn, fs, th = (np.asarray(a) for a in (fn, fs, th))
    assert th.max() > 3.0
    first = np.arange(n) < np.argmax(th > 3.0)               # before half a turn: fine
    assert first.sum() > 200
    assert np.abs(fn[first]).max() < 2000.0 and np.abs(fs[first]).max() < 500.0
    assert th.max() > math.pi                                # it did pass half a turn
    assert np.abs(fn).max() < 2000.0 and np.abs(fs).max() < 500.0


def _bar_scene():
    """Three discs (R = 0.45 d, so no contacts) bonded in a row, disc 0 clamped, an oblique
    load on the tip, no damping."""
    d = 0.01
    x = np.stack([0.02 + d * np.arange(3), np.full(3, 0.05)], axis=1)
    f_ext = np.zeros((3, 2))
    f_ext[2] = [30.0, -20.0]
    blk = disc_block(x, 0.45 * d, 2700.0, fixed=np.array([True, False, False]), f_ext=f_ext)
    return Scene(name="bar", params=Params(
        gravity=(0.0, 0.0), dt=1e-6, dem=DemParams(kn=1.0e6, ks=0.0, mu=0.0),
        bond=BondParams(kn=KN, ks=KS)),
        domain_lo=(0.0, 0.0), domain_hi=(0.1, 0.1), v_max=1.0, solid=blk,
        bonds=BondBlock(i=np.array([0, 1], np.int32), j=np.array([1, 2], np.int32))).validate()


@x64
def test_grad_of_rollout_tip_displacement_wrt_bond_kn():
    sc = _bar_scene()
    phys = Physics.for_scene(sc, x64=True)
    p = sc.params.replace(dt=0.25 * timestep.dem_dt(sc, sc.params)).as_arrays(jnp.float64)
    st = init.init_state(sc, phys, p)
    y0 = float(st.solid.x[2, 1])

    @jax.jit
    def tip(kn):
        q = p.replace(bond=p.bond.replace(kn=kn))
        end, _ = forward.rollout(phys, st, q, 150)
        return end.solid.x[2, 1] - y0

    kn = jnp.asarray(KN)
    g = float(jax.grad(tip)(kn))
    h = 1e-4 * KN
    fd = (float(tip(kn + h)) - float(tip(kn - h))) / (2 * h)
    assert abs(float(tip(kn))) > 1e-7                       # the tip moved
    assert g != 0.0
    assert g == pytest.approx(fd, rel=1e-5)


# --- grains in the fluid over rollouts (float64) -----------------------------------------
@x64
def test_grain_forces_and_their_reaction_sum_to_zero():
    """Σ_p F_p + Σ_f m_f a_f(reaction) = 0 to round-off in the stepped state (W47–W48)."""
    scene = grain_scene(rho_grain=2500.0)
    phys, p, st = init_x64(scene)
    st = jax.jit(lambda s: forward.rollout(phys, s, p, 30)[0])(st)
    f = st.fluid
    n_sph = st.nbrs.idx.shape[0] - 1
    rows = fpi.grain_rows(kernels.get(phys.kernel), f.x, f.h, f.mass / (st.fpi.eps * f.rho),
                          st.solid.x[st.fpi.idx], st.nbrs.idx[n_sph:], phys.n_fluid)
    reaction = f.mass[:, None] * fpi.reaction_acceleration(rows, st.fpi.force, f.mass)
    total = np.asarray(reaction.sum(0) + st.fpi.force.sum(0))
    assert float(jnp.abs(st.fpi.force).max()) > 1e-3
    np.testing.assert_allclose(total, 0.0, atol=1e-14 * float(jnp.abs(st.fpi.force).sum()))


@x64
def test_grain_velocity_gradient_wrt_viscosity_and_added_mass_matches_finite_differences():
    """d v_p(t) / d μ and d v_p(t) / d C_a through 60 coupled steps (SPH, DEM, drag,
    voidage, and the added mass: the grain's inertia, the held m_a Du/Dt and the
    reaction) vs central differences; one program for both (its compilation is most of
    the test's time)."""
    scene = grain_scene(rho_grain=2500.0, added_mass=True)
    phys, p, st = init_x64(scene)

    @jax.jit
    def vy(mu, c_a):
        q = p.replace(sph=p.sph.replace(mu=mu), fpi=p.fpi.replace(added_mass=c_a))
        end, _ = forward.rollout(phys, st, q, 60)
        return end.solid.v[0, 1]

    mu, c_a = jnp.asarray(0.01), jnp.asarray(1.0)
    g_mu, g_ca = (float(g) for g in jax.grad(vy, argnums=(0, 1))(mu, c_a))
    h = 1e-5
    fd_mu = (float(vy(mu + h, c_a)) - float(vy(mu - h, c_a))) / (2 * h)
    fd_ca = (float(vy(mu, c_a + h)) - float(vy(mu, c_a - h))) / (2 * h)
    assert g_mu != 0.0
    assert g_mu == pytest.approx(fd_mu, rel=1e-4)
    assert g_ca > 0.0                   # more inertia: the grain falls slower
    assert g_ca == pytest.approx(fd_ca, rel=1e-5)


def test_a_packed_bed_with_added_mass_stays_stable():
    """The added mass in a packed bed under water (shared pressure): its light pore
    particles serve several grains each, and without fpi.added_mass_limit the explicit
    exchange grew from step to step (the two-phase dam break's bed blew up at step 28).
    200 steps: the run stays healthy and the grains' added mass is held below C_a ρ_f V_p."""
    scene = cases.build("grain_bed", t_end=0.01)
    phys, params = setup(scene, fpi_pressure="shared", added_mass=True)
    p = params.as_arrays(jnp.float32)
    st = init.init_state(scene, phys, p)
    end, _ = jax.jit(lambda s: forward.rollout(phys, s, p, 200))(st)
    assert not bool(end.status.bad) and not bool(end.status.overflow)
    r = np.asarray(end.solid.radius)[np.asarray(end.fpi.idx)]
    ratio = np.asarray(end.fpi.m_a) / (1000.0 * np.pi * r * r)
    assert 0.0 < ratio.min() and ratio.max() < 0.5
    assert np.abs(np.asarray(end.fluid.v)).max() < 0.1


@x64
def test_grain_velocity_gradient_with_shared_pressure_matches_finite_differences():
    """The same through the 'shared' pressure (the cells' pressure force split between
    fluid and grain), with respect to the sound speed c0, which the shared part carries."""
    scene = grain_scene(rho_grain=2500.0)
    phys, p, st = init_x64(scene, fpi_pressure="shared")

    @jax.jit
    def vy(c0):
        end, _ = forward.rollout(phys, st, p.replace(sph=p.sph.replace(c0=c0)), 60)
        return end.solid.v[0, 1]

    c0 = p.sph.c0
    g = float(jax.grad(vy)(c0))
    h = 1e-4 * float(c0)
    fd = (float(vy(c0 + h)) - float(vy(c0 - h))) / (2 * h)
    assert g != 0.0
    assert g == pytest.approx(fd, rel=1e-4)


# --- the compiled step holds only what the scene has (float64) ---------------------------
@x64
def test_dem_only_scene_compiles_no_sph(step_hlo):
    _, scopes, files = step_hlo(cases.build("collision"), jnp.float64)
    for want in ("dem.contacts", "dem.local_damping", "step.solid_kick_drift",
                 "neighbors.dem_update"):
        assert want in scopes, want
    assert not [s for s in scopes if s.startswith(("sph.", "boundary."))]
    for absent in ("step.kick_drift", "neighbors.update", "dem.walls", "bonds"):
        assert absent not in scopes, absent
    assert "dem.py" in files and "sph.py" not in files and "kernels.py" not in files
    _, scopes_w, files_w = step_hlo(cases.build("rolling"), jnp.float64)
    assert "dem.walls" in scopes_w and "sph.py" not in files_w


@x64
def test_fluid_only_scene_compiles_no_dem(tiny_tank, step_hlo):
    _, scopes, files = step_hlo(tiny_tank)
    assert "sph.continuity" in scopes and "sph.pressure" in scopes
    assert not [s for s in scopes if s.startswith("dem.")]
    for absent in ("bonds", "step.solid_kick_drift", "neighbors.dem_update"):
        assert absent not in scopes, absent
    assert "sph.py" in files and "dem.py" not in files and "bonds.py" not in files


@x64
def test_bonded_scene_compiles_bonds(step_hlo):
    _, scopes, files = step_hlo(cases.build("bond_tension", n_discs=3), jnp.float64)
    assert {"bonds", "dem.contacts"} <= scopes
    assert "bonds.py" in files and "sph.py" not in files
    assert not [s for s in scopes if s.startswith("sph.")]


@x64
def test_coupled_step_compiles_the_coupling_and_fluid_only_does_not(step_hlo, tiny_tank):
    _, scopes, _ = step_hlo(coarse_plate(), jnp.float64, x64=True)
    assert {"fsi.extrapolated", "fsi.reaction", "step.dem_substeps"} <= scopes
    _, scopes, _ = step_hlo(tiny_tank)
    assert not any(s.startswith("fsi.") for s in scopes)


@x64
def test_multirate_step_hlo_shows_the_dem_substep_mechanisms(step_hlo):
    """In a coupled scene the DEM forces sit inside the sub-step loop, whose op locations
    are relative ("bonds/..."): the HLO fixture must see them, or an absence test on a
    coupled scene would pass whether the mechanism is compiled or not."""
    _, scopes, _ = step_hlo(coarse_plate())
    assert {"dem.contacts", "bonds", "step.dem_substeps", "fsi.extrapolated"} <= scopes
    assert "dem.walls" not in scopes                 # the plate has no DEM walls


@x64
def test_fpi_is_compiled_only_with_grains(step_hlo, tiny_tank):
    _, scopes, _ = step_hlo(grain_scene(), jnp.float64)
    assert {"fpi.voidage", "fpi.drag", "fpi.buoyancy", "fpi.reaction", "fpi.lubrication"} <= scopes
    _, scopes, _ = step_hlo(grain_scene(), jnp.float64, lubrication=False)
    assert "fpi.lubrication" not in scopes
    _, scopes, files = step_hlo(tiny_tank)
    assert not [s for s in scopes if s.startswith("fpi")] and "fpi.py" not in files


@pytest.mark.parametrize("mu_roll", [0.02, 0.05])
def test_rolling_resistance_decelerates_a_rolling_disc_as_the_rigid_body_does(mu_roll):
    """A disc rolling without slip on the floor (v0 = 1 m/s, ω = −v0/R) under rolling
    resistance μ_r: the couple μ_r R m g against the spin and the friction that keeps it
    rolling give dv/dt = −μ_r g/(1 + J/(mR²)) = −(2/3) μ_r g (J = ½mR²); the slope of v over
    0.02–0.1 s within 1 %, and no slip (v = −ω ℓ to 10⁻⁴)."""
    sc = cases.build("rolling", t_end=0.1, speed=1.0)
    r = float(sc.solid.radius[0])
    sc.solid.omega[:] = -1.0 / r
    p = sc.params
    sc = dataclasses.replace(sc, params=p.replace(dem=p.dem.replace(mu_roll=mu_roll)))
    phys, params = setup(sc)
    st = init.init_state(sc, phys, params.as_arrays(jnp.float64))
    n = int(round(0.1 / float(params.dt)))
    _, (v, w) = jax.jit(lambda s: forward.rollout(
        phys, s, params.as_arrays(jnp.float64), n,
        lambda q: (q.solid.v[0, 0], q.solid.omega[0])))(st)
    t = (np.arange(n) + 1) * float(params.dt)
    keep = t > 0.02
    slope = np.polyfit(t[keep], np.asarray(v)[keep], 1)[0]
    assert slope == pytest.approx(-2.0 / 3.0 * mu_roll * 9.81, rel=0.01)
    # rolling about the contact point, ℓ = R − δ/2 from the centre (δ = m g/k_n)
    lever = r - 0.5 * float(sc.solid.mass[0]) * 9.81 / float(p.dem.kn)
    np.testing.assert_allclose(-np.asarray(w)[keep] * lever, np.asarray(v)[keep], rtol=1e-4)
