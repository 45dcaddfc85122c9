"""Unit tests of the parallel bonds (fpsi_jax.physics.bonds; physics.md §Parallel bonds).

One bond between two discs placed by hand: section, stretch, bending, shear, rigid motion,
agreement with the incremental law K17–K20 for small displacements, fracture in tension
(with and without the moment term) and in shear, and the gradient of the bond force with
respect to k̄_n (float64). Bonds inside the step are tested in tests/solver/test_stages.py
and tests/solver/test_forward.py.
"""
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from fpsi_jax.model.params import BondParams
from fpsi_jax.physics import bonds

pytestmark = pytest.mark.usefixtures("float64")  # conftest: x64 for this module only


RTOL = 1e-12
KN, KS = 1.0e9, 4.0e8
R = 0.005
D0 = 2 * R
AREA = 2 * R * 1.0                       # slab, λ = 1, t = 1 m: 0.01 m²
INERTIA = 2.0 / 3.0 * 1.0 * R ** 3       # 8.333e-8 m⁴


def F(*v):
    return jnp.asarray(np.array(v[0] if len(v) == 1 else v, float))


def rot(phi):
    c, s = math.cos(phi), math.sin(phi)
    return np.array([[c, -s], [s, c]])


def one_bond(xb, theta=(0.0, 0.0), x0=None, bp=None, kind="slab", radius=(R, R),
             intact=True):
    """bond_forces of one bond A = 0 → B = 1, made at ``x0`` (default A at (0.1, 0.2), B at
    D0 along x), evaluated with A at x0[0], B at ``xb`` and rotations ``theta``."""
    x0 = np.array([[0.1, 0.2], [0.1 + D0, 0.2]]) if x0 is None else np.asarray(x0, float)
    i, j = jnp.asarray([0]), jnp.asarray([1])
    d0, e0 = bonds.rest_geometry(F(x0), i, j)
    bp = bp or BondParams(kn=KN, ks=KS)
    x = np.array([x0[0], xb], float) if np.ndim(xb) == 1 else np.asarray(xb, float)
    out = bonds.bond_forces(bp, kind, 2, F(x - x0), F(theta), F(radius), i, j, d0, e0,
                            jnp.asarray([intact]))
    return [np.asarray(o) for o in out]


# --- geometry ----------------------------------------------------------------------------
def test_bond_axis_holds_a_float32_stretch_far_from_the_origin():
    """A bond made at x = 0.6 m, B displaced by 10⁻⁷ m along it, all float32: F̄_n = k̄_n A u
    = 1 N from the displacements (bond_axis), to the resolution of the 10 mm length d
    (an ulp of 9·10⁻¹⁰ m, 1 % of this stretch). Read from the positions, the stretch is
    what float32 keeps of 0.61 + 10⁻⁷ m: two ulps of 6·10⁻⁸ m, 19 % too much."""
    f32 = jnp.float32
    x0 = jnp.asarray([[0.6, 0.2], [0.6 + D0, 0.2]], f32)
    i, j = jnp.asarray([0]), jnp.asarray([1])
    d0, e0 = bonds.rest_geometry(x0, i, j)
    u = jnp.asarray([[0.0, 0.0], [1e-7, 0.0]], f32)
    fn, *_ = bonds.bond_loads(BondParams(kn=KN, ks=KS), "slab", u, jnp.zeros(2, f32),
                              jnp.full(2, R, f32), i, j, d0, e0)
    assert fn.dtype == f32
    assert float(fn[0]) == pytest.approx(KN * AREA * 1e-7, rel=0.01)
    x = x0 + u
    from_positions = float(jnp.linalg.norm(x[1] - x[0]) - d0[0])
    assert abs(from_positions / 1e-7 - 1.0) > 0.1


def test_section_slab_and_circular():
    a, i = bonds.section("slab", 0.005, 2.0)
    assert float(a) == pytest.approx(0.02, rel=RTOL)                 # 2 R̄ t
    assert float(i) == pytest.approx(2.0 / 3.0 * 2.0 * 1.25e-7, rel=RTOL)   # (2/3) t R̄³
    assert float(i) == pytest.approx(1.6666666666666667e-07, rel=RTOL)
    a, i = bonds.section("circular", 0.004, 123.0)                  # thickness unused
    assert float(a) == pytest.approx(math.pi * 1.6e-5, rel=RTOL)    # π R̄² = 5.0265e-5
    assert float(a) == pytest.approx(5.026548245743669e-05, rel=RTOL)
    assert float(i) == pytest.approx(math.pi * 2.56e-10 / 4, rel=RTOL)   # π R̄⁴/4
    with pytest.raises(ValueError, match="hexagon"):
        bonds.section("hexagon", 0.004, 1.0)


def test_bond_radius_and_rest_geometry():
    bp = BondParams(lam=0.8)
    assert float(bonds.bond_radius(bp, 0.004, 0.006)) == pytest.approx(0.004, rel=RTOL)
    x = F([[0.0, 0.0], [0.003, 0.004], [1.0, 1.0]])
    d0, e0 = bonds.rest_geometry(x, jnp.asarray([0, 2]), jnp.asarray([1, 1]))
    np.testing.assert_allclose(d0, [0.005, math.hypot(0.997, 0.996)], rtol=RTOL)
    np.testing.assert_allclose(e0[0], [0.6, 0.8], rtol=RTOL)


# --- force–moment law --------------------------------------------------------------------
@pytest.mark.parametrize("u", [1e-5, -2e-5])
def test_stretch_gives_normal_force_pulling_discs_together(u):
    """F̄_n = k̄_n A u, tension positive; on B −F̄_n n, on A +F̄_n n, no shear nor moment."""
    ang = math.radians(35)
    e = np.array([math.cos(ang), math.sin(ang)])
    xa = np.array([0.1, 0.2])
    x0 = [xa, xa + D0 * e]
    force, torque, alive, mode, fn, fs, m = one_bond(xa + (D0 + u) * e, x0=x0)
    want = KN * AREA * u                                   # 100 N for u = 1e-5
    assert fn[0] == pytest.approx(want, rel=1e-9)
    if u > 0:
        assert fn[0] == pytest.approx(100.0, rel=1e-9)
    np.testing.assert_allclose(force[1], -want * e, rtol=1e-9)
    np.testing.assert_allclose(force[0], want * e, rtol=1e-9)
    # tension: B pulled back towards A
    assert (force[1] @ e < 0) == (u > 0)
    np.testing.assert_allclose([fs[0], m[0]], 0.0, atol=1e-9 * abs(want) * R)
    np.testing.assert_allclose(torque, 0.0, atol=1e-9 * abs(want) * R)
    assert alive[0] and mode[0] == 0


def test_bond_across_a_gap_is_a_bar_of_its_rest_length():
    """Discs R = 5 mm made 12 mm apart (gap 2 mm): c = (R_A + R_B)/d0 = 10/12, so
    F̄_n = k̄_n c A u = 1e9·(5/6)·0.01·1e-5 = 83.33 N (a bar EA/d0 with k̄_n = E/2R),
    M̄ = −k̄_n c I Δθ and F̄_s = −k̄_s c A U_s likewise; equal and opposite forces."""
    x0 = [[0.1, 0.2], [0.112, 0.2]]
    force, torque, alive, mode, fn, fs, m = one_bond([0.112 + 1e-5, 0.2], x0=x0)
    assert fn[0] == pytest.approx(1e9 * (10 / 12) * 0.01 * 1e-5, rel=1e-9)
    assert fn[0] == pytest.approx(83.33333333333333, rel=1e-9)
    np.testing.assert_allclose(force[0] + force[1], 0.0, atol=1e-9)
    _, _, _, _, _, _, m = one_bond([0.112, 0.2], theta=(0.0, 1e-4), x0=x0)
    assert m[0] == pytest.approx(-KN * (10 / 12) * INERTIA * 1e-4, rel=1e-9)
    # U_s = d0Δφ − ℓ_A θ_A − ℓ_B θ_B with ℓ = d0/2 for equal discs: B moved 1e-6 sideways
    _, _, _, _, _, fs, _ = one_bond([0.112, 0.2 + 1e-6], x0=x0)
    assert fs[0] == pytest.approx(-KS * (10 / 12) * AREA * 0.012 * math.atan2(1e-6, 0.012),
                                  rel=1e-9)


def test_circular_section_stretch():
    """Circular section with λ = 0.8: A = π(0.8 R)²."""
    bp = BondParams(kn=KN, ks=KS, lam=0.8)
    _, _, _, _, fn, _, _ = one_bond(np.array([0.1 + D0 + 1e-5, 0.2]), bp=bp, kind="circular")
    assert fn[0] == pytest.approx(KN * math.pi * (0.8 * R) ** 2 * 1e-5, rel=1e-9)


def test_pure_relative_rotation_gives_opposite_moments():
    """θ_A = −Δθ/2, θ_B = +Δθ/2 (equal discs): M̄ = −k̄_n I Δθ, U_s = 0; torques ∓M̄."""
    dth = 1e-4
    force, torque, _, _, fn, fs, m = one_bond(np.array([0.1 + D0, 0.2]),
                                              theta=(-dth / 2, dth / 2))
    mm = -KN * INERTIA * dth                                # −8.333e-3 N·m
    assert m[0] == pytest.approx(mm, rel=1e-12)
    assert m[0] == pytest.approx(-8.333333333333334e-3, rel=1e-9)
    np.testing.assert_allclose(torque, [-mm, mm], rtol=1e-12)
    np.testing.assert_allclose([fn[0], fs[0]], 0.0, atol=1e-9)
    np.testing.assert_allclose(force, 0.0, atol=1e-9)


def test_one_sided_rotation_adds_shear_at_the_contact_point():
    """θ_A = 0, θ_B = Δθ with R_A ≠ R_B (touching): U_s = −ℓ_B Δθ, ℓ_B = d0 R_B/(R_A + R_B);
    F̄_s = −k̄_s A U_s; on B F̄_s t and M̄ − F̄_s ℓ_B, on A −F̄_s t and −M̄ − F̄_s ℓ_A."""
    ra, rb = 0.004, 0.006
    x0 = np.array([[0.1, 0.2], [0.1 + ra + rb, 0.2]])
    dth = 2e-4
    force, torque, _, _, fn, fs, m = one_bond(x0[1], theta=(0.0, dth), x0=x0,
                                              radius=(ra, rb))
    area = 2 * 0.005 * 1.0                                  # R̄ = (ra + rb)/2 = 0.005
    inertia = 2.0 / 3.0 * 0.005 ** 3
    la, lb = ra, rb
    fs_w = KS * area * lb * dth                             # 4.8 N
    m_w = -KN * inertia * dth
    assert fs[0] == pytest.approx(fs_w, rel=1e-12) and fs_w == pytest.approx(4.8)
    assert m[0] == pytest.approx(m_w, rel=1e-12)
    np.testing.assert_allclose(force[1], [0.0, fs_w], rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(force[0], [0.0, -fs_w], rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(torque, [-m_w - fs_w * la, m_w - fs_w * lb], rtol=1e-12)


def test_sideways_displacement_gives_shear():
    """B moved by s ⊥ the bond: Δφ = atan2(s, d0), U_s = d0 Δφ, d = √(d0² + s²); the force
    on B −F̄_n n + F̄_s (d0/d) t."""
    s = 3e-6
    xb = np.array([0.1 + D0, 0.2 + s])
    force, torque, _, _, fn, fs, m = one_bond(xb)
    d = math.hypot(D0, s)
    n = np.array([D0, s]) / d
    t = np.array([-n[1], n[0]])
    us = D0 * math.atan2(s, D0)
    fs_w, fn_w = -KS * AREA * us, KN * AREA * (d - D0)
    assert fs[0] == pytest.approx(fs_w, rel=1e-10)          # ≈ −12 N
    assert fn[0] == pytest.approx(fn_w, rel=1e-6)
    np.testing.assert_allclose(force[1], -fn_w * n + fs_w * (D0 / d) * t, rtol=1e-9)
    np.testing.assert_allclose(force[0], -force[1], rtol=1e-12)
    np.testing.assert_allclose(torque, [-fs_w * R, -fs_w * R], rtol=1e-10)
    assert m[0] == 0.0


@pytest.mark.parametrize("radius", [(R, R), (0.004, 0.006)])
def test_bond_forces_are_minus_the_gradient_of_its_energy_and_carry_no_moment(radius):
    """A bond stretched 3 %, turned and bent (discs of equal or unequal radius, made 1 mm
    apart): the forces and torques on both discs are −∂E/∂(u, θ) of the bond energy
    E = ½F̄_n²/(k̄_n cA) + ½F̄_s²/(k̄_s cA) + ½M̄²/(k̄_n cI) (jax.grad), and the pair's
    moment about the origin, Σ x × F + τ, is zero: the shear force on the discs is
    F̄_s d0/d (F̄_s alone left F̄_s (d − d0) = 3 % of its lever arm's moment)."""
    ra, rb = radius
    x0 = np.array([[0.1, 0.2], [0.1 + ra + rb + 0.001, 0.2]])
    i, j = jnp.asarray([0]), jnp.asarray([1])
    d0, e0 = bonds.rest_geometry(F(x0), i, j)
    bp = BondParams(kn=KN, ks=KS)
    c = (ra + rb) / float(d0[0])
    area = 2 * 0.5 * (ra + rb)
    inertia = 2.0 / 3.0 * (0.5 * (ra + rb)) ** 3

    def energy(u, theta):
        fn, fs, m, *_ = bonds.bond_loads(bp, "slab", u, theta, F(radius), i, j, d0, e0)
        return jnp.sum(0.5 * fn ** 2 / (KN * c * area) + 0.5 * fs ** 2 / (KS * c * area)
                       + 0.5 * m ** 2 / (KN * c * inertia))

    u = F([[0.0, 0.0], [0.03 * float(d0[0]), 4e-4]])
    theta = F([2e-3, -1e-2])
    force, torque, *_ = bonds.bond_forces(bp, "slab", 2, u, theta, F(radius), i, j, d0, e0,
                                          jnp.asarray([True]))
    gu, gt = jax.grad(energy, argnums=(0, 1))(u, theta)
    scale = float(jnp.max(jnp.abs(force)))
    assert scale > 1e3                      # F̄_n ≈ 3 kN
    np.testing.assert_allclose(np.asarray(force), -np.asarray(gu), rtol=1e-10,
                               atol=1e-12 * scale)
    np.testing.assert_allclose(np.asarray(torque), -np.asarray(gt), rtol=1e-10,
                               atol=1e-12 * scale * R)
    x = x0 + np.asarray(u)
    f = np.asarray(force)
    moment = np.sum(x[:, 0] * f[:, 1] - x[:, 1] * f[:, 0] + np.asarray(torque))
    assert abs(moment) < 1e-12 * scale * 0.2


@pytest.mark.parametrize("phi", [0.3, 2.0, -2.5, 3.1])
def test_rigid_rotation_gives_no_load(phi):
    """Positions rotated by φ about an arbitrary point and translated, both θ = φ."""
    x0 = np.array([[0.1, 0.2], [0.1 + D0, 0.2]])
    c = np.array([0.13, 0.17])
    x = (x0 - c) @ rot(phi).T + c + np.array([0.01, -0.02])
    force, torque, alive, _, fn, fs, m = one_bond(x, theta=(phi, phi), x0=x0)
    scale = KN * AREA * D0                                  # 1e5 N: force of a 100 % strain
    np.testing.assert_allclose([fn[0], fs[0]], 0.0, atol=1e-12 * scale)
    assert m[0] == 0.0
    np.testing.assert_allclose(force, 0.0, atol=1e-12 * scale)
    np.testing.assert_allclose(torque, 0.0, atol=1e-12 * scale * R)
    assert alive[0]


@pytest.mark.parametrize("phi", [3.5, -4.0, 2 * math.pi + 0.3])
def test_rigid_rotation_beyond_half_a_turn_gives_no_load(phi):
    x0 = np.array([[0.1, 0.2], [0.1 + D0, 0.2]])
    x = (x0 - x0[0]) @ rot(phi).T + x0[0]
    _, _, alive, _, fn, fs, m = one_bond(x, theta=(phi, phi), x0=x0,
                                         bp=BondParams(kn=KN, ks=KS))
    scale = KN * AREA * D0
    np.testing.assert_allclose([fn[0], fs[0]], 0.0, atol=1e-9 * scale)


def test_total_form_agrees_with_incremental_law_for_small_displacements():
    """Integrate K17–K20 along a curved path of small motions (translation, a small rigid
    rotation, stretch, sideways shear, independent disc rotations; strains ~1e-4) and compare
    with the total form at the end: equal to O(strain) relative."""
    ra, rb = 0.004, 0.006
    d0 = ra + rb
    xa0 = np.array([0.1, 0.2])
    x0 = np.array([xa0, xa0 + [d0, 0.0]])
    bp = BondParams(kn=KN, ks=KS)
    r_bar = 0.5 * (ra + rb)
    area, inertia = 2 * r_bar, 2.0 / 3.0 * r_bar ** 3

    def path(s):
        phi = 3e-5 * math.sin(1.3 * s)                       # rigid part
        u = 1e-6 * math.sin(math.pi * s / 2) + 4e-7 * s ** 2   # stretch
        w = 8e-7 * s ** 2 - 3e-7 * math.sin(3 * s)            # sideways
        xa = xa0 + np.array([2e-4 * s, -1e-4 * s ** 3])
        xb = xa + rot(phi) @ np.array([d0 + u, w])
        tha = phi + 5e-5 * math.sin(2 * s)
        thb = phi - 7e-5 * s ** 2
        return xa, xb, tha, thb

    n_steps = 2000
    fn = fs = mm = 0.0
    prev = path(0.0)
    for k in range(1, n_steps + 1):
        s0, s1 = (k - 1) / n_steps, k / n_steps
        cur, mid = path(s1), path(0.5 * (s0 + s1))
        dr = (cur[1] - cur[0]) - (prev[1] - prev[0])          # (v_B − v_A) Δt
        rm = mid[1] - mid[0]
        n = rm / np.linalg.norm(rm)
        t = np.array([-n[1], n[0]])
        dtha, dthb = cur[2] - prev[2], cur[3] - prev[3]
        fn += KN * area * float(dr @ n)                       # F̄_n += k̄_n A ΔU_n
        fs -= KS * area * (float(dr @ t) - dthb * rb - dtha * ra)   # ΔU_s = V_s Δt
        mm -= KN * inertia * (dthb - dtha)                    # M̄ −= k̄_n I Δθ
        prev = cur
    xa, xb, tha, thb = path(1.0)
    _, _, _, _, fn_t, fs_t, m_t = one_bond(np.array([xa, xb]), theta=(tha, thb), x0=x0,
                                           radius=(ra, rb), bp=bp)
    assert abs(fn) > 1.0 and abs(fs) > 1.0 and abs(mm) > 1e-3   # all three loaded
    assert fn_t[0] == pytest.approx(fn, rel=1e-3)
    assert fs_t[0] == pytest.approx(fs, rel=1e-3)
    assert m_t[0] == pytest.approx(mm, rel=1e-9)                 # M̄ is linear in Δθ


# --- fracture ----------------------------------------------------------------------------
def _stretched(u, dth=0.0, **bp_kw):
    bp = BondParams(kn=KN, ks=KS, **bp_kw)
    return one_bond(np.array([0.1 + D0 + u, 0.2]), theta=(-dth / 2, dth / 2), bp=bp)


@pytest.mark.parametrize("factor, breaks", [(0.999999, True), (1.0, True), (1.000001, False)])
def test_tension_break_without_moment_term(factor, breaks):
    """β̄ = 0: breaks when F̄_n/A = k̄_n u ≥ σ̄_c (u = 1e-4: σ = 1e5 Pa); factor 1: σ̄_c is
    exactly the σ the code computes (the criterion is ≥)."""
    u = 1e-4
    sigma = KN * u
    if factor == 1.0:
        disp = F([[0.0, 0.0], [u, 0.0]])
        i, j = jnp.asarray([0]), jnp.asarray([1])
        d0, e0 = bonds.rest_geometry(F([[0.1, 0.2], [0.1 + D0, 0.2]]), i, j)
        bp0 = BondParams(kn=KN, ks=KS, beta_bar=0.0)
        fn, fs, m, _, _, _, a, ii, rb = bonds.bond_loads(bp0, "slab", disp, F(0.0, 0.0), F(R, R),
                                                          i, j, d0, e0)
        sigma = float(bonds.bond_stresses(bp0, fn, fs, m, a, ii, rb)[0][0])
        assert sigma == pytest.approx(KN * u, rel=1e-9)
    force, torque, alive, mode, fn, fs, m = _stretched(u, sigma_c=factor * sigma,
                                                       beta_bar=0.0)
    assert bool(alive[0]) is (not breaks)
    assert mode[0] == (1 if breaks else 0)
    if breaks:      # a bond that breaks in this evaluation exerts nothing
        np.testing.assert_array_equal(force, 0.0)
        np.testing.assert_array_equal(torque, 0.0)
        assert fn[0] == 0.0 and fs[0] == 0.0 and m[0] == 0.0
    else:
        assert fn[0] == pytest.approx(KN * AREA * u, rel=1e-9)


@pytest.mark.parametrize("beta_bar, sign, breaks", [(1.0, 1, True), (1.0, -1, True),
                                                    (0.0, 1, False), (0.5, 1, False)])
def test_tension_break_with_moment_term(beta_bar, sign, breaks):
    """σ = F̄_n/A + β̄|M̄|R̄/I = k̄_n u + β̄ k̄_n R̄ |Δθ| = 0.6 σ̄_c + β̄ 0.5 σ̄_c."""
    sigma_c = 1.0e6
    u = 0.6 * sigma_c / KN                                   # 6e-4 m
    dth = sign * 0.5 * sigma_c / (KN * R)                    # 1e-4 rad
    _, _, alive, mode, fn, fs, m = _stretched(u, dth, sigma_c=sigma_c, beta_bar=beta_bar)
    assert bool(alive[0]) is (not breaks)
    assert mode[0] == (1 if breaks else 0)
    # the stresses the criterion uses, by hand
    fn_, m_ = KN * AREA * u, -KN * INERTIA * dth
    s, tau = bonds.bond_stresses(BondParams(beta_bar=beta_bar), fn_, 0.0, m_, AREA, INERTIA, R)
    assert float(s) == pytest.approx((0.6 + beta_bar * 0.5) * sigma_c, rel=1e-9)


@pytest.mark.parametrize("factor, breaks", [(0.9999, True), (1.0001, False)])
def test_shear_break(factor, breaks):
    """B moved sideways by s: τ = |F̄_s|/A = k̄_s d0 atan(s/d0) ≥ τ̄_c breaks in shear."""
    s = 5e-5
    tau = KS * D0 * math.atan2(s, D0)                        # ≈ 2e4 Pa
    bp = BondParams(kn=KN, ks=KS, tau_c=factor * tau)
    _, _, alive, mode, fn, fs, m = one_bond(np.array([0.1 + D0, 0.2 + s]), bp=bp)
    assert bool(alive[0]) is (not breaks)
    assert mode[0] == (2 if breaks else 0)
    if not breaks:
        assert abs(fs[0]) / AREA == pytest.approx(tau, rel=1e-9)


def test_tension_takes_precedence_over_shear():
    bp = BondParams(kn=KN, ks=KS, sigma_c=1.0, tau_c=1.0)
    _, _, alive, mode, *_ = one_bond(np.array([0.1 + D0 + 1e-5, 0.2 + 1e-5]), bp=bp)
    assert not alive[0] and mode[0] == 1


def test_fracture_never_heals_and_reports_only_new_breaks():
    bp = BondParams(sigma_c=1.0, tau_c=1.0)
    intact = jnp.asarray([True, True, False, False])
    sigma = F(2.0, 0.5, 0.5, 2.0)
    tau = F(0.0, 0.0, 0.0, 2.0)
    alive, mode = bonds.fracture(bp, sigma, tau, intact)
    np.testing.assert_array_equal(alive, [False, True, False, False])
    np.testing.assert_array_equal(mode, [1, 0, 0, 0])
    # a broken bond exerts nothing even when unloaded
    force, torque, alive, mode, fn, fs, m = one_bond(np.array([0.1 + D0 + 1e-5, 0.2]),
                                                     intact=False)
    assert not alive[0] and mode[0] == 0
    np.testing.assert_array_equal(force, 0.0)
    assert fn[0] == 0.0


# --- gradient ------------------------------------------------------------------------------
def test_grad_of_bond_force_wrt_kn():
    x0 = np.array([[0.1, 0.2], [0.1 + D0, 0.2]])
    d0, e0 = bonds.rest_geometry(F(x0), jnp.asarray([0]), jnp.asarray([1]))
    disp = F([[0.0, 0.0], [1e-5, 2e-6]])

    def fx(kn):
        bp = BondParams(kn=kn, ks=KS)
        f, *_ = bonds.bond_forces(bp, "slab", 2, disp, F(1e-4, -2e-4), F(R, R),
                                  jnp.asarray([0]), jnp.asarray([1]), d0, e0,
                                  jnp.asarray([True]))
        return f[1, 0]

    g = float(jax.grad(fx)(KN))
    h = 1e-3 * KN
    fd = (float(fx(KN + h)) - float(fx(KN - h))) / (2 * h)
    assert g == pytest.approx(fd, rel=1e-8)
    assert g == pytest.approx(-AREA * 1e-5, rel=1e-3)     # ∂(−F̄_n n_x)/∂k̄_n ≈ −A u
