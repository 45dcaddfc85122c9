"""Fluid–particle closure laws (fpsi_jax.physics.fpi) against hand-computed values, the
reaction laws and a gradient check. The coupling inside the step is tested in
tests/solver/test_stages.py and tests/solver/test_forward.py."""
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from fpsi_jax.physics import fpi, kernels

from ..finite_differences import fd_check

pytestmark = pytest.mark.usefixtures("float64")


RHO, MU, D = 1000.0, 1e-3, 2.5e-3


def test_drag_coefficient_schiller_naumann_and_newton():
    re = jnp.asarray([0.5, 10.0, 999.0, 2000.0])
    want = [24 / 0.5 * (1 + 0.15 * 0.5 ** 0.687), 2.4 * (1 + 0.15 * 10 ** 0.687),
            24 / 999 * (1 + 0.15 * 999 ** 0.687), 0.44]
    np.testing.assert_allclose(np.asarray(fpi.drag_coefficient(re)), want, rtol=1e-12)


def test_beta_ergun_below_and_wen_yu_above_the_switch():
    slip = 0.05
    for eps in (0.5, 0.8):
        want = 150 * (1 - eps) ** 2 * MU / (eps * D * D) + 1.75 * (1 - eps) * RHO * slip / D
        assert float(fpi.interphase_beta(eps, slip, RHO, D, MU)) == pytest.approx(want, 1e-12)
    eps = 0.9
    re = slip * eps * RHO * D / MU
    cd = 24 / re * (1 + 0.15 * re ** 0.687)
    want = 0.75 * cd * eps * (1 - eps) * RHO * slip * eps ** -2.65 / D
    assert float(fpi.interphase_beta(eps, slip, RHO, D, MU)) == pytest.approx(want, 1e-12)


def test_drag_force_is_along_the_slip_with_W19_magnitude():
    eps = jnp.asarray([0.95])
    u, v = jnp.asarray([[0.1, 0.0]]), jnp.asarray([[0.0, -0.2]])
    vol = jnp.asarray([np.pi * (D / 2) ** 2])
    f = np.asarray(fpi.drag_force(eps, u, v, vol, RHO, D, MU))[0]
    rel = np.array([0.1, 0.2])
    beta = float(fpi.interphase_beta(0.95, np.linalg.norm(rel), RHO, D, MU))
    np.testing.assert_allclose(f, beta / 0.05 * float(vol[0]) * rel, rtol=1e-12)


def test_drag_of_a_grain_in_clear_water_is_finite_in_float32():
    """ε = 1 exactly (a wave front reaching a dry grain: its one fluid neighbour at the
    kernel's edge is clear water): β/(1 − ε) is the Wen–Yu limit ¾ C_d ρ s/d, not 0/0,
    in float32 as in float64, for both laws; and β/(1 − ε) is β divided by 1 − ε where
    that is exact."""
    from fpsi_jax.model.options import Drag
    s = 0.3
    re = s * RHO * D / MU
    cd = 24 / re * (1 + 0.15 * re ** 0.687)
    for dtype in (jnp.float32, jnp.float64):
        f = fpi.drag_force(jnp.asarray([1.0], dtype), jnp.asarray([[s, 0.0]], dtype),
                           jnp.zeros((1, 2), dtype), jnp.asarray([1.0], dtype), RHO, D, MU)
        assert np.isfinite(np.asarray(f)).all()
        assert float(f[0, 0]) == pytest.approx(0.75 * cd * RHO * s * s / D, rel=1e-5)
        fc = fpi.drag_force(jnp.asarray([1.0], dtype), jnp.asarray([[s, 0.0]], dtype),
                            jnp.zeros((1, 2), dtype), jnp.asarray([1.0], dtype), RHO, D, MU,
                            Drag.CYLINDER)
        assert np.isfinite(np.asarray(fc)).all() and float(fc[0, 0]) > 0
    for eps in (0.5, 0.8, 0.9):
        assert float(fpi.beta_per_solid(eps, s, RHO, D, MU)) == pytest.approx(
            float(fpi.interphase_beta(eps, s, RHO, D, MU)) / (1 - eps), rel=1e-12)


def test_cylinder_drag_coefficient_sucker_brauer():
    """Hand values of 1.18 + 6.8 Re^−0.89 + 1.96 Re^−½ − 4e-4 Re/(1 + 3.64e-7 Re²):
    Re = 20 → 2.0830 (Dennis & Chang's steady solution: 2.045), Re = 1 → 9.9396."""
    cd = np.asarray(fpi.cylinder_drag_coefficient(jnp.asarray([1.0, 20.0])))
    want = [1.18 + 6.8 + 1.96 - 4e-4 / (1 + 3.64e-7),
            1.18 + 6.8 * 20 ** -0.89 + 1.96 * 20 ** -0.5 - 4e-4 * 20 / (1 + 3.64e-7 * 400)]
    np.testing.assert_allclose(cd, want, rtol=1e-12)
    assert cd[1] == pytest.approx(2.0830, abs=1e-4)


def test_cylinder_drag_of_an_isolated_disc_is_half_rho_s2_d_cd_per_length():
    """ε → 1: F = ½ρ s² d C_D per unit length (a cylinder), not the sphere's ¾ C_D ρ s²/d
    per volume; below ε = 0.8 both laws are Ergun."""
    from fpsi_jax.model.options import Drag
    s, eps = 0.06, 1.0 - 1e-9
    vol = jnp.asarray([np.pi * (D / 2) ** 2])
    f = np.asarray(fpi.drag_force(jnp.asarray([eps]), jnp.asarray([[0.0, s]]),
                                  jnp.zeros((1, 2)), vol, RHO, D, MU, Drag.CYLINDER))[0]
    re = s * RHO * D / MU                                   # 150
    cd = float(fpi.cylinder_drag_coefficient(re))
    assert f[1] == pytest.approx(0.5 * RHO * s * s * D * cd, rel=1e-6)
    assert f[0] == 0.0
    for e in (0.5, 0.8):
        assert float(fpi.interphase_beta(e, s, RHO, D, MU, Drag.CYLINDER)) == \
            float(fpi.interphase_beta(e, s, RHO, D, MU))


def test_pressure_gradient_is_exact_for_a_linear_field_even_with_a_cut_kernel():
    kern = kernels.get("wendland")
    h, dx = 0.003, 0.0015
    xs = np.stack(np.meshgrid(np.arange(-4, 5) * dx, np.arange(0, 5) * dx), -1).reshape(-1, 2)
    x_p = jnp.asarray([[0.0002, 0.0003]])          # near the "free surface" y < 0 is empty
    p = 1000.0 + 3000.0 * xs[:, 0] - 9810.0 * xs[:, 1]
    n = xs.shape[0]
    rows = fpi.grain_rows(kern, jnp.asarray(xs), jnp.full(n, h), jnp.full(n, dx * dx), x_p,
                          jnp.arange(n)[None, :], n)
    grad = np.asarray(fpi.pressure_gradient(rows, jnp.asarray(p)))[0]
    np.testing.assert_allclose(grad, [3000.0, -9810.0], rtol=1e-6)   # 1e-9 ridge
    force = np.asarray(fpi.pressure_force(rows, jnp.asarray(p), jnp.asarray([2e-6])))[0]
    np.testing.assert_allclose(force, [-2e-6 * 3000.0, 2e-6 * 9810.0], rtol=1e-6)


def test_grain_drag_uses_shepard_averages_and_the_3d_voidage():
    kern = kernels.get("wendland")
    h = 0.003
    xf = jnp.asarray([[0.001, 0.0], [-0.001, 0.0], [0.0, 0.002]])
    vf = jnp.asarray([[0.1, 0.0], [0.1, 0.0], [0.1, 0.3]])
    eps_f = jnp.asarray([0.9, 0.8, 0.95])
    rows = fpi.grain_rows(kern, xf, jnp.full(3, h), jnp.full(3, 2e-6), jnp.zeros((1, 2)),
                          jnp.asarray([[0, 1, 2, 3]]), 3)
    w = np.asarray(kern.w(jnp.asarray([0.001, 0.001, 0.002]), h))
    eps2 = float((w * np.asarray(eps_f)).sum() / w.sum())
    u = (w[:, None] * np.asarray(vf)).sum(0) / w.sum()
    eps_p, u_f, wet, drag = fpi.grain_drag(rows, eps_f, vf, jnp.zeros((1, 2)),
                                           jnp.asarray([np.pi * D * D / 4]), jnp.asarray([D]),
                                           RHO, MU)
    np.testing.assert_allclose(np.asarray(u_f[0]), u, rtol=1e-12)
    assert float(wet[0]) == pytest.approx(2e-6 * w.sum(), 1e-12)
    assert float(eps_p[0]) == pytest.approx(float(fpi.voidage_3d(eps2)), 1e-12)
    want = fpi.drag_force(eps_p, u_f, jnp.zeros((1, 2)), jnp.asarray([np.pi * D * D / 4]),
                          RHO, D, MU)
    np.testing.assert_allclose(np.asarray(drag), np.asarray(want), rtol=1e-12)
    dry = fpi.grain_drag(rows, eps_f, vf, jnp.zeros((1, 2)), jnp.asarray([1e-6]),
                         jnp.asarray([D]), RHO, MU)
    assert float(jnp.abs(dry[3]).sum()) > 0
    far = fpi.grain_rows(kern, xf, jnp.full(3, h), jnp.full(3, 2e-6), jnp.asarray([[1.0, 1.0]]),
                         jnp.asarray([[3, 3, 3, 3]]), 3)
    assert float(jnp.abs(fpi.grain_drag(far, eps_f, vf, jnp.zeros((1, 2)), jnp.asarray([1e-6]),
                                        jnp.asarray([D]), RHO, MU)[3]).sum()) == 0.0


def test_lubrication_value_regularisation_cutoff_and_pair_symmetry():
    x = jnp.asarray([[[D + 1e-4, 0.0]], [[-(D + 1e-4), 0.0]]])      # i–j and j–i
    v = jnp.asarray([[[-0.01, 0.0]], [[0.01, 0.0]]])                 # approaching
    f = np.asarray(fpi.lubrication(x, v, D, MU, gap_min=0.01 * D, cutoff=0.5 * D))
    r = D + 1e-4
    want = -3 * np.pi * MU * D ** 2 / (8 * 1e-4) * (-0.01 * r) / r ** 2 * r
    np.testing.assert_allclose(f[0, 0], [want, 0.0], rtol=1e-12)
    np.testing.assert_allclose(f[0, 0] + f[1, 0], 0.0, atol=1e-18)   # Newton's third law
    assert want > 0                                                   # resists the approach
    touching = fpi.lubrication(jnp.asarray([[[D * 0.99, 0.0]]]), v[:1], D, MU, 0.01 * D, D)
    assert np.all(np.isfinite(np.asarray(touching)))                  # overlap: regularised
    far = fpi.lubrication(jnp.asarray([[[2 * D, 0.0]]]), v[:1], D, MU, 0.01 * D, 0.5 * D)
    assert float(jnp.abs(far).sum()) == 0.0


def test_voidage_is_gathered_from_the_grain_rows_and_maps_to_3d():
    # two grains (volumes 0.1, 0.2) and three fluid particles; grain 0 sees fluid 0 and 1,
    # grain 1 sees fluid 1; fluid 2 sees none. Slot 2 is padding.
    w = jnp.asarray([[2.0, 1.0, 5.0], [0.5, 9.0, 9.0]])
    idx = jnp.asarray([[0, 1, 3], [1, 3, 3]])
    valid = idx < 3
    eps2 = fpi.fluid_voidage(w, jnp.asarray([0.1, 0.2]), idx, valid, 3)
    np.testing.assert_allclose(np.asarray(eps2), [1 - 0.2, 1 - 0.1 - 0.1, 1.0], rtol=1e-12)
    k = 2 / np.sqrt(np.pi * np.sqrt(3))
    np.testing.assert_allclose(np.asarray(fpi.voidage_3d(eps2)),
                               [1 - k * 0.2 ** 1.5, 1 - k * 0.2 ** 1.5, 1.0], rtol=1e-12)
    # hexagonal discs (area fraction π/(2√3)) map to face-centred spheres (π/(3√2))
    hex2 = 1 - np.pi / (2 * np.sqrt(3))
    assert float(fpi.voidage_3d(hex2)) == pytest.approx(1 - np.pi / (3 * np.sqrt(2)), 1e-12)
    # a dense overlap is clipped at EPS_MIN
    assert float(fpi.fluid_voidage(w[:1] * 10, jnp.asarray([1.0]), idx[:1], valid[:1], 3)[0]) \
        == fpi.EPS_MIN


def test_shepard_averages():
    w = jnp.asarray([[2.0, 1.0, 5.0]])
    vol = jnp.asarray([[0.1, 0.3, 9.0]])
    valid = jnp.asarray([[True, True, False]])
    vals = jnp.asarray([[[1.0, 0.0], [0.0, 2.0], [7.0, 7.0]]])
    avg, den = fpi.shepard(vals, w, vol, valid)
    np.testing.assert_allclose(np.asarray(avg[0]), [0.2 / 0.5, 0.6 / 0.5])
    assert float(den[0]) == pytest.approx(0.5)


def test_reaction_sums_to_minus_the_grain_force():
    rng = np.random.default_rng(3)
    n_f, n_p, k = 30, 6, 5
    idx = jnp.asarray(rng.integers(0, n_f, (n_p, k)))
    valid = jnp.asarray(rng.random((n_p, k)) > 0.2).at[:, 0].set(True)
    w = jnp.asarray(rng.random((n_p, k)))
    vol = jnp.asarray(rng.random((n_p, k)))
    weights = fpi.reaction_weights(w, vol, valid)
    np.testing.assert_allclose(np.asarray(weights.sum(1)), 1.0, rtol=1e-14)
    force = jnp.asarray(rng.normal(size=(n_p, 2)))
    out = fpi.reaction_on_fluid(force, weights, idx, n_f)
    np.testing.assert_allclose(np.asarray(out.sum(0)), -np.asarray(force.sum(0)), atol=1e-14)


def test_lubrication_on_discs_obeys_newtons_third_law():
    rng = np.random.default_rng(5)
    n = 12
    x = jnp.asarray(rng.random((n, 2)) * 0.01)
    v = jnp.asarray(rng.normal(size=(n, 2)) * 0.01)
    r = jnp.full(n, 0.0012)
    idx = jnp.asarray([[j for j in range(n) if j != i] for i in range(n)])
    wet = jnp.asarray(rng.random(n) > 0.3)
    f = fpi.lubrication_on_discs(x, v, r, wet, idx, MU, 0.02, 2.0)
    assert float(jnp.abs(f).max()) > 0
    np.testing.assert_allclose(np.asarray(f.sum(0)), 0.0, atol=1e-12 * float(jnp.abs(f).sum()))
    assert np.all(np.asarray(f)[~np.asarray(wet)] == 0.0)        # dry grains: no lubrication


def test_drag_gradient_wrt_viscosity_matches_finite_differences():
    eps = jnp.asarray([0.7, 0.9])
    u = jnp.asarray([[0.1, 0.0], [0.0, 0.05]])
    v = jnp.zeros((2, 2))
    vol = jnp.full(2, 5e-6)

    def total(mu):
        return jnp.sum(fpi.drag_force(eps, u, v, vol, RHO, D, mu))

    g = float(jax.grad(total)(MU))
    e = 1e-8
    fd = (float(total(MU + e)) - float(total(MU - e))) / (2 * e)
    np.testing.assert_allclose(g, fd, rtol=1e-6)


def test_cylinder_drag_gradient_wrt_viscosity_matches_finite_differences():
    from fpsi_jax.model.options import Drag
    eps = jnp.asarray([0.85, 0.95])
    u = jnp.asarray([[0.1, 0.0], [0.0, 0.05]])
    vol = jnp.full(2, 5e-6)

    def total(mu):
        return jnp.sum(fpi.drag_force(eps, u, jnp.zeros((2, 2)), vol, RHO, D, mu,
                                      Drag.CYLINDER))

    g = float(jax.grad(total)(MU))
    fd = (float(total(MU + 1e-8)) - float(total(MU - 1e-8))) / 2e-8
    np.testing.assert_allclose(g, fd, rtol=1e-6)


def test_cell_share_goes_to_the_grains_by_their_part_of_the_solid_fraction():
    """Fluid particle 0 is in the support of grains A (V_p W = 2·0.3) and B (1·0.2); fluid
    particle 1 only in A's. Its cell force F_0 = (1, −2) splits 0.75 / 0.25, F_1 = (0, 4)
    goes to A whole: A gets (0.75, 2.5), B (0.25, −0.5); the sums agree (Newton)."""
    rows = fpi.GrainRows(idx=jnp.asarray([[0, 1], [0, 2]]), valid=jnp.asarray([[True, True],
                                                                                [True, False]]),
                         w=jnp.asarray([[0.3, 0.5], [0.2, 0.0]]), vol=None, dx=None, f=None)
    force = jnp.asarray([[1.0, -2.0], [0.0, 4.0]])
    out = np.asarray(fpi.cell_share_on_grains(rows, force, jnp.asarray([2.0, 1.0]), 2))
    np.testing.assert_allclose(out, [[0.75, 2.5], [0.25, -0.5]], rtol=1e-12)
    np.testing.assert_allclose(out.sum(0), np.asarray(force).sum(0), rtol=1e-12)


def test_mixture_flux_is_the_volume_flux_of_fluid_and_grains():
    """J_f = ε_f u_f + (1 − ε_f) v̄_f with v̄ weighted by the grains' part of the solid
    fraction (the weights of cell_share_on_grains). Fluid 0 sees grains A (V_p W = 2·0.3)
    and B (1·0.2): v̄_0 = 0.75 v_A + 0.25 v_B = (0.75, 0.5); fluid 1 sees A only; fluid 2
    no grain, J = u. With ε = (0.2, 0.5, 1): J_0 = 0.2 (1, 1) + 0.8 (0.75, 0.5) = (0.8, 0.6),
    J_1 = 0.5 (0, 2) + 0.5 (1, 0) = (0.5, 1), J_2 = (3, −1)."""
    rows = fpi.GrainRows(idx=jnp.asarray([[0, 1], [0, 3]]),
                         valid=jnp.asarray([[True, True], [True, False]]),
                         w=jnp.asarray([[0.3, 0.5], [0.2, 0.0]]), vol=None, dx=None, f=None)
    u = jnp.asarray([[1.0, 1.0], [0.0, 2.0], [3.0, -1.0]])
    v_p = jnp.asarray([[1.0, 0.0], [0.0, 2.0]])
    out = np.asarray(fpi.mixture_flux(rows, jnp.asarray([0.2, 0.5, 1.0]), u, v_p,
                                      jnp.asarray([2.0, 1.0]), 3))
    np.testing.assert_allclose(out, [[0.8, 0.6], [0.5, 1.0], [3.0, -1.0]], rtol=1e-12)


def test_wall_images_mirror_the_grains_in_one_sided_walls_they_project_onto():
    # floor (0,0)→(1,0) with its fluid above (side +1); a two-sided wall; a right wall
    a = jnp.asarray([[0.0, 0.0], [0.0, 0.5], [1.0, 0.0]])
    b = jnp.asarray([[1.0, 0.0], [1.0, 0.5], [1.0, 1.0]])
    side = jnp.asarray([1, 0, 1])          # the right wall's left side: (−t_y, t_x) = (−1, 0)
    x_p = jnp.asarray([[0.3, 0.002], [1.2, 0.002], [0.3, -0.001], [0.997, 0.4]])
    img, on, _, n_in = fpi.wall_images(x_p, a, b, side)
    np.testing.assert_allclose(np.asarray(n_in), [[0.0, 1.0], [0.0, 0.0], [-1.0, 0.0]],
                               atol=1e-15)
    # (the first grain's image in the right wall is 1.4 m off: its kernel values are zero)
    np.testing.assert_array_equal(np.asarray(on), [[True, False, True],    # above the floor
                                                   [False, False, False],  # beyond its end
                                                   [False, False, False],  # behind it
                                                   [True, False, True]])   # floor and right
    np.testing.assert_allclose(np.asarray(img[0, 0]), [0.3, -0.002], atol=1e-15)
    np.testing.assert_allclose(np.asarray(img[3, 2]), [1.003, 0.4], atol=1e-15)
    np.testing.assert_allclose(np.asarray(img[3, 0]), [0.997, -0.4], atol=1e-15)


def test_a_grain_and_its_floor_image_give_the_fluid_the_grains_whole_kernel_mass():
    """Σ_f V_f W_pf over a fluid lattice above a floor is short by the kernel's part below
    it; with the image's W_p'f the sum is the kernel's unit mass (to lattice quadrature)."""
    kern = kernels.get("wendland")
    h, dx = 0.003, 0.0003
    xs = np.stack(np.meshgrid(np.arange(-40, 41) * dx, (np.arange(0, 40) + 0.5) * dx),
                  -1).reshape(-1, 2)
    n = xs.shape[0]
    x_p = jnp.asarray([[0.0, 0.5 * h]])
    walls = (jnp.asarray([[-1.0, 0.0]]), jnp.asarray([[1.0, 0.0]]), jnp.asarray([1]))
    rows = fpi.grain_rows(kern, jnp.asarray(xs), jnp.full(n, h), jnp.full(n, dx * dx), x_p,
                          jnp.arange(n)[None, :], n, fpi.wall_images(x_p, *walls))
    alone = float(jnp.sum(rows.w * rows.vol))
    whole = float(jnp.sum(rows.ws * rows.vol))
    assert alone < 0.9                                   # a part lies inside the floor
    assert whole == pytest.approx(1.0, abs=2e-3)
    # the step's voidage from the same rows, and the builders' brute-force one, agree
    vol_p = jnp.asarray([1e-6])
    eps = fpi.fluid_voidage(rows.ws, vol_p, rows.idx, rows.valid, n)
    np.testing.assert_allclose(np.asarray(eps), np.asarray(
        fpi.voidage_at(kern, xs, np.full(n, h), x_p, vol_p, walls=walls)), rtol=1e-12)
    # the shared force and the flux use the same weights: a uniform cell force is shared
    # whole (momentum), and grains at rest add no flux
    force_f = jnp.tile(jnp.asarray([[0.0, 2.0]]), (n, 1))
    got = fpi.cell_share_on_grains(rows, force_f * (1 - eps)[:, None], vol_p, n)
    np.testing.assert_allclose(float(got[0, 1]), float(jnp.sum(2.0 * (1 - eps))), rtol=1e-10)


def test_voidage_with_wall_images_is_differentiable_in_the_grains_position():
    """∂/∂x_p of Σ_f ε_f² (a smooth function of the voidage field) with a grain 0.6 h above
    a floor: jax.grad through wall_images and the image's kernel sum against central
    differences."""
    kern = kernels.get("wendland")
    h, dx = 0.003, 0.001
    xs = jnp.asarray(np.stack(np.meshgrid(np.arange(-8, 9) * dx, (np.arange(0, 9) + 0.5) * dx),
                              -1).reshape(-1, 2))
    n = xs.shape[0]
    walls = (jnp.asarray([[-1.0, 0.0]]), jnp.asarray([[1.0, 0.0]]), jnp.asarray([1]))

    def loss(theta, w=walls):
        eps = fpi.voidage_at(kern, xs, jnp.full(n, h), theta[None, :], jnp.asarray([4e-6]),
                             walls=w)
        return jnp.sum(eps ** 2)

    theta = jnp.asarray([0.0003, 0.6 * h])
    g = fd_check(loss, theta, rel_step=1e-4, tol=1e-5)
    alone = np.asarray(jax.grad(lambda t: loss(t, None))(theta))
    assert abs(g[1] - alone[1]) > 0.1 * abs(alone[1])      # the image is in the gradient


def test_added_mass_is_ca_rho_vp_on_wet_grains_only():
    """m_a = C_a ρ_f V_p (C_a = 1: a circular cylinder in potential flow), 0 when dry."""
    vol = jnp.asarray([2.0e-6, 3.0e-6])
    m_a = fpi.added_mass(1.0, 1000.0, vol, jnp.asarray([0.7, 0.0]))
    np.testing.assert_allclose(np.asarray(m_a), [2.0e-3, 0.0], rtol=1e-14)
    assert float(fpi.added_mass(0.5, 1000.0, vol, jnp.ones(2))[1]) == pytest.approx(1.5e-3)


def test_added_mass_force_is_ma_times_fluid_minus_grain_acceleration():
    """F_a = m_a (Du/Dt − Δv_p/Δt): a grain that keeps pace with the fluid takes none."""
    m_a = jnp.asarray([2.0e-3, 2.0e-3])
    du = jnp.asarray([[0.0, 0.0], [1.0, -2.0]])
    dv = jnp.asarray([[0.0, -1.0e-4], [1.0e-4, -2.0e-4]])
    f = np.asarray(fpi.added_mass_force(m_a, du, dv, 1.0e-4))
    np.testing.assert_allclose(f[0], [0.0, 2.0e-3], rtol=1e-12)
    np.testing.assert_allclose(f[1], [0.0, 0.0], atol=1e-15)


def test_fluid_acceleration_is_the_shepard_average_and_zero_when_dry():
    kern = kernels.get("wendland")
    x_f = jnp.asarray([[0.0, 0.001], [0.001, 0.0], [0.05, 0.05]])
    acc = jnp.asarray([[1.0, 0.0], [0.0, 3.0], [9.0, 9.0]])
    idx = jnp.asarray([[0, 1, 3], [3, 3, 3]])        # grain 1 has no fluid neighbour
    rows = fpi.grain_rows(kern, x_f, jnp.full(3, 0.002), jnp.full(3, 1e-6),
                          jnp.zeros((2, 2)), idx, 3)
    du = np.asarray(fpi.fluid_acceleration(rows, acc))
    w = np.asarray(rows.w[0, :2])
    np.testing.assert_allclose(du[0], [w[0] / w.sum(), 3.0 * w[1] / w.sum()], rtol=1e-6)
    np.testing.assert_array_equal(du[1], [0.0, 0.0])


def test_added_mass_limit_is_half_the_mass_the_weights_see_shared_between_grains():
    """½ / Σ_f s_pf L_f/m_f with s the Shepard weights and L_f the reaction shares f takes
    from all grains: one grain with two fluid neighbours of weights 3:1 and masses 2 and 1
    g gets ½ / (0.75²/2 + 0.25²/1) = 1.455 g; a second grain on the same two particles
    halves it."""
    z = jnp.zeros((1, 2, 2))
    one = fpi.GrainRows(jnp.asarray([[0, 1]]), jnp.asarray([[True, True]]),
                        jnp.asarray([[3.0, 1.0]]), jnp.asarray([[1.0, 1.0]]), z, z[..., 0])
    m_f = jnp.asarray([2.0e-3, 1.0e-3])
    want = 0.5 / (0.75 ** 2 / 2.0e-3 + 0.25 ** 2 / 1.0e-3)
    assert float(fpi.added_mass_limit(one, m_f)[0]) == pytest.approx(want, rel=1e-12)
    two = fpi.GrainRows(jnp.asarray([[0, 1], [0, 1]]), jnp.ones((2, 2), bool),
                        jnp.asarray([[3.0, 1.0], [3.0, 1.0]]), jnp.ones((2, 2)),
                        jnp.zeros((2, 2, 2)), jnp.zeros((2, 2)))
    np.testing.assert_allclose(np.asarray(fpi.added_mass_limit(two, m_f)), want / 2,
                               rtol=1e-12)


def test_an_image_counts_only_for_the_fluid_on_its_walls_side():
    """A grain beside a thin obstacle's face (its outline one-sided outward for the images)
    gives its image's kernel to the fluid on its own side only: water behind the face (on
    the obstacle's far side, or beyond a far grain's mirror) sees no solid from it."""
    kern = kernels.get("wendland")
    h = 0.003
    walls = (jnp.asarray([[0.0, -1.0]]), jnp.asarray([[0.0, 1.0]]), jnp.asarray([1]))
    # the wall x = 0 from (0,-1) to (0,1), side +1: its left, −x, is the fluid's side
    x_p = jnp.asarray([[-0.002, 0.0]])
    x_f = np.asarray([[-0.001, 0.0], [0.002, 0.0], [0.004, 0.0]])     # front; behind ×2
    eps = np.asarray(fpi.voidage_at(kern, x_f, np.full(3, h), x_p, jnp.asarray([1e-6]),
                                    walls=walls))
    alone = np.asarray(fpi.voidage_at(kern, x_f, np.full(3, h), x_p, jnp.asarray([1e-6])))
    assert eps[0] < alone[0]                     # the image adds solid in front
    np.testing.assert_allclose(eps[1:], alone[1:], rtol=1e-12)     # none behind
