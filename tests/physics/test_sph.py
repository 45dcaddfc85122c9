"""Unit tests of the SPH fluid terms (fpsi_jax.sph; physics.md §SPH).

Each term is compared with a value computed here with plain Python from the formula in
physics.md, for two fluid particles and one boundary particle placed by hand; then the
conservation properties (Newton's third law, momentum of a free blob over a rollout) and the
gradients with respect to μ, c0 and α (jax.grad vs central finite differences).
"""
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from fpsi_jax import integrate, kernels, scenes, sph
from fpsi_jax.params import SphParams
from fpsi_jax.scene import NeighborConfig, Physics


pytestmark = pytest.mark.usefixtures("float64")  # conftest: x64 for this module only


RTOL = 1e-10
KERN = kernels.get("wendland")


# --- the formulas of physics.md, in plain Python -----------------------------------------
def W(r, h):
    q = r / h
    return 7.0 / (4.0 * math.pi * h * h) * (1 - q / 2) ** 4 * (2 * q + 1) if q < 2 else 0.0


def F(r, h):
    """(1/r) dW/dr of Wendland C2."""
    q = r / h
    return -35.0 / (4.0 * math.pi * h ** 4) * (1 - q / 2) ** 3 if q < 2 else 0.0


def tait(rho, rho0, c0, gamma):
    return c0 * c0 * rho0 / gamma * ((rho / rho0) ** gamma - 1.0)


class Pair:
    """Everything about the pair (i, j) that the formulas need."""

    def __init__(self, i, j, x, v, h):
        self.i, self.j = i, j
        self.xij = np.array(x[i], float) - np.array(x[j], float)
        self.vij = np.array(v[i], float) - np.array(v[j], float)
        self.r2 = float(self.xij @ self.xij)
        self.r = math.sqrt(self.r2)
        self.h = 0.5 * (h[i] + h[j])
        self.w = W(self.r, self.h)
        self.f = F(self.r, self.h)
        self.gradw = self.xij * self.f          # ∇_i W_ij


def ref_terms(i, nbrs, x, v, h, m, rho_old, rho, p, n_fluid, sp, anticlump_boundary=False):
    """Every SPH term of fluid particle i, summed over the neighbour list ``nbrs``."""
    out = dict(cont=0.0, delta=0.0, pres=np.zeros(2), clump=np.zeros(2), visc=np.zeros(2),
               av=np.zeros(2), xsph=np.zeros(2))
    for j in nbrs:
        pr = Pair(i, j, x, v, h)
        fluid_j = j < n_fluid
        # continuity (K32), volumes from the densities at the start of the step
        out["cont"] += rho_old[i] * m[j] / rho_old[j] * float(pr.vij @ pr.gradw)
        # δ-SPH (Molteni & Colagrossi): δ h c0 Σ 2(ρj−ρi) x_ji·∇W/(r²+0.01h²) V_j, fluid only
        if fluid_j:
            psi_dot = 2 * (rho_old[j] - rho_old[i]) * float(-pr.xij @ pr.gradw) / (
                pr.r2 + 0.01 * pr.h ** 2)
            out["delta"] += sp["delta"] * pr.h * sp["c0"] * psi_dot * m[j] / rho_old[j]
        # pressure (W43, K34)
        out["pres"] += -m[j] * (p[i] / rho[i] ** 2 + p[j] / rho[j] ** 2) * pr.gradw
        # anti-clump (W45, K38): R_ij = r (|Pi|/ρi² + |Pj|/ρj²)(W/W(Δp))⁴
        if fluid_j or anticlump_boundary:
            R = sp["r_clump"] * (abs(p[i]) / rho[i] ** 2 + abs(p[j]) / rho[j] ** 2) * (
                pr.w / W(sp["dp"], pr.h)) ** 4
            out["clump"] += -m[j] * R * pr.gradw
        # Morris viscosity (K36)
        out["visc"] += (m[j] * 2 * sp["mu"] * float(pr.xij @ pr.gradw)
                        / (rho[i] * rho[j] * (pr.r2 + 0.01 * pr.h ** 2)) * pr.vij)
        # Monaghan artificial viscosity
        vx = float(pr.vij @ pr.xij)
        if vx < 0:
            mu_ij = pr.h * vx / (pr.r2 + 0.01 * pr.h ** 2)
            Pi = -sp["alpha"] * sp["c0"] * mu_ij / (0.5 * (rho[i] + rho[j]))
            out["av"] += -m[j] * Pi * pr.gradw
        # XSPH (K39, Monaghan 1989), over fluid neighbours only (sph.xsph_pairs: the
        # v = 0 boundary particles would pull the transport velocity to zero at a wall)
        if fluid_j:
            out["xsph"] += -sp["eps_xsph"] * m[j] / (0.5 * (rho[i] + rho[j])) * pr.w * pr.vij
    return out


# --- the hand-placed configuration -------------------------------------------------------
# fluid 0, fluid 1, boundary 2; N = 3 so the padding index is 3
X = [[0.0, 0.0], [0.006, 0.002], [0.001, -0.005]]
V = [[0.3, -0.1], [-0.2, 0.4], [0.0, 0.0]]
Hs = [0.005, 0.006, 0.0045]
M = [0.025, 0.027, 0.020]
RHO_OLD = [1003.0, 997.0, 1000.0]    # densities at the start of the step (pair volumes)
RHO = [1004.0, 995.0, 1001.0]        # densities at the new level (momentum)
P = [300.0, -150.0, 500.0]           # pressures at the new level (P_1 < 0: |P| matters)
NF = 2
NBRS = {0: [1, 2], 1: [0, 2]}
IDX = [[1, 2, 3], [0, 2, 3]]         # Dense rows of the fluid, one padded slot each
SP = dict(rho0=1000.0, c0=20.0, gamma=7.0, mu=0.02, r_clump=0.01, dp=0.004,
          eps_xsph=0.5, delta=0.1, alpha=0.3)
G = np.array([0.0, -9.81])


def _phys(n_fluid=NF, n_boundary=1, **flags):
    nb = NeighborConfig(r_cut=0.02, skin=0.0, origin=(0.0, 0.0), box=(1.0, 1.0))
    return Physics(n_fluid=n_fluid, n_boundary=n_boundary, neighbors=nb, **flags)


def _sp(**kw):
    return SphParams(**{k: jnp.float64(v) for k, v in {**SP, **kw}.items()})


def _a(v, dtype=jnp.float64):
    return jnp.asarray(np.asarray(v), dtype=dtype)


def _pairs(idx=IDX, v=V):
    return sph.pairs(KERN, NF, _a(X), _a(v), _a(Hs), _a(M), _a(RHO_OLD),
                     jnp.asarray(idx, jnp.int32))


def _ref(i, sp=SP, **kw):
    return ref_terms(i, NBRS[i], X, V, Hs, M, RHO_OLD, RHO, P, NF, sp, **kw)


def _momentum(phys, sp=None, gravity=(0.0, 0.0), idx=IDX, p=P):
    sp = _sp() if sp is None else sp
    return sph.momentum_rate(phys, KERN, sp, _a(gravity), _a(RHO), _a(p), _pairs(idx))[:2]


def test_module_runs_in_float64():
    assert _pairs().w.dtype == jnp.float64


def test_configuration_is_inside_the_support():
    """Guard: every listed pair interacts, so no test below is vacuous."""
    for i, nb in NBRS.items():
        for j in nb:
            pr = Pair(i, j, X, V, Hs)
            assert pr.r < 1.9 * pr.h and pr.w > 0 and pr.f < 0


# --- equation of state -------------------------------------------------------------------
def test_eos_known_value():
    p = float(sph.eos_pressure(jnp.float64(1010.0), 1000.0, 20.0, 7.0))
    b = 20.0 ** 2 * 1000.0 / 7.0
    assert p == pytest.approx(b * (1.01 ** 7 - 1.0), rel=1e-13)
    assert p == pytest.approx(4122.0201, rel=1e-7)   # 57142.857 × 0.0721354
    assert float(sph.eos_pressure(jnp.float64(1000.0), 1000.0, 20.0, 7.0)) == 0.0
    assert float(sph.eos_density(jnp.float64(p), 1000.0, 20.0, 7.0)) == pytest.approx(
        1010.0, rel=1e-13)
    assert float(sph.eos_density(jnp.float64(0.0), 1000.0, 20.0, 7.0)) == 1000.0


def test_eos_inverse_of_each_other():
    rho = jnp.linspace(950.0, 1080.0, 27)
    p = sph.eos_pressure(rho, 1000.0, 35.0, 7.0)
    np.testing.assert_allclose(np.asarray(sph.eos_density(p, 1000.0, 35.0, 7.0)),
                               np.asarray(rho), rtol=1e-13)
    pp = jnp.linspace(-5e4, 5e5, 31)
    np.testing.assert_allclose(
        np.asarray(sph.eos_pressure(sph.eos_density(pp, 1000.0, 35.0, 7.0), 1000.0, 35.0,
                                    7.0)), np.asarray(pp), rtol=1e-10, atol=1e-8)
    # γ = 1: linear EOS P = c0²(ρ − ρ0)
    assert float(sph.eos_pressure(jnp.float64(1002.0), 1000.0, 10.0, 1.0)) == pytest.approx(
        200.0, rel=1e-13)


def test_eos_density_clamped_for_tension_below_minus_b():
    b = 20.0 ** 2 * 1000.0 / 7.0
    rho = float(sph.eos_density(jnp.float64(-3.0 * b), 1000.0, 20.0, 7.0))
    assert math.isfinite(rho) and rho == pytest.approx(1000.0 * 1e-6 ** (1 / 7), rel=1e-12)


# --- pair geometry -----------------------------------------------------------------------
def test_pairs_geometry():
    pr = _pairs()
    for i, nb in NBRS.items():
        for k, j in enumerate(nb):
            ref = Pair(i, j, X, V, Hs)
            np.testing.assert_allclose(np.asarray(pr.dx[i, k]), ref.xij, rtol=1e-14)
            np.testing.assert_allclose(np.asarray(pr.vij[i, k]), ref.vij, rtol=1e-14)
            assert float(pr.r2[i, k]) == pytest.approx(ref.r2, rel=1e-13)
            assert float(pr.hij[i, k]) == pytest.approx(ref.h, rel=1e-14)
            assert float(pr.w[i, k]) == pytest.approx(ref.w, rel=1e-12)
            assert float(pr.f[i, k]) == pytest.approx(ref.f, rel=1e-12)
            assert float(pr.m_j[i, k]) == M[j]
            assert float(pr.rho_j[i, k]) == RHO_OLD[j]
            assert bool(pr.fluid_j[i, k]) == (j < NF)
    # the padded slot
    assert np.all(np.asarray(pr.w[:, 2]) == 0.0)
    assert np.all(np.asarray(pr.f[:, 2]) == 0.0)
    assert not np.any(np.asarray(pr.fluid_j[:, 2]))


# --- density rate ------------------------------------------------------------------------
def test_continuity():
    got = np.asarray(sph.continuity(_a(RHO_OLD[:NF]), _pairs()))
    want = [_ref(i)["cont"] for i in range(NF)]
    assert all(abs(w) > 1e-3 for w in want)
    np.testing.assert_allclose(got, want, rtol=RTOL)
    # density_rate without δ-SPH is the continuity equation alone
    got2 = sph.density_rate(_phys(delta_sph=False), _sp(), _a(RHO_OLD[:NF]), _pairs())
    np.testing.assert_array_equal(np.asarray(got2), got)


def test_continuity_rigid_motion_is_zero():
    """A uniform translation does not compress the fluid."""
    v = [[0.7, -0.3]] * 3
    got = sph.continuity(_a(RHO_OLD[:NF]), _pairs(v=v))
    np.testing.assert_allclose(np.asarray(got), 0.0, atol=1e-12)


def test_delta_diffusion():
    phys = _phys(delta_sph=True)
    got = np.asarray(sph.density_rate(phys, _sp(), _a(RHO_OLD[:NF]), _pairs()))
    want = [_ref(i)["cont"] + _ref(i)["delta"] for i in range(NF)]
    np.testing.assert_allclose(got, want, rtol=RTOL)
    d = np.asarray(sph.delta_diffusion(0.1, 20.0, _a(RHO_OLD[:NF]), _pairs()))
    np.testing.assert_allclose(d, [_ref(i)["delta"] for i in range(NF)], rtol=RTOL)
    # diffusion: the denser particle (0) loses density, the lighter one (1) gains it, and
    # the fluid–fluid exchange is antisymmetric: Σ_i V_i Dρ_i/Dt = 0 with V_i = m_i/ρ_i
    assert d[0] < 0 < d[1]
    vol = np.asarray(M[:NF]) / np.asarray(RHO_OLD[:NF])
    assert abs(vol @ d) < 1e-12 * np.sum(np.abs(vol * d))


# --- momentum ----------------------------------------------------------------------------
OFF = dict(anticlump=False, artificial_viscosity=False, xsph=False)


def test_pressure_acc():
    acc, xs = _momentum(_phys(**OFF), _sp(mu=0.0))
    want = np.array([_ref(i)["pres"] for i in range(NF)])
    assert np.all(np.abs(want) > 1e-3)
    np.testing.assert_allclose(np.asarray(acc), want, rtol=RTOL)
    np.testing.assert_array_equal(np.asarray(xs), 0.0)   # XSPH off → zero correction


def test_pressure_acc_two_particles_closed_form():
    """Two particles a distance h apart (q = 1): a_0 = −m(P0/ρ0² + P1/ρ1²) x_01 F(h)."""
    h, m, p, rho = 0.01, 0.1, 1000.0, 1000.0
    x = _a([[0.0, 0.0], [h, 0.0]])
    pr = sph.pairs(KERN, 2, x, jnp.zeros((2, 2)), _a([h, h]), _a([m, m]), _a([rho, rho]),
                   jnp.asarray([[1], [0]]))
    acc, _, _ = sph.momentum_rate(_phys(n_fluid=2, n_boundary=0, **OFF), KERN, _sp(mu=0.0),
                               _a([0.0, 0.0]), _a([rho, rho]), _a([p, p]), pr)
    f = -35.0 / (32.0 * math.pi * h ** 4)       # F at q = 1: −35/(4πh⁴)·(1/2)³
    ax = -m * (2 * p / rho ** 2) * (-h) * f     # x_01 = (−h, 0): pushes 0 to −x
    np.testing.assert_allclose(np.asarray(acc), [[ax, 0.0], [-ax, 0.0]], rtol=1e-13)
    assert ax < 0


def test_gravity_is_added():
    acc0, _ = _momentum(_phys(**OFF), _sp(mu=0.0))
    acc1, _ = _momentum(_phys(**OFF), _sp(mu=0.0), gravity=G)
    np.testing.assert_allclose(np.asarray(acc1 - acc0), np.tile(G, (NF, 1)), rtol=1e-12,
                               atol=1e-12)


def test_viscous_acc_morris():
    acc, _ = _momentum(_phys(**OFF), p=[0.0, 0.0, 0.0])     # P = 0: viscosity alone
    want = np.array([_ref(i)["visc"] for i in range(NF)])
    assert np.all(np.abs(want) > 1e-6)
    np.testing.assert_allclose(np.asarray(acc), want, rtol=RTOL)
    # the function itself, with distinct μ_i, μ_j
    pr = _pairs()
    rho_j = sph.gather(_a(RHO), pr.idx)
    got = sph.viscous_acc(0.01, 0.03, _a(RHO[:NF]), rho_j, pr)
    np.testing.assert_allclose(np.asarray(got), want, rtol=RTOL)   # μ_i + μ_j = 2·0.02


def test_viscous_acc_opposes_relative_motion():
    """Morris viscosity of a single pair: a_i = −k v_ij with k > 0 (drag towards v_j)."""
    acc, _ = _momentum(_phys(**OFF), p=[0.0, 0.0, 0.0], idx=[[1, 3], [0, 3]])
    a = np.asarray(acc)
    v01 = np.asarray(V[0]) - np.asarray(V[1])
    k0 = -(a[0] @ v01) / (v01 @ v01)
    assert k0 > 0
    np.testing.assert_allclose(a[0], -k0 * v01, rtol=1e-12)
    np.testing.assert_allclose(M[0] * a[0], -M[1] * a[1], rtol=1e-12)   # action = reaction


def test_anticlump():
    base, _ = _momentum(_phys(**OFF))
    on, _ = _momentum(_phys(**{**OFF, "anticlump": True}))
    want = np.array([_ref(i)["clump"] for i in range(NF)])
    assert np.all(np.abs(want) > 0)
    np.testing.assert_allclose(np.asarray(on - base), want, rtol=1e-8,
                               atol=1e-12 * np.max(np.abs(want)))
    # the fluid–boundary pair is excluded unless anticlump_boundary
    on_b, _ = _momentum(_phys(**{**OFF, "anticlump": True, "anticlump_boundary": True}))
    want_b = np.array([_ref(i, anticlump_boundary=True)["clump"] for i in range(NF)])
    assert not np.allclose(want_b, want)
    np.testing.assert_allclose(np.asarray(on_b - base), want_b, rtol=1e-8,
                               atol=1e-12 * np.max(np.abs(want_b)))


def test_anticlump_function():
    pr = _pairs()
    rp = sph.gather(jnp.stack([_a(RHO), _a(P)], axis=1), pr.idx)
    w_dp = KERN.w(SP["dp"], pr.hij)
    r = np.asarray(sph.anticlump(SP["r_clump"], _a(P[:NF]), _a(RHO[:NF]), rp[..., 1],
                                 rp[..., 0], pr.w, w_dp))
    for i, nb in NBRS.items():
        for k, j in enumerate(nb):
            q = Pair(i, j, X, V, Hs)
            want = SP["r_clump"] * (abs(P[i]) / RHO[i] ** 2 + abs(P[j]) / RHO[j] ** 2) * (
                q.w / W(SP["dp"], q.h)) ** 4
            assert r[i, k] == pytest.approx(want, rel=1e-12)
        assert r[i, 2] == 0.0                 # padded slot


def test_artificial_viscosity():
    base, _ = _momentum(_phys(**OFF))
    on, _ = _momentum(_phys(**{**OFF, "artificial_viscosity": True}))
    want = np.array([_ref(i)["av"] for i in range(NF)])
    np.testing.assert_allclose(np.asarray(on - base), want, rtol=1e-8,
                               atol=1e-12 * np.max(np.abs(want)))
    # pair (1, 2) separates (v_12·x_12 > 0) and must not contribute; (0,1), (0,2) approach
    assert float(Pair(1, 2, X, V, Hs).vij @ Pair(1, 2, X, V, Hs).xij) > 0
    pr = _pairs()
    rho_j = sph.gather(_a(RHO), pr.idx)
    one = sph.artificial_viscosity(SP["alpha"], SP["c0"], _a(RHO[:NF]), rho_j, pr)
    np.testing.assert_allclose(np.asarray(one), want, rtol=RTOL)
    # only the approaching pair (1, 0) acts on particle 1: −m_0 Π_10 ∇_1W_10
    q = Pair(1, 0, X, V, Hs)
    pi10 = (-SP["alpha"] * SP["c0"] * q.h * float(q.vij @ q.xij)
            / (q.r2 + 0.01 * q.h ** 2) / (0.5 * (RHO[1] + RHO[0])))
    assert pi10 > 0
    np.testing.assert_allclose(np.asarray(one)[1], -M[0] * pi10 * q.gradw, rtol=RTOL)
    # α = 0 switches it off exactly
    zero = sph.artificial_viscosity(0.0, SP["c0"], _a(RHO[:NF]), rho_j, pr)
    np.testing.assert_array_equal(np.asarray(zero), 0.0)


def _wall_pair(r, r0=0.0032, p=(0.0, 0.0), beta=0.05):
    """Fluid 0 at the origin, boundary particle 1 at (r, 0); pressures ``p``. Returns the
    backstop's part of a_0 (the step with it minus the step without)."""
    x = _a([[0.0, 0.0], [r, 0.0]])
    pr = sph.pairs(KERN, 1, x, jnp.zeros((2, 2)), _a([0.004, 0.004]), _a([0.016, 0.016]),
                   _a([1000.0, 1000.0]), jnp.asarray([[1]]))
    sp = _sp(mu=0.0, wall_beta=beta)
    out = {}
    for on in (False, True):
        phys = _phys(n_fluid=1, n_boundary=1, wall_repulsion=on, wall_range=r0, **OFF)
        acc, _, _ = sph.momentum_rate(phys, KERN, sp, _a([0.0, 0.0]), _a([1000.0, 1000.0]),
                                      _a(p), pr)
        out[on] = np.asarray(acc)[0]
    return out[True] - out[False]


def test_wall_repulsion_two_particles_closed_form():
    """a_i = (β c0²/r0²)(1 − r²/r0²)² x_ij inside r0, zero outside and with β = 0."""
    beta, c0, r0 = 0.05, SP["c0"], 0.0032
    for r in (0.25 * r0, 0.5 * r0, 0.9 * r0):
        want = beta * c0 ** 2 / r0 ** 2 * (1 - r * r / r0 ** 2) ** 2 * (-r)  # x_01 = (−r, 0)
        np.testing.assert_allclose(_wall_pair(r), [want, 0.0], rtol=1e-12)
        assert want < 0                                                # pushed away, to −x
    assert np.all(_wall_pair(1.001 * r0) == 0.0) and np.all(_wall_pair(0.006) == 0.0)
    # independent of the pressures; off with β = 0 or without a range
    np.testing.assert_allclose(_wall_pair(0.5 * r0, p=(-400.0, 0.0)), _wall_pair(0.5 * r0),
                               rtol=1e-12)
    assert np.all(_wall_pair(0.5 * r0, beta=0.0) == 0.0)
    assert np.all(_wall_pair(0.5 * r0, r0=0.0) == 0.0)


def test_wall_repulsion_is_the_gradient_of_its_potential():
    """Conservative: a = −dU/dr along x_ij/r with U = β c0²/6 (1 − r²/r0²)³ (checked by
    central differences of U), so a particle can bounce off it without gaining energy."""
    beta, c0, r0 = 0.05, SP["c0"], 0.0032
    U = lambda r: beta * c0 ** 2 / 6 * max(1 - r * r / r0 ** 2, 0.0) ** 3
    for r in (0.3 * r0, 0.7 * r0):
        e = 1e-8
        np.testing.assert_allclose(-_wall_pair(r)[0], -(U(r + e) - U(r - e)) / (2 * e),
                                   rtol=1e-6)


def test_wall_repulsion_gradient_matches_finite_differences():
    """d a_0/d(r, β, c0) of the backstop by jax.grad equals central differences."""
    r0 = 0.0032

    def acc(theta):
        r, beta, c0 = theta
        x = jnp.stack([jnp.zeros(2), jnp.stack([r, 0.3 * r])])
        pr = sph.pairs(KERN, 1, x, jnp.zeros((2, 2)), _a([0.004, 0.004]),
                       _a([0.016, 0.016]), _a([1000.0, 1000.0]), jnp.asarray([[1]]))
        sp = _sp(mu=0.0).replace(wall_beta=beta, c0=c0)
        phys = _phys(n_fluid=1, n_boundary=1, wall_repulsion=True, wall_range=r0, **OFF)
        a, _, _ = sph.momentum_rate(phys, KERN, sp, _a([0.0, 0.0]), _a([1000.0, 1000.0]),
                                    _a([0.0, 0.0]), pr)
        return a[0, 0] + 2.0 * a[0, 1]

    theta = jnp.asarray([0.5 * r0, 0.05, 20.0])
    g = np.asarray(jax.grad(acc)(theta))
    for k, e in enumerate([1e-8, 1e-6, 1e-4]):
        d = np.zeros(3)
        d[k] = e
        fd = (float(acc(theta + d)) - float(acc(theta - d))) / (2 * e)
        np.testing.assert_allclose(g[k], fd, rtol=1e-5)
    assert np.all(g != 0.0)


def test_wall_range_from_the_scene_and_its_time_step_bound():
    """r0 = 0.8 min(√(m_b/ρ0), Δp); the derived step respects Δt ≤ r0/(c0 √β)."""
    sc = scenes.build("dam_break", dx=0.01, dx_boundary=0.005)
    np.testing.assert_allclose(sc.wall_range(), 0.8 * 0.005, rtol=1e-12)
    assert Physics.for_scene(sc).wall_range == sc.wall_range()
    sc = scenes.build("dam_break", dx=0.01)
    np.testing.assert_allclose(sc.wall_range(), 0.8 * 0.01, rtol=1e-12)
    sp = sc.params.sph
    strong = sc.params.replace(sph=sp.replace(wall_beta=1.0))     # binding for β = 1
    bound = sc.wall_range() / float(sp.c0)
    assert integrate.sph_dt(sc, strong) <= bound * (1 + 1e-12)
    np.testing.assert_allclose(integrate.sph_dt(sc, strong), bound, rtol=1e-12)


def test_wall_repulsion_only_acts_on_fixed_boundary_neighbours():
    """Fluid–fluid pairs closer than r0 feel nothing from it (only j in the boundary)."""
    r = 0.5 * 0.0032
    x = _a([[0.0, 0.0], [r, 0.0]])
    pr = sph.pairs(KERN, 2, x, jnp.zeros((2, 2)), _a([0.004, 0.004]), _a([0.016, 0.016]),
                   _a([1000.0, 1000.0]), jnp.asarray([[1], [0]]))
    accs = [np.asarray(sph.momentum_rate(_phys(n_fluid=2, n_boundary=0, wall_repulsion=on,
                                               wall_range=0.0032, **OFF), KERN,
                                         _sp(mu=0.0), _a([0.0, 0.0]), _a([1000.0, 1000.0]),
                                         _a([0.0, 0.0]), pr)[0])
            for on in (False, True)]
    np.testing.assert_array_equal(accs[0], accs[1])


@pytest.mark.parametrize("name", ["dam_break", "hydrostatic_tank"])
def test_wall_repulsion_is_zero_at_rest(name):
    """In the builders' initial states no fluid particle is inside r0 of a wall particle,
    so the backstop adds exactly nothing there (it is a safeguard, not a model change)."""
    scene = scenes.build(name, dx=0.02)
    on, off = (integrate.init_state(scene, Physics.for_scene(scene, wall_repulsion=w),
                                    scene.params) for w in (True, False))
    np.testing.assert_array_equal(np.asarray(on.fluid.acc), np.asarray(off.fluid.acc))


def test_xsph_correction():
    _, xs = _momentum(_phys(**{**OFF, "xsph": True}))
    want = np.array([_ref(i)["xsph"] for i in range(NF)])
    assert np.all(np.abs(want) > 0)
    np.testing.assert_allclose(np.asarray(xs), want, rtol=RTOL)
    # by hand for particle 0: only its fluid neighbour 1 counts, the boundary particle 2 not
    q = Pair(0, 1, X, V, Hs)
    x0 = -SP["eps_xsph"] * M[1] / (0.5 * (RHO[0] + RHO[1])) * q.w * q.vij
    np.testing.assert_allclose(np.asarray(xs)[0], x0, rtol=RTOL)
    _, xs_f = _momentum(_phys(**{**OFF, "xsph": True}), idx=[[1, 3, 3], [0, 3, 3]])
    np.testing.assert_array_equal(np.asarray(xs), np.asarray(xs_f))
    # the fluid pair alone: m_0 δv_0 = −m_1 δv_1 (XSPH redistributes, no net transport)
    xs_np = np.asarray(xs)
    np.testing.assert_allclose(M[0] * xs_np[0], -M[1] * xs_np[1], rtol=1e-12)


def test_all_terms_together():
    phys = _phys(anticlump=True, artificial_viscosity=True, xsph=True)
    acc, xs = _momentum(phys, gravity=G)
    want = np.array([sum(_ref(i)[k] for k in ("pres", "clump", "visc", "av")) + G
                     for i in range(NF)])
    np.testing.assert_allclose(np.asarray(acc), want, rtol=1e-9)
    np.testing.assert_allclose(np.asarray(xs), [_ref(i)["xsph"] for i in range(NF)],
                               rtol=RTOL)


def test_smoothing_length_rate():
    h, rho, drho = 0.005, 1002.0, -37.5
    got = float(sph.smoothing_length_rate(jnp.float64(h), jnp.float64(rho),
                                          jnp.float64(drho)))
    assert got == pytest.approx(-h / (2.0 * rho) * drho, rel=1e-14)
    assert got > 0        # expansion (Dρ/Dt < 0) grows h
    got3 = float(sph.smoothing_length_rate(jnp.float64(h), jnp.float64(rho),
                                           jnp.float64(drho), n_d=3.0))
    assert got3 == pytest.approx(-h / (3.0 * rho) * drho, rel=1e-14)
    # keeps h ρ^(1/n_d) constant: d/dt (h ρ^(1/2)) = 0
    assert got * math.sqrt(rho) + h * 0.5 / math.sqrt(rho) * drho == pytest.approx(0.0,
                                                                                   abs=1e-15)


# --- padding -----------------------------------------------------------------------------
def test_padded_slots_contribute_exactly_zero():
    phys = _phys(anticlump=True, anticlump_boundary=True, artificial_viscosity=True,
                 xsph=True, delta_sph=True)
    sp = _sp()
    idx_lists = {
        "none": [[1, 2], [0, 2]],
        "one": IDX,
        "three": [[1, 3, 2, 3, 3], [3, 0, 3, 2, 3]],
    }
    out = {}
    for k, idx in idx_lists.items():
        pr = _pairs(idx)
        drho = sph.density_rate(phys, sp, _a(RHO_OLD[:NF]), pr)
        acc, xs, _ = sph.momentum_rate(phys, KERN, sp, _a(G), _a(RHO), _a(P), pr)
        out[k] = (np.asarray(drho), np.asarray(acc), np.asarray(xs))
        pad = np.asarray(pr.idx) == 3
        assert np.all(np.asarray(pr.w)[pad] == 0.0) and np.all(np.asarray(pr.f)[pad] == 0.0)
    for k in ("one", "three"):
        for a, b in zip(out[k], out["none"]):
            assert np.all(np.isfinite(a))
            np.testing.assert_allclose(a, b, rtol=1e-15, atol=0)


# --- extrapolated boundary pressure (Adami et al. 2012) ----------------------------------
XB = [[-0.002, 0.003], [0.0025, 0.004], [0.0, -0.001], [0.004, -0.001], [0.5, 0.5]]
HB = [0.004, 0.0045, 0.0035, 0.004, 0.004]
RHOB = [1002.0, 1001.0, 1234.0, 987.0, 1000.0]   # boundary entries must not be used
PB = [150.0, 80.0, 9999.0, -777.0, 0.0]
NFB = 2
IDXB = [[0, 1, 3, 5], [0, 1, 2, 5], [5, 5, 5, 5]]   # rows: boundary 2, 3, 4 (4 is alone)


def _ref_pb(b, fluid, p, g=G, a_b=(0.0, 0.0)):
    num = den = 0.0
    gma = np.asarray(g, float) - np.asarray(a_b, float)
    for f in fluid:
        xbf = np.asarray(XB[b]) - np.asarray(XB[f])
        w = W(math.hypot(*xbf), 0.5 * (HB[b] + HB[f]))
        num += p[f] * w + float(gma @ xbf) * RHOB[f] * w
        den += w
    return max(num / den, 0.0) if den > 0 else 0.0


def _pb(p=PB, g=G, acc_b=None, idx=IDXB):
    return sph.extrapolated_boundary_pressure(
        NFB, KERN, _sp(), _a(g), _a(XB), _a(HB), _a(RHOB), _a(p), jnp.asarray(idx),
        acc_b=None if acc_b is None else _a(acc_b))


def test_extrapolated_boundary_pressure():
    pb, rhob = (np.asarray(a) for a in _pb())
    want = [_ref_pb(2, [0, 1], PB), _ref_pb(3, [0, 1], PB), 0.0]
    # the hydrostatic term really matters: the wall below the fluid sees more than Σ PW/ΣW
    no_g = _ref_pb(2, [0, 1], PB, g=(0.0, 0.0))
    assert want[0] > no_g > 0
    assert want[0] - no_g == pytest.approx(
        sum(9.81 * (XB[f][1] - XB[2][1]) * RHOB[f]
            * W(math.dist(XB[2], XB[f]), 0.5 * (HB[2] + HB[f])) for f in (0, 1))
        / sum(W(math.dist(XB[2], XB[f]), 0.5 * (HB[2] + HB[f])) for f in (0, 1)), rel=1e-12)
    np.testing.assert_allclose(pb, want, rtol=RTOL, atol=1e-12)
    np.testing.assert_allclose(rhob, [float(sph.eos_density(jnp.float64(p), 1000.0, 20.0, 7.0))
                                      for p in want], rtol=1e-13)
    assert rhob[2] == 1000.0                  # no fluid neighbour: P = 0, ρ = ρ0


def test_extrapolated_boundary_pressure_wall_acceleration():
    """A wall accelerating with g feels no hydrostatic correction: (g − a_b) = 0."""
    acc_b = np.tile(G, (3, 1))
    pb = np.asarray(_pb(acc_b=acc_b)[0])
    want = [_ref_pb(b, [0, 1], PB, a_b=G) for b in (2, 3)]
    np.testing.assert_allclose(pb[:2], want, rtol=RTOL)
    np.testing.assert_allclose(pb[:2], [_ref_pb(b, [0, 1], PB, g=(0, 0)) for b in (2, 3)],
                               rtol=RTOL)


def test_extrapolated_boundary_pressure_clamped_at_zero():
    p_neg = [-3000.0, -2500.0, 0.0, 0.0, 0.0]
    pb, rhob = (np.asarray(a) for a in _pb(p=p_neg))
    raw = [sum(
        (p_neg[f] + float(G @ (np.asarray(XB[b]) - np.asarray(XB[f]))) * RHOB[f])
        * W(math.dist(XB[b], XB[f]), 0.5 * (HB[b] + HB[f])) for f in (0, 1)) for b in (2, 3)]
    assert all(r < 0 for r in raw)            # the unclamped Adami value is a suction
    np.testing.assert_array_equal(pb, 0.0)
    np.testing.assert_array_equal(rhob, 1000.0)


def test_extrapolated_boundary_pressure_padding_exact():
    a = [np.asarray(t) for t in _pb(idx=[[0, 1], [0, 1], [5, 5]])]
    b = [np.asarray(t) for t in _pb(idx=[[5, 0, 5, 5, 1, 3], [2, 5, 1, 0, 5, 5],
                                         [5, 5, 5, 5, 5, 5]])]
    for u, w in zip(a, b):
        np.testing.assert_allclose(u, w, rtol=1e-15, atol=0)


# --- Newton's third law ------------------------------------------------------------------
def _random_blob(n_x=10, n_y=5, seed=0):
    rng = np.random.default_rng(seed)
    dp = 0.005
    gx, gy = np.meshgrid(np.arange(n_x), np.arange(n_y), indexing="ij")
    x = np.stack([gx.ravel(), gy.ravel()], 1) * dp + rng.uniform(-0.3, 0.3, (n_x * n_y, 2)) * dp
    n = x.shape[0]
    h = 1.3 * dp * rng.uniform(0.9, 1.1, n)
    v = rng.normal(0.0, 0.5, (n, 2))
    m = 1000.0 * dp * dp * rng.uniform(0.9, 1.1, n)
    rho_old = 1000.0 * rng.uniform(0.99, 1.01, n)
    rho = 1000.0 * rng.uniform(0.99, 1.01, n)
    # brute-force Dense list: all j ≠ i within 2 max(h), padded with N
    d = np.linalg.norm(x[:, None] - x[None], axis=-1)
    near = (d < 2.0 * h.max()) & ~np.eye(n, dtype=bool)
    k = int(near.sum(1).max())
    idx = np.full((n, k + 2), n, np.int32)
    for i in range(n):
        js = rng.permutation(np.flatnonzero(near[i]))
        idx[i, :len(js)] = js
    return dict(x=x, v=v, h=h, m=m, rho_old=rho_old, rho=rho, idx=idx, dp=dp)


ALL_ON = dict(anticlump=True, artificial_viscosity=True, xsph=True, delta_sph=True)


def test_newton_third_law_random_configuration():
    c = _random_blob()
    n = c["x"].shape[0]
    assert n == 50 and c["idx"].shape[1] > 8
    sp = _sp(dp=c["dp"], mu=0.05, alpha=0.5, c0=30.0, r_clump=0.2)
    p = np.asarray(sph.eos_pressure(_a(c["rho"]), 1000.0, 30.0, 7.0))
    assert p.min() < 0 < p.max()          # tension and compression: |P| in R_ij matters
    pr = sph.pairs(KERN, n, _a(c["x"]), _a(c["v"]), _a(c["h"]), _a(c["m"]),
                   _a(c["rho_old"]), jnp.asarray(c["idx"]))
    phys = _phys(n_fluid=n, n_boundary=0, **ALL_ON)
    acc, xs, _ = sph.momentum_rate(phys, KERN, sp, _a([0.0, 0.0]), _a(c["rho"]), _a(p), pr)
    ma = c["m"][:, None] * np.asarray(acc)
    assert np.sum(np.abs(ma)) > 0
    assert np.all(np.abs(ma.sum(0)) < 1e-12 * np.sum(np.abs(ma)))
    # each term on its own, too
    for flags, kw in [(OFF, dict(mu=0.0)), (OFF, dict(r_clump=0.0)),
                      ({**OFF, "anticlump": True}, dict(mu=0.0)),
                      ({**OFF, "artificial_viscosity": True}, dict(mu=0.0))]:
        a1, _, _ = sph.momentum_rate(_phys(n_fluid=n, n_boundary=0, **flags), KERN,
                                  sp.replace(**{k: jnp.float64(v) for k, v in kw.items()}),
                                  _a([0.0, 0.0]), _a(c["rho"]), _a(p), pr)
        ma1 = c["m"][:, None] * np.asarray(a1)
        assert np.sum(np.abs(ma1)) > 0
        assert np.all(np.abs(ma1.sum(0)) < 1e-12 * np.sum(np.abs(ma1))), flags
    # XSPH moves positions, but its mass-weighted sum vanishes as well
    mx = c["m"][:, None] * np.asarray(xs)
    assert np.all(np.abs(mx.sum(0)) < 1e-12 * np.sum(np.abs(mx)))
    # pressure, anti-clump and artificial viscosity are central forces: no net torque
    a_c, _, _ = sph.momentum_rate(
        _phys(n_fluid=n, n_boundary=0, anticlump=True, artificial_viscosity=True,
              xsph=False), KERN, sp.replace(mu=jnp.float64(0.0)), _a([0.0, 0.0]),
        _a(c["rho"]), _a(p), pr)
    ma_c = c["m"][:, None] * np.asarray(a_c)
    torque = np.sum(c["x"][:, 0] * ma_c[:, 1] - c["x"][:, 1] * ma_c[:, 0])
    scale = np.sum(np.abs(c["x"][:, 0] * ma_c[:, 1]) + np.abs(c["x"][:, 1] * ma_c[:, 0]))
    assert abs(torque) < 1e-12 * scale


def test_newton_third_law_matches_reference_sums():
    """The same random blob, particle by particle against the Python formulas."""
    c = _random_blob(n_x=4, n_y=4, seed=3)
    n = c["x"].shape[0]
    spd = {**SP, "dp": c["dp"], "mu": 0.05, "alpha": 0.5, "r_clump": 0.2}
    p = [tait(r, 1000.0, 20.0, 7.0) for r in c["rho"]]
    pr = sph.pairs(KERN, n, _a(c["x"]), _a(c["v"]), _a(c["h"]), _a(c["m"]),
                   _a(c["rho_old"]), jnp.asarray(c["idx"]))
    phys = _phys(n_fluid=n, n_boundary=0, **ALL_ON)
    acc, xs, _ = sph.momentum_rate(phys, KERN, _sp(**spd), _a([0.0, 0.0]), _a(c["rho"]),
                                _a(p), pr)
    drho = sph.density_rate(phys, _sp(**spd), _a(c["rho_old"]), pr)
    for i in range(n):
        nb = [int(j) for j in c["idx"][i] if j < n]
        ref = ref_terms(i, nb, c["x"], c["v"], c["h"], c["m"], c["rho_old"], c["rho"], p, n,
                        spd)
        a_ref = ref["pres"] + ref["clump"] + ref["visc"] + ref["av"]
        np.testing.assert_allclose(np.asarray(acc[i]), a_ref, rtol=1e-9,
                                   atol=1e-11 * np.abs(a_ref).max())
        np.testing.assert_allclose(np.asarray(xs[i]), ref["xsph"], rtol=1e-9,
                                   atol=1e-12 * np.abs(ref["xsph"]).max())
        assert float(drho[i]) == pytest.approx(ref["cont"] + ref["delta"], rel=1e-9,
                                               abs=1e-9 * abs(ref["cont"]))


# --- rollout: momentum of a free blob ----------------------------------------------------
_rollout = jax.jit(integrate.rollout, static_argnums=(0, 3))


def test_rollout_conserves_momentum_of_free_blob():
    scene = scenes.build("hydrostatic_tank", dx=0.01, depth=0.1, width=0.1)
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
    params = scene.params.replace(dt=integrate.stable_dt(scene)).as_arrays(jnp.float64)
    state = integrate.init_state(scene, phys, params)
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


# --- gradients ---------------------------------------------------------------------------
def _fd_check(loss, theta, rel_step=1e-5, tol=1e-5):
    """jax.grad of ``loss`` at ``theta`` vs a central difference with steps rel_step·θ_k
    (the 2·len(θ) forward evaluations run as one vmapped, compiled call)."""
    theta = jnp.asarray(theta, jnp.float64)
    n = theta.shape[0]
    g = np.asarray(jax.jit(jax.grad(loss))(theta))
    steps = rel_step * np.asarray(theta)
    pts = theta + jnp.concatenate([jnp.diag(steps), -jnp.diag(steps)])
    f = np.asarray(jax.jit(jax.vmap(loss))(pts))
    fd = (f[:n] - f[n:]) / (2.0 * steps)
    assert np.all(np.isfinite(g)) and np.all(g != 0.0), g
    np.testing.assert_allclose(g, fd, rtol=tol, atol=0)
    return g


def test_gradient_of_momentum_rate_wrt_mu_c0_alpha():
    c = _random_blob(n_x=5, n_y=4, seed=7)
    n = c["x"].shape[0]
    pr = sph.pairs(KERN, n, _a(c["x"]), _a(c["v"]), _a(c["h"]), _a(c["m"]),
                   _a(c["rho_old"]), jnp.asarray(c["idx"]))
    phys = _phys(n_fluid=n, n_boundary=0, **ALL_ON)
    rho = _a(c["rho"])

    def loss(theta):
        mu, c0, alpha = theta
        sp = _sp(dp=c["dp"]).replace(mu=mu, c0=c0, alpha=alpha)
        p = sph.eos_pressure(rho, sp.rho0, c0, sp.gamma)
        acc, _, _ = sph.momentum_rate(phys, KERN, sp, _a([0.0, 0.0]), rho, p, pr)
        return jnp.sum(acc ** 2)

    _fd_check(loss, [0.05, 20.0, 0.3])


def test_gradient_through_rollout_wrt_mu_c0_alpha():
    scene = scenes.build("hydrostatic_tank", dx=0.02, depth=0.06, width=0.06)
    rng = np.random.default_rng(2)
    scene.fluid.v = rng.normal(0.0, 0.3, scene.fluid.x.shape)
    phys = Physics.for_scene(scene, x64=True, artificial_viscosity=True)
    base = scene.params.replace(dt=integrate.stable_dt(scene)).as_arrays(jnp.float64)
    state0 = integrate.init_state(scene, phys, base)
    m = state0.fluid.mass

    def loss(theta):
        mu, c0, alpha = theta
        params = base.replace(sph=base.sph.replace(mu=mu, c0=c0, alpha=alpha))
        s0 = integrate.refresh_rates(phys, state0, params)
        s, _ = integrate.rollout(phys, s0, params, 20)
        return 0.5 * jnp.sum(m * jnp.sum(s.fluid.v ** 2, axis=1))

    _fd_check(loss, [0.01, float(base.sph.c0), 0.1])


# --- coincident particles ----------------------------------------------------------------
XC = [[0.0, 0.0], [0.0, 0.0], [0.004, 0.001]]     # particles 0 and 1 sit on top of each other


def _coincident_acc(x):
    n = 3
    pr = sph.pairs(KERN, n, x, _a(V), _a([0.005] * 3), _a([0.025] * 3), _a(RHO_OLD),
                   jnp.asarray([[1, 2, 3], [0, 2, 3], [0, 1, 3]]))
    phys = _phys(n_fluid=n, n_boundary=0, **ALL_ON)
    acc, xs, _ = sph.momentum_rate(phys, KERN, _sp(), _a([0.0, 0.0]), _a(RHO), _a(P), pr)
    drho = sph.density_rate(phys, _sp(), _a(RHO_OLD), pr)
    return acc, xs, drho


def test_coincident_particles_give_finite_rates():
    """kernels.py: two particles on top of each other give zero pair force, not NaN."""
    acc, xs, drho = _coincident_acc(_a(XC))
    for a in (acc, xs, drho):
        assert np.all(np.isfinite(np.asarray(a)))
    # ∇W_01 = 0, so without the (0, 1) pair in the lists the forces are the same
    pr = sph.pairs(KERN, 3, _a(XC), _a(V), _a([0.005] * 3), _a([0.025] * 3), _a(RHO_OLD),
                   jnp.asarray([[2, 3, 3], [2, 3, 3], [0, 1, 3]]))
    phys = _phys(n_fluid=3, n_boundary=0, **ALL_ON)
    a2, _, _ = sph.momentum_rate(phys, KERN, _sp(), _a([0.0, 0.0]), _a(RHO), _a(P), pr)
    np.testing.assert_allclose(np.asarray(acc), np.asarray(a2), rtol=1e-14)
    assert np.any(np.asarray(acc) != 0.0)


def test_position_gradient_finite_for_coincident_particles():
    def loss(x):
        acc, xs, drho = _coincident_acc(x)
        return jnp.sum(acc ** 2) + jnp.sum(xs ** 2) + jnp.sum(drho ** 2)

    g = np.asarray(jax.jit(jax.grad(loss))(_a(XC)))
    assert np.all(np.isfinite(g))


def test_sum_neighbours_equals_per_term_sums_and_differentiates_with_an_unused_output():
    """The variadic neighbour sum: the same values as jnp.sum per term, and a gradient that
    uses only some outputs (a symbolic-zero cotangent for the rest: JAX's own transpose of a
    variadic reduce failed there) equals the per-term one."""
    a = jnp.arange(12.0).reshape(3, 4) / 7.0
    b = jnp.cos(a)
    sa, sb = sph.sum_neighbours(a, b)
    np.testing.assert_allclose(sa, jnp.sum(a, axis=1), rtol=1e-6)
    np.testing.assert_allclose(sb, jnp.sum(b, axis=1), rtol=1e-6)

    def run(c, total):
        def body(x, _):
            u, v = total(x * c, jnp.sin(x))      # v is carried out, never used
            return x + 0.01 * u[:, None], v
        x, _ = jax.lax.scan(body, a, None, length=3)
        return jnp.sum(x ** 2)

    per_term = lambda *t: tuple(jnp.sum(x, axis=1) for x in t)
    g = jax.grad(run)(2.0, sph.sum_neighbours)       # raised TypeError without the rule
    np.testing.assert_allclose(g, jax.grad(run)(2.0, per_term), rtol=1e-6)
    jf = jax.jacfwd(lambda x: sph.sum_neighbours(x, x * x)[1])(a)
    np.testing.assert_allclose(jf, jax.jacfwd(lambda x: jnp.sum(x * x, axis=1))(a), rtol=1e-6)
