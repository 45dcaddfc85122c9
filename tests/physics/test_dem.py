"""Unit tests of the DEM contacts (fpsi_jax.dem, physics.md §DEM contacts) and of the DEM
half of the stepper (integrate.solid_update / _solid_step).

Every contact term is compared with a number computed here by hand for two discs (or one
disc and one wall) placed by hand; then the contact history across neighbour-list rebuilds,
conservation of momentum and angular momentum in a closed cluster with friction, Newton's
third law per pair, and that a DEM-only scene compiles no SPH (and a fluid-only none DEM).
"""
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from fpsi_jax import dem, integrate, scenes
from fpsi_jax.params import DemParams, Params
from fpsi_jax.scene import Physics, Scene, WallBlock
from fpsi_jax.scenes._solids import disc_block

pytestmark = pytest.mark.usefixtures("float64")  # conftest: x64 for this module only

RTOL = 1e-12


def A(*v):
    """A(1, 2) → array([1., 2.]); A([[..]]) → that array (float64)."""
    return jnp.asarray(np.array(v[0] if len(v) == 1 else v, float))


# --- two discs placed by hand ------------------------------------------------------------
RA, RB = 0.010, 0.015
D = 0.024                                    # centre distance: overlap δ = 0.001
DELTA = RA + RB - D
LA, LB = RA - DELTA / 2, RB - DELTA / 2      # levers 0.0095, 0.0145
MA, MB = 0.8, 2.4


def two_discs(angle=0.0, va=(0, 0), vb=(0, 0), wa=0.0, wb=0.0, shear=0.0, d=D,
              fixed=(False, False), dp=None, dt=1e-4):
    """disc_contacts for A = 0 at (0.1, 0.2) and B = 1 at distance d along ``angle``."""
    n = np.array([math.cos(angle), math.sin(angle)])
    xa = np.array([0.1, 0.2])
    x = A(xa, xa + d * n)
    dp = dp or DemParams(kn=1.0e5, ks=5.0e4, mu=0.3)
    out = dem.disc_contacts(dp, x, A(va, vb), A(wa, wb), A(RA, RB), A(MA, MB),
                            jnp.asarray(fixed), jnp.asarray([[1], [0]]),
                            A([shear], [shear]), dt)
    return [np.asarray(o) for o in out], n


def test_normal_spring_force_two_discs():
    """F_n = k_n δ along the line of centres, pushing A and B apart, equal and opposite."""
    (f, tq, hist, delta), n = two_discs(angle=math.radians(30))
    assert delta[0, 0] == pytest.approx(0.001, rel=1e-9)
    fn = 1.0e5 * 0.001                                      # 100 N
    np.testing.assert_allclose(f[0], -fn * n, rtol=RTOL)    # A pushed away from B
    np.testing.assert_allclose(f[1], fn * n, rtol=RTOL)
    np.testing.assert_allclose(f[0] + f[1], 0.0, atol=1e-12)
    np.testing.assert_allclose(tq, 0.0, atol=1e-15)        # no shear, no torque
    np.testing.assert_allclose(hist, 0.0)


def test_normal_dashpot_uses_reduced_mass():
    """F_n = k_n δ + 2β √(m* k_n) δ̇, δ̇ = −(v_B − v_A)·n, m* = m_A m_B/(m_A + m_B)."""
    beta = 0.2
    dp = DemParams(kn=1.0e5, ks=0.0, mu=0.0, beta_n=beta)
    va, vb = np.array([0.3, 0.1]), np.array([-0.2, 0.05])
    (f, _, _, _), n = two_discs(angle=0.4, va=va, vb=vb, dp=dp)
    ddot = -float((vb - va) @ n)
    m = MA * MB / (MA + MB)                                 # 0.6 kg
    assert m == pytest.approx(0.6)
    fn = 1.0e5 * DELTA + 2 * beta * math.sqrt(m * 1.0e5) * ddot
    np.testing.assert_allclose(f[0], -fn * n, rtol=RTOL)
    np.testing.assert_allclose(f[1], fn * n, rtol=RTOL)
    # the dashpot really contributes (approaching discs: δ̇ > 0)
    assert ddot > 0 and fn > 1.0e5 * DELTA * 1.3


@pytest.mark.parametrize("fixed, m", [((True, False), MB), ((False, True), MA)])
def test_dashpot_mass_with_a_clamped_disc(fixed, m):
    """A clamped disc counts as infinitely heavy: the reduced mass is the other disc's."""
    beta = 0.3
    dp = DemParams(kn=2.0e5, ks=0.0, mu=0.0, beta_n=beta)
    va, vb = np.array([0.0, 0.0]), np.array([-0.4, 0.0])
    (f, _, _, _), n = two_discs(va=va, vb=vb, dp=dp, fixed=fixed)
    fn = 2.0e5 * DELTA + 2 * beta * math.sqrt(m * 2.0e5) * 0.4
    np.testing.assert_allclose(f[1], fn * n, rtol=RTOL)
    np.testing.assert_allclose(f[0], -fn * n, rtol=RTOL)
    assert float(dem.reduced_mass(2.0, 3.0, True, False)) == 3.0
    assert float(dem.reduced_mass(2.0, 3.0, False, True)) == 2.0
    assert float(dem.reduced_mass(2.0, 3.0, False, False)) == pytest.approx(1.2)


def test_shear_increment_with_rotation_and_torques():
    """F_s = F_s0 − k_s V_s Δt, V_s = (v_B − v_A)·t − ω_B ℓ_B − ω_A ℓ_A, ℓ = R − δ/2;
    force on A −F_n n − F_s t, torques −F_s ℓ_A and −F_s ℓ_B (n = x̂, t = ŷ)."""
    (f, tq, hist, _), n = two_discs(va=(0.0, 0.1), vb=(0.0, -0.2), wa=2.0, wb=-3.0,
                                    shear=2.0)
    # by hand: V_s = −0.3 − (−3)(0.0145) − 2(0.0095) = −0.2755
    vs = -0.3 + 3.0 * 0.0145 - 2.0 * 0.0095
    assert vs == pytest.approx(-0.2755)
    fs = 2.0 - 5.0e4 * vs * 1e-4                              # 2 + 1.3775 = 3.3775 N
    assert fs == pytest.approx(3.3775)
    np.testing.assert_allclose(hist[:, 0], [fs, fs], rtol=RTOL)
    np.testing.assert_allclose(f[0], [-100.0, -fs], rtol=RTOL)
    np.testing.assert_allclose(f[1], [100.0, fs], rtol=RTOL)
    np.testing.assert_allclose(tq, [-fs * 0.0095, -fs * 0.0145], rtol=RTOL)
    np.testing.assert_allclose(tq, [-0.03208625, -0.04897375], rtol=1e-9)


def test_shear_increment_rotated_frame():
    """Same pair rotated by 50°: t = (−n_y, n_x) rotates with it, the scalars do not."""
    ang = math.radians(50)
    n = np.array([math.cos(ang), math.sin(ang)])
    t = np.array([-n[1], n[0]])
    (f, tq, hist, _), _ = two_discs(angle=ang, va=0.1 * t, vb=-0.2 * t, wa=2.0, wb=-3.0,
                                    shear=2.0)
    fs = 2.0 - 5.0e4 * (-0.2755) * 1e-4
    np.testing.assert_allclose(f[0], -100.0 * n - fs * t, rtol=1e-11)
    np.testing.assert_allclose(f[1], 100.0 * n + fs * t, rtol=1e-11)
    np.testing.assert_allclose(tq, [-fs * LA, -fs * LB], rtol=1e-11)


@pytest.mark.parametrize("s0, expect", [(40.0, 30.0), (-40.0, -30.0), (20.0, 21.3775)])
def test_coulomb_cap(s0, expect):
    """|F_s| ≤ μ k_n δ = 0.3 × 100 N = 30 N; the history is capped too."""
    (f, tq, hist, _), _ = two_discs(va=(0.0, 0.1), vb=(0.0, -0.2), wa=2.0, wb=-3.0, shear=s0)
    exp = min(expect, 30.0) if expect > 0 else max(expect, -30.0)
    np.testing.assert_allclose(hist[:, 0], [exp, exp], rtol=RTOL)
    np.testing.assert_allclose(f[0, 1], -exp, rtol=RTOL)
    np.testing.assert_allclose(tq[0], -exp * LA, rtol=RTOL)


def test_coulomb_cap_ignores_normal_dashpot_and_shear_dashpot_only_while_sticking():
    """The cap is μ k_n δ (spring only); the shear dashpot −2β_s√(m k_s) V_s acts only while
    the contact sticks and is not stored in the history."""
    dp = DemParams(kn=1.0e5, ks=5.0e4, mu=0.3, beta_n=0.5, beta_s=0.2)
    m = MA * MB / (MA + MB)
    # approaching fast: the dashpot raises F_n far above k_n δ but the cap stays 30 N
    (f, _, hist, _), _ = two_discs(va=(1.0, 0.1), vb=(0.0, -0.2), wa=2.0, wb=-3.0,
                                   shear=40.0, dp=dp)
    fn = 100.0 + 2 * 0.5 * math.sqrt(m * 1.0e5) * 1.0
    np.testing.assert_allclose(f[0], [-fn, -30.0], rtol=RTOL)
    np.testing.assert_allclose(hist[:, 0], 30.0, rtol=RTOL)
    # sticking: dashpot added to the force, not to the history
    (f, tq, hist, _), _ = two_discs(va=(0.0, 0.1), vb=(0.0, -0.2), wa=2.0, wb=-3.0,
                                    shear=2.0, dp=dp)
    fs = 3.3775
    damp = -2 * 0.2 * math.sqrt(m * 5.0e4) * (-0.2755)
    np.testing.assert_allclose(hist[:, 0], fs, rtol=RTOL)
    np.testing.assert_allclose(f[0, 1], -(fs + damp), rtol=RTOL)
    np.testing.assert_allclose(tq, [-(fs + damp) * LA, -(fs + damp) * LB], rtol=RTOL)


@pytest.mark.parametrize("d", [RA + RB + 1e-9, RA + RB + 1e-3])
def test_history_resets_when_contact_opens(d):
    (f, tq, hist, delta), _ = two_discs(va=(0.0, 0.1), vb=(0.0, -0.2), wa=2.0, shear=7.0, d=d)
    assert np.all(delta <= 0)
    np.testing.assert_array_equal(hist, 0.0)
    np.testing.assert_array_equal(f, 0.0)
    np.testing.assert_array_equal(tq, 0.0)


def test_padding_slots_give_nothing():
    """Padding index n in the Dense list: no force, zero history even if fed garbage."""
    x = A([0.1, 0.1], [0.1 + D, 0.1])
    idx = jnp.asarray([[1, 2, 2], [2, 0, 2]])
    shear = A([1.0, 5.0, 6.0], [7.0, 1.0, 8.0])
    f, tq, hist, _ = dem.disc_contacts(DemParams(), x, jnp.zeros((2, 2)), jnp.zeros(2),
                                       A(RA, RB), A(MA, MB), jnp.zeros(2, bool), idx, shear,
                                       1e-4)
    hist = np.asarray(hist)
    assert hist[0, 0] == pytest.approx(1.0) and hist[1, 1] == pytest.approx(1.0)
    np.testing.assert_array_equal(hist[0, 1:], 0.0)
    np.testing.assert_array_equal(hist[1, [0, 2]], 0.0)
    np.testing.assert_allclose(np.asarray(f).sum(0), 0.0, atol=1e-12)


# --- remap_history ------------------------------------------------------------------------
def test_remap_history_permuted_slots_and_new_capacity():
    # 4 discs: padding index 4
    old_idx = jnp.asarray([[1, 2, 4], [0, 4, 4], [3, 0, 4], [2, 4, 4]])
    old = A([1.0, 2.0, 0.0], [1.0, 0.0, 0.0], [3.0, 2.0, 0.0], [3.0, 0.0, 0.0])
    # same capacity, permuted slots, one pair gone (2–3), one new pair (0–3)
    new_idx = jnp.asarray([[3, 2, 1], [0, 4, 4], [0, 4, 4], [0, 4, 4]])
    got = np.asarray(dem.remap_history(old_idx, old, new_idx))
    np.testing.assert_array_equal(got, [[0.0, 2.0, 1.0], [1.0, 0, 0], [2.0, 0, 0],
                                        [0.0, 0, 0]])
    # larger capacity (reallocation)
    new5 = jnp.asarray([[4, 2, 4, 1, 4], [4, 4, 4, 4, 0], [0, 3, 4, 4, 4], [2, 4, 4, 4, 4]])
    got = np.asarray(dem.remap_history(old_idx, old, new5))
    np.testing.assert_array_equal(got, [[0, 2.0, 0, 1.0, 0], [0, 0, 0, 0, 1.0],
                                        [2.0, 3.0, 0, 0, 0], [3.0, 0, 0, 0, 0]])
    # smaller capacity
    new2 = jnp.asarray([[2, 1], [0, 4], [3, 0], [2, 4]])
    got = np.asarray(dem.remap_history(old_idx, old, new2))
    np.testing.assert_array_equal(got, [[2.0, 1.0], [1.0, 0], [3.0, 2.0], [3.0, 0]])


# --- shear history through a real rebuild inside a rollout --------------------------------
R = 0.01


def _press_scene():
    """A (1) and B (2) pressed together by opposite external forces, B sliding and spinning on
    A; C (0) passes under A without touching it, entering and leaving A's neighbour row."""
    x = np.array([[0.1 - 0.5 * R, 0.1 - 2.03 * R], [0.1, 0.1], [0.1, 0.1 + 2 * R - 5e-4]])
    v = np.array([[1.125, 0.0], [0.0, 0.0], [0.05, 0.0]])
    blk = disc_block(x, R, 2700.0, v=v, f_ext=np.array([[0, 0], [0, 50.0], [0, -50.0]]))
    blk.omega[2] = 3.0
    return Scene(name="press", params=Params(gravity=(0.0, 0.0), dt=2e-5,
                                             dem=DemParams(kn=1e5, ks=5e4, mu=0.5)),
                 domain_lo=(0.0, 0.0), domain_hi=(0.2, 0.2), v_max=1.0, solid=blk).validate()


_ROLLOUT = jax.jit(integrate.rollout, static_argnums=(0, 3, 4))


def _run(scene, n_steps, observe, fn=_ROLLOUT, **opts):
    phys = Physics.for_scene(scene, x64=True, **opts)
    p = scene.params.as_arrays(jnp.float64)
    st = integrate.init_state(scene, phys, p)
    return fn(phys, st, p, n_steps, observe)


def _obs(s):
    return s.solid_nbrs.idx, s.solid.shear, s.status.rebuilds


@pytest.fixture(scope="module")
def press_runs(float64):
    """dem_skin 0.05 R (rebuilds every ~12 steps) and 2 R (never rebuilds), 400 steps."""
    sc = _press_scene()
    small = _run(sc, 400, _obs, dem_skin=0.05, capacity_multiplier=3.0)
    large = _run(sc, 400, _obs, dem_skin=2.0, capacity_multiplier=3.0)
    return sc, small, large


def _slot(idx, i, j):
    """Slot of j in row i of a stack of Dense lists (steps, n, K)."""
    hit = idx[:, i, :] == j
    assert hit.any(axis=1).all()
    return np.argmax(hit, axis=1)


def test_shear_history_survives_neighbour_rebuilds(press_runs):
    """C enters A's row before B, so B's slot moves at a rebuild while the A–B contact
    carries a shear force; the history follows the pair. Same trajectories as without any
    rebuild, to round-off (here: bit for bit)."""
    sc, (small, (idx_s, sh_s, _)), (large, (idx_l, sh_l, _)) = press_runs
    assert not bool(small.status.overflow) and not bool(large.status.overflow)
    assert int(small.status.rebuilds) >= 10 and int(large.status.rebuilds) == 0
    idx_s, sh_s, idx_l, sh_l = (np.asarray(a) for a in (idx_s, sh_s, idx_l, sh_l))
    steps = np.arange(idx_s.shape[0])
    slot_s, slot_l = _slot(idx_s, 1, 2), _slot(idx_l, 1, 2)
    assert set(slot_s) == {0, 1}                            # B (2) changed slot in A's row
    k = np.argmax(np.diff(slot_s) != 0) + 1                 # first step it moved
    ab_small, ab_large = sh_s[steps, 1, slot_s], sh_l[steps, 1, slot_l]
    assert abs(ab_small[k]) > 1.0 and abs(ab_small[k - 1]) > 1.0   # N: real history
    np.testing.assert_allclose(ab_small, ab_large, rtol=1e-12, atol=1e-12)
    # B's own row (the force on B) too
    np.testing.assert_allclose(sh_s[steps, 2, _slot(idx_s, 2, 1)],
                               sh_l[steps, 2, _slot(idx_l, 2, 1)], rtol=1e-12, atol=1e-12)
    for f in ("x", "v", "omega", "theta"):
        np.testing.assert_allclose(getattr(small.solid, f), getattr(large.solid, f),
                                   rtol=1e-12, atol=1e-15)


def test_losing_history_at_rebuild_would_be_detected(press_runs, monkeypatch):
    """Control for the test above: with the history dropped at each rebuild the same run
    differs visibly, so the comparison is sensitive."""
    sc, _, (large, _) = press_runs
    monkeypatch.setattr(dem, "remap_history", lambda o, h, n: jnp.zeros(n.shape, h.dtype))
    fresh = jax.jit(lambda *a: integrate.rollout(*a), static_argnums=(0, 3, 4))
    lost, _ = _run(sc, 400, None, fn=fresh, dem_skin=0.05, capacity_multiplier=3.0)
    assert np.max(np.abs(np.asarray(lost.solid.v - large.solid.v))) > 1e-3


# --- walls -------------------------------------------------------------------------------
def one_wall(x, v=None, w=None, shear=None, dp=None, mass=0.9, dt=1e-4):
    """wall_contacts of discs of radius R at ``x`` (k, 2) with the floor (0, 0) → (0.1, 0)."""
    x = np.asarray(x, float)
    k = x.shape[0]
    v = np.zeros((k, 2)) if v is None else v
    w = np.zeros(k) if w is None else w
    shear = np.zeros((k, 1)) if shear is None else np.reshape(shear, (k, 1))
    dp = dp or DemParams(kn=1.0e5, ks=5.0e4, mu=0.3)
    out = dem.wall_contacts(dp, A(x), A(v), A(w), A(np.full(k, R)), A(np.full(k, mass)),
                            A([[0.0, 0.0]]), A([[0.1, 0.0]]), A(shear), dt)
    return [np.asarray(o) for o in out]


def test_wall_normal_force_dashpot_and_friction_torque():
    """Disc on a floor: n = (0, −1), t = (1, 0), δ = 0.001, ℓ = R − δ/2 = 0.0095;
    moving right at 0.2, down at 0.1, spinning at ω = 5."""
    beta = 0.1
    dp = DemParams(kn=1.0e5, ks=5.0e4, mu=0.3, beta_n=beta)
    f, tq, hist, delta = one_wall([[0.05, 0.009]], v=[[0.2, -0.1]], w=[5.0], dp=dp)
    assert delta[0, 0] == pytest.approx(0.001, rel=1e-9)
    fn = 100.0 + 2 * beta * math.sqrt(0.9 * 1.0e5) * 0.1    # wall: m = the disc's mass
    vs = -0.2 - 5.0 * 0.0095                                 # −v·t − ω ℓ = −0.2475
    fs = -5.0e4 * vs * 1e-4                                  # 1.2375 N
    np.testing.assert_allclose(hist[0, 0], fs, rtol=RTOL)
    np.testing.assert_allclose(f[0], [-fs, fn], rtol=RTOL)   # friction opposes sliding
    np.testing.assert_allclose(tq[0], -fs * 0.0095, rtol=RTOL)  # and the spin
    assert tq[0] < 0


def test_wall_coulomb_and_reset():
    f, _, hist, _ = one_wall([[0.05, 0.009]], v=[[10.0, 0.0]], shear=0.0)
    np.testing.assert_allclose(hist[0, 0], 0.3 * 100.0, rtol=RTOL)
    np.testing.assert_allclose(f[0], [-30.0, 100.0], rtol=RTOL)
    f, tq, hist, _ = one_wall([[0.05, 0.0101]], v=[[5.0, 0.0]], shear=12.0)
    np.testing.assert_array_equal(hist, 0.0)
    np.testing.assert_array_equal(f, 0.0)


def test_wall_segment_end_clipping():
    """Past the end b = (0.1, 0) the contact point is the end itself; a disc within R of the
    infinite line but farther than R from the segment does not touch."""
    x = [[0.105, 0.006], [0.115, 0.005], [-0.005, 0.005]]
    f, tq, hist, delta = one_wall(x)
    d0 = math.hypot(0.005, 0.006)
    n0 = np.array([-0.005, -0.006]) / d0                    # disc → corner
    np.testing.assert_allclose(delta[0, 0], R - d0, rtol=1e-12)
    np.testing.assert_allclose(f[0], -1.0e5 * (R - d0) * n0, rtol=RTOL)
    assert delta[1, 0] < 0
    np.testing.assert_array_equal(f[1], 0.0)
    d2 = math.hypot(0.005, 0.005)
    np.testing.assert_allclose(f[2], 1.0e5 * (R - d2) * np.array([-1, 1]) / math.sqrt(2),
                               rtol=RTOL)
    geo = np.asarray(dem.wall_geometry(A(x), A([[0.0, 0.0]]), A([[0.1, 0.0]])))
    np.testing.assert_allclose(geo[:, 0], [[-0.005, -0.006], [-0.015, -0.005],
                                           [0.005, -0.005]], atol=1e-15)


# --- local damping, load ramp (and their use in solid_update) -----------------------------
def test_local_damping_formula():
    f = A(3.0, -2.0, 4.0, -1.0)
    v = A(1.0, 1.0, -2.0, 0.0)
    got = np.asarray(dem.local_damping(0.7, f, v))
    np.testing.assert_allclose(got, [3 - 2.1, -2 - 1.4, 4 + 2.8, -1.0], rtol=RTOL)


@pytest.mark.parametrize("ramp, t, lf", [(0.5, 0.0, 0.0), (0.5, 0.125, 0.25), (0.5, 0.5, 1.0),
                                         (0.5, 2.0, 1.0), (0.0, 0.0, 1.0), (0.0, 3.0, 1.0)])
def test_load_factor(ramp, t, lf):
    assert float(dem.load_factor(ramp, t)) == pytest.approx(lf, abs=1e-15)


def test_solid_update_applies_ramp_gravity_and_local_damping():
    """One free disc, no contacts: a = (f_ext·t/T + m g − α|·|sign(v))/m, α_rot likewise."""
    blk = disc_block(np.array([[0.05, 0.05]]), R, 2700.0, f_ext=np.array([[3.0, -2.0]]))
    m = float(blk.mass[0])
    sc = Scene(name="one", params=Params(gravity=(0.0, -1.0), dt=1e-5,
                                         dem=DemParams(alpha=0.7, load_ramp=0.5)),
               domain_lo=(0, 0), domain_hi=(0.1, 0.1), v_max=1.0, solid=blk).validate()
    phys = Physics.for_scene(sc, x64=True)
    p = sc.params.as_arrays(jnp.float64)
    st = integrate.init_state(sc, phys, p)
    s = st.solid
    acc, alpha, *_ = integrate.solid_update(phys, p, s, s.x, A([[1.0, 1.0]]), A([2.0]), s.theta,
                                            s.shear, st.solid_nbrs.idx, None, None, 0.25, 0.0)
    F = np.array([1.5, -1.0 - m])              # half the load, gravity on y
    want = (F - 0.7 * np.abs(F) * np.array([1.0, 1.0])) / m
    np.testing.assert_allclose(np.asarray(acc)[0], want, rtol=RTOL)
    np.testing.assert_allclose(np.asarray(alpha), 0.0, atol=1e-15)
    # at t = 0 only gravity, full load after the ramp
    acc0, *_ = integrate.solid_update(phys, p, s, s.x, A([[0.0, 0.0]]), A([0.0]), s.theta, s.shear,
                                      st.solid_nbrs.idx, None, None, 0.0, 0.0)
    np.testing.assert_allclose(np.asarray(acc0)[0], [0.0, -1.0], rtol=RTOL)
    acc1, *_ = integrate.solid_update(phys, p, s, s.x, A([[0.0, 0.0]]), A([0.0]), s.theta, s.shear,
                                      st.solid_nbrs.idx, None, None, 0.9, 0.0)
    np.testing.assert_allclose(np.asarray(acc1)[0], [3.0 / m, -2.0 / m - 1.0], rtol=RTOL)


def test_local_damping_on_the_moment():
    """Torque from a wall contact, damped with sign(ω)."""
    blk = disc_block(np.array([[0.05, 0.009]]), R, 2700.0)
    sc = Scene(name="w", params=Params(gravity=(0.0, 0.0), dt=1e-5,
                                       dem=DemParams(kn=1e5, ks=5e4, mu=0.3, alpha=0.5)),
               domain_lo=(-0.01, -0.01), domain_hi=(0.11, 0.1), v_max=1.0, solid=blk,
               walls=WallBlock(a=np.array([[0.0, 0.0]]), b=np.array([[0.1, 0.0]]))).validate()
    phys = Physics.for_scene(sc, x64=True)
    p = sc.params.as_arrays(jnp.float64)
    st = integrate.init_state(sc, phys, p)
    s = st.solid
    acc, alpha, _, wsh, _ = integrate.solid_update(
        phys, p, s, s.x, A([[0.0, 0.0]]), A([5.0]), s.theta, s.shear, st.solid_nbrs.idx, st.walls,
        None, 0.0, 1e-4)
    fs = 5.0e4 * 5.0 * 0.0095 * 1e-4
    np.testing.assert_allclose(np.asarray(wsh)[0, 0], fs, rtol=RTOL)
    torque = -fs * 0.0095
    want = (torque - 0.5 * abs(torque) * 1.0) / float(blk.inertia[0])
    np.testing.assert_allclose(float(alpha[0]), want, rtol=RTOL)
    # force: x friction −fs (v = 0: undamped), y normal 100 N
    np.testing.assert_allclose(np.asarray(acc)[0], np.array([-fs, 100.0]) / float(blk.mass[0]),
                               rtol=RTOL)


# --- conservation in a closed cluster -----------------------------------------------------
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
    st = integrate.init_state(sc, phys, p)
    end, obs = jax.jit(integrate.rollout, static_argnums=(0, 3, 4))(phys, st, p, 300, _momenta)
    return sc, phys, p, st, end, [np.asarray(o) for o in obs]


def test_momentum_and_angular_momentum_conserved(cluster_run):
    sc, phys, p, st, end, (P, L, nc) = cluster_run
    assert not bool(end.status.overflow) and not bool(end.status.bad)
    assert nc.max() >= 10                      # many frictional contacts
    assert int(end.status.rebuilds) >= 1
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


# --- compiled program: absent phases are absent -------------------------------------------
def test_dem_only_scene_compiles_no_sph(step_hlo):
    _, scopes, files = step_hlo(scenes.build("collision"), jnp.float64)
    for want in ("dem.contacts", "dem.local_damping", "integrate.solid_kick_drift",
                 "neighbors.dem_update"):
        assert want in scopes, want
    assert not [s for s in scopes if s.startswith(("sph.", "boundary."))]
    for absent in ("integrate.kick_drift", "neighbors.update", "dem.walls", "bonds"):
        assert absent not in scopes, absent
    assert "dem.py" in files and "sph.py" not in files and "kernels.py" not in files
    _, scopes_w, files_w = step_hlo(scenes.build("rolling"), jnp.float64)
    assert "dem.walls" in scopes_w and "sph.py" not in files_w


def test_fluid_only_scene_compiles_no_dem(tiny_tank, step_hlo):
    _, scopes, files = step_hlo(tiny_tank)
    assert "sph.continuity" in scopes and "sph.pressure" in scopes
    assert not [s for s in scopes if s.startswith("dem.")]
    for absent in ("bonds", "integrate.solid_kick_drift", "neighbors.dem_update"):
        assert absent not in scopes, absent
    assert "sph.py" in files and "dem.py" not in files and "bonds.py" not in files


# --- viscous (mass-proportional) damping ---------------------------------------------------
def test_viscous_damping_formula_and_in_solid_update():
    """F = −c m v, M = −c J ω on a free disc with no other force."""
    np.testing.assert_allclose(np.asarray(dem.viscous_damping(2.0, 3.0, A(1.0, -4.0))),
                               [-6.0, 24.0], rtol=RTOL)
    blk = disc_block(np.array([[0.05, 0.05]]), R, 2700.0)
    sc = Scene(name="one", params=Params(gravity=(0.0, 0.0), dt=1e-5,
                                         dem=DemParams(damping=3.0)),
               domain_lo=(0, 0), domain_hi=(0.1, 0.1), v_max=1.0, solid=blk).validate()
    phys = Physics.for_scene(sc, x64=True)
    p = sc.params.as_arrays(jnp.float64)
    st = integrate.init_state(sc, phys, p)
    s = st.solid
    acc, alpha, *_ = integrate.solid_update(phys, p, s, s.x, A([[1.0, -2.0]]), A([5.0]), s.theta,
                                            s.shear, st.solid_nbrs.idx, None, None, 0.0, 0.0)
    np.testing.assert_allclose(np.asarray(acc)[0], [-3.0, 6.0], rtol=RTOL)
    np.testing.assert_allclose(np.asarray(alpha)[0], -15.0, rtol=RTOL)


def test_viscous_damping_decay_and_time_step_bound():
    """A free disc coasting with damping c follows the kick–drift–kick recursion with the
    damping evaluated at v½ exactly, and exp(−c t) to O(c²Δt²) per step; the derived DEM
    step respects c Δt ≤ 0.5."""
    blk = disc_block(np.array([[0.05, 0.05]]), R, 2700.0, v=np.array([[0.01, 0.0]]))
    c = 50.0
    sc = Scene(name="coast", params=Params(gravity=(0.0, 0.0), dt=1e-4,
                                           dem=DemParams(damping=c)),
               domain_lo=(0, 0), domain_hi=(0.1, 0.1), v_max=1.0, solid=blk).validate()
    assert integrate.dem_dt(sc, sc.params.replace(dem=DemParams(damping=1e5))) <= 0.5 / 1e5
    phys = Physics.for_scene(sc, x64=True)
    p = sc.params.as_arrays(jnp.float64)
    st = integrate.init_state(sc, phys, p)
    st, _ = integrate.rollout(phys, st, p, 200, None)
    v, a, dt = 0.01, -c * 0.01, 1e-4
    for _ in range(200):
        vh = v + 0.5 * dt * a
        a = -c * vh
        v = vh + 0.5 * dt * a
    np.testing.assert_allclose(float(st.solid.v[0, 0]), v, rtol=1e-12)
    np.testing.assert_allclose(v, 0.01 * math.exp(-c * 0.02), rtol=200 * (c * dt) ** 2 / 2)
