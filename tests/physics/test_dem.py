"""Unit tests of the DEM contact laws (fpsi_jax.physics.dem, physics.md §DEM contacts).

Every contact term is compared with a number computed here by hand for two discs (or one
disc and one wall) placed by hand; then the re-addressing of the contact history to a new
neighbour list, the local and viscous damping laws and the load ramp. The DEM stage of the
step (solver.stages.disc_forces and the sub-step) is tested in tests/solver/test_stages.py,
conservation over rollouts in tests/solver/test_forward.py.
"""
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from fpsi_jax.model.params import DemParams
from fpsi_jax.physics import dem

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


def test_rolling_resistance_couple_between_two_discs():
    """μ_r = 0.2 on the pair of the test above (F_n = 100 N, R* = R_A R_B/(R_A + R_B) =
    0.006): each disc also takes ∓μ_r R* F_n = ∓0.12 N·m against its rolling relative to
    the other (ω_A − ω_B = 5 > 0: A's couple is negative), equal and opposite; forces and
    shear unchanged; none while the two roll alike."""
    dp = DemParams(kn=1.0e5, ks=5.0e4, mu=0.3, mu_roll=0.2)
    args = dict(va=(0.0, 0.1), vb=(0.0, -0.2), wa=2.0, wb=-3.0, shear=2.0)
    (f, tq, hist, _), _ = two_discs(dp=dp, **args)
    (f0, tq0, hist0, _), _ = two_discs(**args)
    m_r = 0.2 * (0.010 * 0.015 / 0.025) * 100.0
    assert m_r == pytest.approx(0.12)
    np.testing.assert_allclose(tq, tq0 + np.array([-m_r, m_r]), rtol=RTOL)
    np.testing.assert_allclose(f, f0, rtol=RTOL)
    np.testing.assert_allclose(hist, hist0, rtol=RTOL)
    (_, tq1, _, _), _ = two_discs(dp=dp, wa=2.0, wb=2.0)
    (_, tq2, _, _), _ = two_discs(wa=2.0, wb=2.0)
    np.testing.assert_allclose(tq1, tq2, rtol=RTOL)


# --- walls -------------------------------------------------------------------------------
R = 0.01


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


def test_wall_reaction_is_the_discs_force_on_the_wall_at_the_contact_point():
    """The disc of the test above pushes the floor with −(its force), applied at the
    contact point c = (0.05, 0.009 − ℓ) = (0.05, −0.0005): moment about the origin
    c_x F_y − c_y F_x. A row left out of ``reaction`` adds nothing."""
    beta = 0.1
    dp = DemParams(kn=1.0e5, ks=5.0e4, mu=0.3, beta_n=beta)
    x, v, w = A([[0.05, 0.009], [0.02, 0.009]]), A([[0.2, -0.1], [0.0, 0.0]]), A([5.0, 0.0])
    out = dem.wall_contacts(dp, x, v, w, A(np.full(2, R)), A(np.full(2, 0.9)),
                            A([[0.0, 0.0]]), A([[0.1, 0.0]]), A(np.zeros((2, 1))), 1e-4,
                            reaction=jnp.asarray([True, False]))
    f_disc = np.asarray(out[0])[0]
    fx, fy = -f_disc
    cx, cy = 0.05, 0.009 - 0.0095
    np.testing.assert_allclose(np.asarray(out[4])[0], [fx, fy, cx * fy - cy * fx], rtol=RTOL)
    # the four outputs are the ones without ``reaction``
    plain = dem.wall_contacts(dp, x, v, w, A(np.full(2, R)), A(np.full(2, 0.9)),
                              A([[0.0, 0.0]]), A([[0.1, 0.0]]), A(np.zeros((2, 1))), 1e-4)
    for a, b in zip(out[:4], plain):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))


def test_rolling_resistance_on_a_wall_opposes_the_spin_and_reaches_the_wall():
    """A disc spinning at ω = 5 on the floor (F_n = 100 N, R* = R against a wall) takes
    −μ_r R F_n = −0.1 N·m more with μ_r = 0.1; the floor's recorded moment takes +0.1."""
    dp0 = DemParams(kn=1.0e5, ks=5.0e4, mu=0.3)
    dp = DemParams(kn=1.0e5, ks=5.0e4, mu=0.3, mu_roll=0.1)
    kw = dict(v=A([[0.0, 0.0]]), w=A([5.0]), radius=A([R]), mass=A([0.9]))

    def run(p):
        return [np.asarray(o) for o in dem.wall_contacts(
            p, A([[0.05, 0.009]]), kw["v"], kw["w"], kw["radius"], kw["mass"],
            A([[0.0, 0.0]]), A([[0.1, 0.0]]), A(np.zeros((1, 1))), 1e-4,
            reaction=jnp.asarray([True]))]

    with_r, without = run(dp), run(dp0)
    np.testing.assert_allclose(with_r[1] - without[1], [-0.1 * R * 100.0], rtol=RTOL)
    np.testing.assert_allclose(with_r[4][0, 2] - without[4][0, 2], 0.1 * R * 100.0,
                               rtol=RTOL)


def test_wall_reaction_conserves_momentum_and_angular_momentum():
    """Discs against the four walls of a box and a free segment inside it: the walls'
    forces sum to minus the discs', and their moments about the origin to minus the
    discs' Σ x_i × F_i + τ_i."""
    rng = np.random.default_rng(3)
    a = A([[0.0, 0.0], [0.1, 0.0], [0.1, 0.1], [0.0, 0.1], [0.03, 0.04]])
    b = A([[0.1, 0.0], [0.1, 0.1], [0.0, 0.1], [0.0, 0.0], [0.07, 0.06]])
    x = np.array([[0.05, 0.008], [0.093, 0.05], [0.05, 0.095], [0.006, 0.03],
                  [0.05, 0.058], [0.006, 0.006]])
    k = len(x)
    dp = DemParams(kn=1.0e5, ks=5.0e4, mu=0.3, beta_n=0.2, beta_s=0.1, mu_roll=0.1)
    f, tq, _, delta, per_wall = dem.wall_contacts(
        dp, A(x), A(rng.normal(0, 0.3, (k, 2))), A(rng.normal(0, 5, k)), A(np.full(k, R)),
        A(np.full(k, 0.9)), a, b, A(rng.normal(0, 1.0, (k, 5))), 1e-4,
        reaction=jnp.ones(k, bool))
    f, tq, per_wall = np.asarray(f, float), np.asarray(tq, float), np.asarray(per_wall, float)
    assert (np.asarray(delta) > 0).sum() >= 7                 # the corner disc touches two
    np.testing.assert_allclose(per_wall[:, :2].sum(axis=0), -f.sum(axis=0), atol=1e-4)
    ang = np.sum(x[:, 0] * f[:, 1] - x[:, 1] * f[:, 0] + tq)
    np.testing.assert_allclose(per_wall[:, 2].sum(), -ang, atol=1e-6)


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


# --- damping and load ramp --------------------------------------------------------------
def test_local_damping_formula():
    f = A(3.0, -2.0, 4.0, -1.0)
    v = A(1.0, 1.0, -2.0, 0.0)
    got = np.asarray(dem.local_damping(0.7, f, v))
    np.testing.assert_allclose(got, [3 - 2.1, -2 - 1.4, 4 + 2.8, -1.0], rtol=RTOL)


@pytest.mark.parametrize("ramp, t, lf", [(0.5, 0.0, 0.0), (0.5, 0.125, 0.25), (0.5, 0.5, 1.0),
                                         (0.5, 2.0, 1.0), (0.0, 0.0, 1.0), (0.0, 3.0, 1.0)])
def test_load_factor(ramp, t, lf):
    assert float(dem.load_factor(ramp, t)) == pytest.approx(lf, abs=1e-15)


def test_viscous_damping_formula():
    """F = −c m v (and M = −c J ω alike)."""
    np.testing.assert_allclose(np.asarray(dem.viscous_damping(2.0, 3.0, A(1.0, -4.0))),
                               [-6.0, 24.0], rtol=RTOL)


# --- one-sided walls (scene.WallBlock.side) --------------------------------------------------
def floor_contacts(x, side, v=None, kn=1.0e5):
    """wall_contacts of discs of radius R at ``x`` with the floor (0, 0) → (0.1, 0) whose
    active side is ``side`` (+1: above, the left of a → b)."""
    x = np.asarray(x, float)
    k = x.shape[0]
    v = np.zeros((k, 2)) if v is None else np.asarray(v, float)
    out = dem.wall_contacts(DemParams(kn=kn, ks=5.0e4, mu=0.3), A(x), A(v), A(np.zeros(k)),
                            A(np.full(k, R)), A(np.full(k, 0.9)), A([[0.0, 0.0]]),
                            A([[0.1, 0.0]]), A(np.zeros((k, 1))), 1e-4, A([side]))
    return [np.asarray(o) for o in out]


def test_one_sided_wall_acts_as_the_two_sided_one_in_front():
    x = [[0.05, 0.009], [0.05, 0.02], [0.105, 0.004]]      # on it, clear of it, off its end
    one = floor_contacts(x, 1.0)
    two = one_wall(x)
    for a, b in zip(one, two):
        np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-15)


def test_one_sided_wall_pushes_a_disc_back_from_behind():
    """Centre 0.3R below the floor's line: δ = R + 0.3R, pushed up with k_n δ; 2.5R below
    (past the 2R reach) or behind but beyond the wall's end: no contact."""
    f, tq, hist, delta = floor_contacts([[0.05, -0.3 * R], [0.05, -2.5 * R],
                                         [0.12, -0.3 * R]], 1.0)
    np.testing.assert_allclose(delta[0, 0], 1.3 * R, rtol=1e-12)
    np.testing.assert_allclose(f[0], [0.0, 1.0e5 * 1.3 * R], rtol=1e-12)
    assert delta[1, 0] < 0 and delta[2, 0] < 0
    np.testing.assert_array_equal(f[1:], 0.0)


def test_one_sided_wall_ignores_discs_on_its_inactive_side():
    """The same floor active below (side −1): a disc 2.5R above it (on the inactive side,
    beyond the 2R reach behind the line) feels nothing, one just below is pushed down."""
    f, _, _, delta = floor_contacts([[0.05, 0.025], [0.05, -0.009]], -1.0)
    np.testing.assert_array_equal(f[0], 0.0)
    np.testing.assert_allclose(f[1], [0.0, -1.0e5 * 0.001], rtol=1e-9)


def _apart(*args):
    """No disc near a wall (dem.walls_near for none)."""
    return ~jnp.any(dem.walls_near(*args))


def test_walls_near_by_hand():
    """walls_near with margin m = 0.1R against the floor (0, 0) → (0.1, 0): a pair counts
    as apart while d − R > m and, one-sided, the centre is clear on the active side
    (s > R + m) or farther than the 2R reach behind the line (d > 2R + m)."""
    m = 0.1 * R
    a, b = A([[0.0, 0.0]]), A([[0.1, 0.0]])

    def apart(y, side=None, x=0.05):
        return bool(_apart(A([[x, y]]), A([R]), a, b, None if side is None else A([side]),
                           m))

    assert apart(1.2 * R) and not apart(1.05 * R)                     # two-sided: d − R vs m
    assert apart(-1.2 * R) and not apart(-1.05 * R)
    assert apart(1.2 * R, 1.0) and not apart(1.05 * R, 1.0)           # active side: s vs R + m
    assert not apart(-1.2 * R, 1.0)                                   # behind, within reach
    assert not apart(-2.05 * R, 1.0) and apart(-2.2 * R, 1.0)         # d vs 2R + m
    assert apart(-0.5 * R, 1.0, x=0.1 + 3.0 * R)                      # behind, off its end
    two = A([[0.05, 0.5], [0.05, 1.05 * R]])
    assert list(np.asarray(dem.walls_near(two, A([R, R]), a, b, None, m))) == [False, True]
    held = dem.walls_near(two, A([R, R]), a, b, None, m, jnp.asarray([False, True]))
    assert not np.asarray(held).any()                                 # a held disc: apart


def test_discs_apart_from_the_walls_moved_within_the_margin_never_touch():
    """Discs the test calls apart, each moved by up to the margin in any direction, have no
    overlap with a one-sided or two-sided floor; the pair just past the 2R reach behind the
    line (d = 2.05R, m = 0.1R) touches once moved up by m, so the test must call it near."""
    rng = np.random.default_rng(3)
    m = 0.25 * R
    a, b = A([[0.0, 0.0]]), A([[0.1, 0.0]])
    x = np.column_stack([rng.uniform(-4 * R, 0.1 + 4 * R, 4000), rng.uniform(-5 * R, 5 * R, 4000)])
    for side in (None, 1.0, -1.0):
        sd = None if side is None else A([side])
        ok = np.asarray(jax.vmap(lambda p: _apart(p[None], A([R]), a, b, sd, m))(A(x)))
        assert 0.3 < ok.mean() < 0.95                  # both answers occur in the sample
        ang = rng.uniform(0, 2 * np.pi, x.shape[0])
        moved = x + m * rng.uniform(0, 1, x.shape[0])[:, None] * np.column_stack(
            [np.cos(ang), np.sin(ang)])
        _, delta = dem.wall_pair_geometry(A(moved), A(np.full(len(x), R)), a, b, sd)
        assert np.all(np.asarray(delta)[ok, 0] <= 0.0)
    touch = floor_contacts([[0.05, -2.05 * R + 0.1 * R]], 1.0)[3]
    assert touch[0, 0] > 0 and not bool(
        _apart(A([[0.05, -2.05 * R]]), A([R]), a, b, A([1.0]), 0.1 * R))


def test_box_walls_face_inwards():
    from fpsi_jax.build.geometry import box_walls
    w = box_walls(0.0, 0.0, 1.0, 0.5, top=True)
    n_in = np.asarray(dem.inward_normals(A(w.a), A(w.b), A(w.sides())))
    np.testing.assert_allclose(n_in, [[0, 1], [1, 0], [-1, 0], [0, -1]], atol=1e-15)
