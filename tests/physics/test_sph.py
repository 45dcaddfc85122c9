"""Unit tests of the SPH fluid terms (fpsi_jax.physics.sph; physics.md §SPH).

Each term is compared with a value computed with plain Python from the formula in physics.md
(sph_reference.py), for two fluid particles and one boundary particle placed by hand: the
terms are read off what the step calls, ``sph.density_rate`` and ``sph.momentum_rate`` with
the other terms switched off, or the per-pair laws (``*_scalar``, ``delta_pairs``) summed
over the neighbours the way those two functions sum them. Then the conservation properties
(Newton's third law), padding, coincident particles and the gradient with respect to μ, c0
and α (jax.grad vs central finite differences).
"""
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from fpsi_jax import cases
from fpsi_jax.model.config import Physics
from fpsi_jax.physics import eos, pairs, sph
from fpsi_jax.solver import init

from ..finite_differences import fd_check
from .sph_reference import (ALL_ON, G, IDX, KERN, M, NBRS, NF, OFF, RHO, RHO_OLD, RTOL, SP,
                            V, X, Hs, P, Pair, W, _a, _momentum, _pairs, _phys,
                            _random_blob, _ref, _sp, ref_terms, tait)

pytestmark = pytest.mark.usefixtures("float64")  # conftest: x64 for this module only


def test_module_runs_in_float64():
    assert _pairs().w.dtype == jnp.float64


def test_configuration_is_inside_the_support():
    """Guard: every listed pair interacts, so no test below is vacuous."""
    for i, nb in NBRS.items():
        for j in nb:
            pr = Pair(i, j, X, V, Hs)
            assert pr.r < 1.9 * pr.h and pr.w > 0 and pr.f < 0


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
    phys = _phys(delta_sph=True, density_diffusion="molteni")
    got = np.asarray(sph.density_rate(phys, _sp(), _a(RHO_OLD[:NF]), _pairs()))
    want = [_ref(i)["cont"] + _ref(i)["delta"] for i in range(NF)]
    np.testing.assert_allclose(got, want, rtol=RTOL)
    # the diffusion alone: its pair law summed over the neighbours as density_rate sums it
    d = np.asarray(jnp.sum(sph.delta_pairs(0.1, 20.0, _a(RHO_OLD[:NF]), _pairs()), axis=1))
    np.testing.assert_allclose(d, [_ref(i)["delta"] for i in range(NF)], rtol=RTOL)
    # diffusion: the denser particle (0) loses density, the lighter one (1) gains it, and
    # the fluid–fluid exchange is antisymmetric: Σ_i V_i Dρ_i/Dt = 0 with V_i = m_i/ρ_i
    assert d[0] < 0 < d[1]
    vol = np.asarray(M[:NF]) / np.asarray(RHO_OLD[:NF])
    assert abs(vol @ d) < 1e-12 * np.sum(np.abs(vol * d))


def test_delta_diffusion_fourtakas():
    """Fourtakas' form: the pair terms of the Molteni form with ρ_j − ρ_i less
    (ρ0/c0²) g·x_ji, read off the density_rate the step calls."""
    phys = _phys(delta_sph=True, density_diffusion="fourtakas")
    got = np.asarray(sph.density_rate(phys, _sp(), _a(RHO_OLD[:NF]), _pairs(), gravity=_a(G)))
    want = [_ref(i)["cont"] + _ref(i, gravity=G)["delta"] for i in range(NF)]
    # guard: the hydrostatic part changes the diffusion by more than the tolerance
    d_m, d_f = ([_ref(i, **kw)["delta"] for i in range(NF)] for kw in ({}, {"gravity": G}))
    assert np.all(np.abs(np.subtract(d_f, d_m)) > 0.005 * np.abs(d_m))
    np.testing.assert_allclose(got, want, rtol=RTOL)


def _hydrostatic_column(dx=0.002, h=0.0025, nx=7, ny=8, depth=0.05, tait=True):
    """A lattice of fluid particles resting on a floor at y = 0 (the lowest row at dx/2),
    its densities those of a Tait fluid at rest under a free surface at ``depth``, and
    every pair within 2h listed (fluid only: δ-SPH reads no wall). ``tait=False``: the
    densities linear in depth, ρ0 + ρ0 g d/c0² (Fourtakas' ρ^H exactly)."""
    sp = _sp()
    rho0, c0, gamma = float(sp.rho0), float(sp.c0), float(sp.gamma)
    gx, gy = np.meshgrid((np.arange(nx) + 0.5) * dx, (np.arange(ny) + 0.5) * dx)
    x = np.stack([gx.ravel(), gy.ravel()], axis=1)
    n = len(x)
    p_h = rho0 * 9.81 * (depth - x[:, 1])
    rho = (rho0 * (1.0 + gamma * p_h / (rho0 * c0 ** 2)) ** (1.0 / gamma) if tait
           else rho0 + p_h / c0 ** 2)
    d = np.linalg.norm(x[:, None] - x[None], axis=-1)
    near = (d < 2 * h) & ~np.eye(n, dtype=bool)
    k = near.sum(1).max()
    idx = np.full((n, k), n, np.int32)
    for i in range(n):                      # the hand-made list of a small test lattice
        js = np.flatnonzero(near[i])
        idx[i, :len(js)] = js
    pr = pairs.pairs(KERN, n, _a(x), _a(np.zeros_like(x)), _a(np.full(n, h)),
                     _a(rho * dx * dx), _a(rho), jnp.asarray(idx))
    return x, rho, pr, sp


@pytest.mark.parametrize("tait", [False, True])
def test_delta_diffusion_leaves_a_fluid_at_rest_at_rest(tait):
    """Near a floor all neighbours lie above: Molteni's term of a hydrostatic column drains
    density from the bottom row (its pressure sinks below ρ0 g d). Fourtakas' form is zero
    for densities linear in depth (to round-off); for the Tait fluid's hydrostatic
    densities what is left is the curvature of ρ(d), under 1 % of Molteni's term."""
    x, rho, pr, sp = _hydrostatic_column(tait=tait)
    n = len(x)
    bottom = x[:, 1] < 0.002
    molteni = np.asarray(sph.delta_pairs(sp.delta, sp.c0, _a(rho), pr).sum(axis=1))
    g = float(sp.rho0 / sp.c0 ** 2) * G
    fourtakas = np.asarray(sph.delta_pairs(sp.delta, sp.c0, _a(rho), pr,
                                           hydrostatic=_a(g)).sum(axis=1))
    assert np.all(molteni[bottom] < 0)
    bound = 1e-2 if tait else 1e-10     # round-off of ρ_j − ρ_i at ρ ≈ 1000
    assert np.max(np.abs(fourtakas)) < bound * np.max(np.abs(molteni[bottom]))
    # and density_rate switches it on for density_diffusion = 'fourtakas'
    phys = _phys(n_fluid=n, n_boundary=0, delta_sph=True, density_diffusion="fourtakas")
    np.testing.assert_allclose(np.asarray(sph.density_rate(phys, sp, _a(rho), pr,
                                                           gravity=_a(G))),
                               fourtakas, rtol=1e-10, atol=1e-12 * np.max(np.abs(molteni)))


# --- momentum ----------------------------------------------------------------------------
def test_pressure_term():
    acc, xs = _momentum(_phys(**OFF), _sp(mu=0.0))
    want = np.array([_ref(i)["pres"] for i in range(NF)])
    assert np.all(np.abs(want) > 1e-3)
    np.testing.assert_allclose(np.asarray(acc), want, rtol=RTOL)
    np.testing.assert_array_equal(np.asarray(xs), 0.0)   # XSPH off → zero correction


def test_pressure_term_two_particles_closed_form():
    """Two particles a distance h apart (q = 1): a_0 = −m(P0/ρ0² + P1/ρ1²) x_01 F(h)."""
    h, m, p, rho = 0.01, 0.1, 1000.0, 1000.0
    x = _a([[0.0, 0.0], [h, 0.0]])
    pr = pairs.pairs(KERN, 2, x, jnp.zeros((2, 2)), _a([h, h]), _a([m, m]), _a([rho, rho]),
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


def test_viscous_term_morris():
    acc, _ = _momentum(_phys(**OFF), p=[0.0, 0.0, 0.0])     # P = 0: viscosity alone
    want = np.array([_ref(i)["visc"] for i in range(NF)])
    assert np.all(np.abs(want) > 1e-6)
    np.testing.assert_allclose(np.asarray(acc), want, rtol=RTOL)
    # the pair law momentum_rate calls, s v_ij summed over the neighbours, with distinct
    # μ_i, μ_j
    pr = _pairs()
    rho_j = pairs.gather(_a(RHO), pr.idx)
    s = sph.viscous_scalar(0.01, 0.03, 1.0 / _a(RHO[:NF]), 1.0 / rho_j, pr)
    got = jnp.sum(s[..., None] * pr.vij, axis=1)
    np.testing.assert_allclose(np.asarray(got), want, rtol=RTOL)   # μ_i + μ_j = 2·0.02


def test_viscous_term_opposes_relative_motion():
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
    rp = pairs.gather(jnp.stack([_a(RHO), _a(P)], axis=1), pr.idx)
    w_dp = KERN.w(SP["dp"], pr.hij)
    r = np.asarray(sph.anticlump(SP["r_clump"], _a(P[:NF]) / _a(RHO[:NF]) ** 2,
                                 rp[..., 1] / rp[..., 0] ** 2, pr.w, w_dp))
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
    # the pair law momentum_rate calls, s x_ij summed over the neighbours
    pr = _pairs()
    rho_j = pairs.gather(_a(RHO), pr.idx)

    def av_sum(alpha):
        s = sph.artificial_viscosity_scalar(alpha, SP["c0"], _a(RHO[:NF]), rho_j, pr)
        return jnp.sum(s[..., None] * pr.dx, axis=1)

    one = av_sum(SP["alpha"])
    np.testing.assert_allclose(np.asarray(one), want, rtol=RTOL)
    # only the approaching pair (1, 0) acts on particle 1: −m_0 Π_10 ∇_1W_10
    q = Pair(1, 0, X, V, Hs)
    pi10 = (-SP["alpha"] * SP["c0"] * q.h * float(q.vij @ q.xij)
            / (q.r2 + 0.01 * q.h ** 2) / (0.5 * (RHO[1] + RHO[0])))
    assert pi10 > 0
    np.testing.assert_allclose(np.asarray(one)[1], -M[0] * pi10 * q.gradw, rtol=RTOL)
    # α = 0 switches it off exactly
    zero = av_sum(0.0)
    np.testing.assert_array_equal(np.asarray(zero), 0.0)


def _wall_pair(r, r0=0.0032, p=(0.0, 0.0), beta=0.05):
    """Fluid 0 at the origin, boundary particle 1 at (r, 0); pressures ``p``. Returns the
    backstop's part of a_0 (the step with it minus the step without)."""
    x = _a([[0.0, 0.0], [r, 0.0]])
    pr = pairs.pairs(KERN, 1, x, jnp.zeros((2, 2)), _a([0.004, 0.004]), _a([0.016, 0.016]),
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
        pr = pairs.pairs(KERN, 1, x, jnp.zeros((2, 2)), _a([0.004, 0.004]),
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


def test_wall_repulsion_only_acts_on_fixed_boundary_neighbours():
    """Fluid–fluid pairs closer than r0 feel nothing from it (only j in the boundary)."""
    r = 0.5 * 0.0032
    x = _a([[0.0, 0.0], [r, 0.0]])
    pr = pairs.pairs(KERN, 2, x, jnp.zeros((2, 2)), _a([0.004, 0.004]), _a([0.016, 0.016]),
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
    scene = cases.build(name, dx=0.02)
    on, off = (init.init_state(scene, Physics.for_scene(scene, wall_repulsion=w),
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
        drho = sph.density_rate(phys, sp, _a(RHO_OLD[:NF]), pr, gravity=_a(G))
        acc, xs, _ = sph.momentum_rate(phys, KERN, sp, _a(G), _a(RHO), _a(P), pr)
        out[k] = (np.asarray(drho), np.asarray(acc), np.asarray(xs))
        pad = np.asarray(pr.idx) == 3
        assert np.all(np.asarray(pr.w)[pad] == 0.0) and np.all(np.asarray(pr.f)[pad] == 0.0)
    for k in ("one", "three"):
        for a, b in zip(out[k], out["none"]):
            assert np.all(np.isfinite(a))
            np.testing.assert_allclose(a, b, rtol=1e-15, atol=0)


# --- Newton's third law ------------------------------------------------------------------
def test_newton_third_law_random_configuration():
    c = _random_blob()
    n = c["x"].shape[0]
    assert n == 50 and c["idx"].shape[1] > 8
    sp = _sp(dp=c["dp"], mu=0.05, alpha=0.5, c0=30.0, r_clump=0.2)
    p = np.asarray(eos.pressure(_a(c["rho"]), 1000.0, 30.0, 7.0))
    assert p.min() < 0 < p.max()          # tension and compression: |P| in R_ij matters
    pr = pairs.pairs(KERN, n, _a(c["x"]), _a(c["v"]), _a(c["h"]), _a(c["m"]),
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
    pr = pairs.pairs(KERN, n, _a(c["x"]), _a(c["v"]), _a(c["h"]), _a(c["m"]),
                     _a(c["rho_old"]), jnp.asarray(c["idx"]))
    phys = _phys(n_fluid=n, n_boundary=0, **ALL_ON)
    acc, xs, _ = sph.momentum_rate(phys, KERN, _sp(**spd), _a([0.0, 0.0]), _a(c["rho"]),
                                _a(p), pr)
    drho = sph.density_rate(phys, _sp(**spd), _a(c["rho_old"]), pr, gravity=_a(G))
    for i in range(n):
        nb = [int(j) for j in c["idx"][i] if j < n]
        ref = ref_terms(i, nb, c["x"], c["v"], c["h"], c["m"], c["rho_old"], c["rho"], p, n,
                        spd, gravity=G)             # the default δ-SPH: Fourtakas'
        a_ref = ref["pres"] + ref["clump"] + ref["visc"] + ref["av"]
        np.testing.assert_allclose(np.asarray(acc[i]), a_ref, rtol=1e-9,
                                   atol=1e-11 * np.abs(a_ref).max())
        np.testing.assert_allclose(np.asarray(xs[i]), ref["xsph"], rtol=1e-9,
                                   atol=1e-12 * np.abs(ref["xsph"]).max())
        assert float(drho[i]) == pytest.approx(ref["cont"] + ref["delta"], rel=1e-9,
                                               abs=1e-9 * abs(ref["cont"]))


# --- gradients ---------------------------------------------------------------------------
def test_gradient_of_momentum_rate_wrt_mu_c0_alpha():
    c = _random_blob(n_x=5, n_y=4, seed=7)
    n = c["x"].shape[0]
    pr = pairs.pairs(KERN, n, _a(c["x"]), _a(c["v"]), _a(c["h"]), _a(c["m"]),
                     _a(c["rho_old"]), jnp.asarray(c["idx"]))
    phys = _phys(n_fluid=n, n_boundary=0, **ALL_ON)
    rho = _a(c["rho"])

    def loss(theta):
        mu, c0, alpha = theta
        sp = _sp(dp=c["dp"]).replace(mu=mu, c0=c0, alpha=alpha)
        p = eos.pressure(rho, sp.rho0, c0, sp.gamma)
        acc, _, _ = sph.momentum_rate(phys, KERN, sp, _a([0.0, 0.0]), rho, p, pr)
        return jnp.sum(acc ** 2)

    fd_check(loss, [0.05, 20.0, 0.3])


# --- coincident particles ----------------------------------------------------------------
XC = [[0.0, 0.0], [0.0, 0.0], [0.004, 0.001]]     # particles 0 and 1 sit on top of each other


def _coincident_acc(x):
    n = 3
    pr = pairs.pairs(KERN, n, x, _a(V), _a([0.005] * 3), _a([0.025] * 3), _a(RHO_OLD),
                     jnp.asarray([[1, 2, 3], [0, 2, 3], [0, 1, 3]]))
    phys = _phys(n_fluid=n, n_boundary=0, **ALL_ON)
    acc, xs, _ = sph.momentum_rate(phys, KERN, _sp(), _a([0.0, 0.0]), _a(RHO), _a(P), pr)
    drho = sph.density_rate(phys, _sp(), _a(RHO_OLD), pr, gravity=_a(G))
    return acc, xs, drho


def test_coincident_particles_give_finite_rates():
    """kernels.py: two particles on top of each other give zero pair force, not NaN."""
    acc, xs, drho = _coincident_acc(_a(XC))
    for a in (acc, xs, drho):
        assert np.all(np.isfinite(np.asarray(a)))
    # ∇W_01 = 0, so without the (0, 1) pair in the lists the forces are the same
    pr = pairs.pairs(KERN, 3, _a(XC), _a(V), _a([0.005] * 3), _a([0.025] * 3), _a(RHO_OLD),
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


def test_shifting_concentration_gradient_and_divergence_by_hand():
    """sph.shifting_scalars summed as momentum_rate sums them: ∇C_i against central
    differences of C(x) = Σ_j V_j W(|x − x_j|, h) moved in x_i alone, and ∇·r ≈ 2 inside a
    lattice, under DualSPHysics' 1.5 at its free top row."""
    x, rho, pr, _ = _hydrostatic_column(nx=9, ny=9)
    h, dx = 0.0025, 0.002
    vol = np.where(np.asarray(pr.w) > 0, dx * dx, 0.0)      # V_j = m_j/ρ_j = Δx²
    s, div = sph.shifting_scalars(_a(vol), pr)
    grad = np.stack([np.sum(np.asarray(s * pr.dx[..., k]), axis=1) for k in (0, 1)], 1)
    div = np.asarray(jnp.sum(div, axis=1))

    def conc(i, xi):
        d = np.linalg.norm(np.delete(x, i, 0) - xi, axis=1)
        return float(np.sum(dx * dx * np.asarray(KERN.w(_a(d), h))))

    e = 1e-7
    for i in (0, 40, 44, 76):          # a corner, the centre, the right edge, the top row
        fd = [(conc(i, x[i] + e * u) - conc(i, x[i] - e * u)) / (2 * e)
              for u in (np.array([1.0, 0.0]), np.array([0.0, 1.0]))]
        np.testing.assert_allclose(grad[i], fd, rtol=1e-6, atol=1e-3)
    assert abs(div[40] - 2.0) < 0.1 and np.linalg.norm(grad[40]) < 1.0   # lattice interior
    top = np.flatnonzero(x[:, 1] > x[:, 1].max() - 1e-9)
    assert np.all(div[top] < 1.5) and np.all(grad[top][:, 1] < -50.0)     # ∇C into the fluid


def test_shifting_velocity_by_hand():
    """δr/Δt = −A h² ∇C/Δt where ∇·r ≥ 1.5, zero at a free surface."""
    a, h, dt = 0.01, 0.0025, 1e-4
    got = np.asarray(sph.shifting_velocity(a, _a([h, h]), dt, _a([[1.0, 2.0], [1.0, 2.0]]),
                                           _a([2.0, 1.0])))
    k = a * h * h / dt
    np.testing.assert_allclose(got, [[-k, -2 * k], [0.0, 0.0]], rtol=1e-13)


def test_momentum_rate_adds_the_shifting_to_the_position_term():
    """With Physics.shifting = A the step's position term gains exactly
    shifting_velocity(A, h, Δt, ∇C, ∇·r) of the summed shifting_scalars; A = 0 adds nothing."""
    x, rho, pr, sp = _hydrostatic_column()
    n, h, dt = len(x), 0.0025, 1e-4
    args = (KERN, sp, _a([0.0, -9.81]), _a(rho), _a(np.zeros(n)), pr)
    kw = dict(h=_a(np.full(n, h)), dt=dt)
    _, xs0, _ = sph.momentum_rate(_phys(n_fluid=n, n_boundary=0, **OFF), *args, **kw)
    _, xs1, _ = sph.momentum_rate(_phys(n_fluid=n, n_boundary=0, shifting=0.02, **OFF),
                                  *args, **kw)
    live = pr.w > 0
    vol = jnp.where(live, pr.m_j / jnp.where(live, pr.rho_j, 1.0), 0.0)
    s, div = sph.shifting_scalars(vol, pr)
    grad = jnp.stack([jnp.sum(s * pr.dx[..., 0], 1), jnp.sum(s * pr.dx[..., 1], 1)], 1)
    want = sph.shifting_velocity(0.02, _a(np.full(n, h)), dt, grad, jnp.sum(div, 1))
    np.testing.assert_array_equal(np.asarray(xs0), 0.0)
    np.testing.assert_allclose(np.asarray(xs1), np.asarray(want), rtol=1e-12, atol=1e-15)
    assert np.max(np.abs(np.asarray(want))) > 0


def test_smoothing_length_among_grains():
    eta, dp, rho0 = 1.25, 0.005, 1000.0
    f = lambda m, eps, rho, phi=0.5, var=True: float(  # noqa: E731
        sph.smoothing_length_among_grains(eta, jnp.float64(m), jnp.float64(eps),
                                          jnp.float64(rho), dp, rho0, phi, var))
    clear = rho0 * dp * dp
    # clear water: K37 integrated, h0 √(ρ0/ρ)
    assert f(clear, 1.0, 1010.0) == pytest.approx(eta * dp * math.sqrt(rho0 / 1010.0),
                                                  rel=1e-14)
    # a clear-water particle in a pore of ε = 0.13 is spread over Δp²/ε: h = h0 √(φ/ε),
    # which keeps φ of the lattice's neighbours (h²/V = φ h0²/Δp²)
    h = f(clear, 0.13, rho0)
    assert h == pytest.approx(eta * dp * math.sqrt(0.5 / 0.13), rel=1e-14)
    assert h * h / (dp * dp / 0.13) == pytest.approx(0.5 * eta * eta, rel=1e-14)
    assert f(clear, 0.13, rho0, 1.0) == pytest.approx(eta * dp / math.sqrt(0.13), rel=1e-14)
    # born in the bed (m = ε0 ρ0 Δp²): h0 until its pore is under φ of its birth voidage
    assert f(0.2 * clear, 0.2, rho0) == pytest.approx(eta * dp, rel=1e-14)
    assert f(0.2 * clear, 0.12, rho0) == pytest.approx(eta * dp, rel=1e-14)
    assert f(0.2 * clear, 0.05, rho0) == pytest.approx(eta * dp * math.sqrt(2.0), rel=1e-14)
    assert f(0.2 * clear, 0.4, rho0) == pytest.approx(eta * dp, rel=1e-14)
    # without variable h the floor is the lattice's h0 whatever ρ
    assert f(0.2 * clear, 0.4, 1010.0, var=False) == pytest.approx(eta * dp, rel=1e-14)
    assert f(clear, 0.25, 1010.0, var=False) == pytest.approx(
        eta * math.sqrt(0.5 * clear / (0.25 * 1010.0)), rel=1e-14)
