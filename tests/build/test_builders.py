"""The public builders of fpsi_jax.build against hand-counted values."""
import math

import numpy as np
import pytest

from fpsi_jax import build
from fpsi_jax.model.errors import ParameterError
from fpsi_jax.physics import eos


def test_inside_polygon_even_odd_rule():
    tri = [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0)]
    pts = np.array([[0.2, 0.2], [0.6, 0.6], [0.49, 0.49], [-0.1, 0.5], [0.5, -0.01]])
    assert build.inside_polygon(pts, tri).tolist() == [True, False, True, False, False]
    with pytest.raises(ParameterError):
        build.inside_polygon(pts, [(0, 0), (1, 1)])


def test_polygon_lattice_keeps_the_cells_inside():
    # a 1 × 1 right triangle on a 0.1 lattice: cell centres (i+½, j+½)/10 with i + j + 1 < 10
    pts = build.polygon_lattice([(0, 0), (1, 0), (0, 1)], 0.1)
    assert pts.shape == (45, 2)
    assert np.all(pts.sum(axis=1) < 1.0)


def test_in_region_rectangle_polygon_and_function():
    x = np.array([[0.0, 0.0], [1.0, 1.5], [2.0, 1.0]])
    assert build.in_region(x, (0.5, 0.5, 1.5, 1.5)).tolist() == [False, True, False]
    assert build.in_region(x, [(0.5, 0.5), (3, 0.5), (3, 3)]).tolist() == [False, False, True]
    assert build.in_region(x, lambda p: p[:, 0] < 0.5).tolist() == [True, False, False]


def test_fluid_rectangle_is_hydrostatic():
    dx, rho0, c0, h = 0.01, 1000.0, 20.0, 0.0125
    f = build.fluid_rectangle(0.0, 0.0, 0.1, 0.2, dx, rho0, c0, h)
    assert f.n == 10 * 20
    assert np.allclose(f.mass, rho0 * dx * dx) and np.allclose(f.h, h)
    assert np.all(f.v == 0)
    bottom = np.argmin(f.x[:, 1])
    p = rho0 * build.G * (0.2 - f.x[bottom, 1])          # the surface at the block's top
    assert f.rho[bottom] == pytest.approx(float(eos.density(p, rho0, c0, 7.0)), rel=1e-6)


def test_fluid_polygon_counts_the_polygon_lattice():
    f = build.fluid_polygon([(0, 0), (1, 0), (0, 1)], 0.1, 1000.0, 20.0, 0.125)
    assert f.n == 45


def test_tank_layers_cover_the_kernel_and_walls_follow_the_outline():
    t = build.tank(0.6, 0.3, 0.005, 0.00625, 1000.0, dem_walls=True)
    assert t.layers == math.ceil(2 * 0.00625 / 0.005) == 3
    # open-top box: the outer lattice (0.6 + 2·0.015) × (0.3 + 0.015) minus the inside
    assert t.boundary.n == 126 * 63 - 120 * 60
    assert np.allclose(t.boundary.mass, 1000.0 * 0.005 ** 2) and np.all(t.boundary.p == 0)
    assert t.walls.n == 3
    lo, hi = t.domain(headroom=0.5)
    pad = 3 * 0.005 + 2 * 0.00625
    assert lo == pytest.approx((-pad, -pad)) and hi == pytest.approx((0.6 + pad, 0.45))
    assert build.tank(0.6, 0.3, 0.005, 0.00625, 1000.0).walls is None


def test_tank_spacing_is_fitted_so_both_walls_stand_half_a_spacing_out():
    """0.05 m at 1.5 mm is 33.3 spacings: the tank lays 33 of 0.05/33 m, so the innermost
    particles of the left and the right wall are dxb/2 outside the box on both sides (on
    a 1.5 mm lattice from the left the right wall stood 1 mm out, against 0.75 mm)."""
    t = build.tank(0.05, 0.1, 0.0015, 0.003, 1000.0)
    dxb = 0.05 / 33
    x = t.boundary.x[:, 0]
    assert x[x < 0].max() == pytest.approx(-dxb / 2, rel=1e-9)
    assert x[x > 0.05].min() == pytest.approx(0.05 + dxb / 2, rel=1e-9)
    assert np.allclose(t.boundary.mass, 1000.0 * dxb ** 2)
    with pytest.raises(ParameterError, match="whole number"):
        build.tank_walls(0.05, 0.1, 0.0015, 4)


def test_bonded_rectangle_mass_bonds_and_stiffness():
    d, E, nu, rho = 0.0025, 1.0e7, 0.4, 1100.0
    s = build.bonded_rectangle(0.0, 0.0, 0.01, 0.1, d, E, nu, rho, plane_strain=True)
    nx, ny = 4, 40
    assert s.solid.n == nx * ny
    assert s.bonds.n == nx * (ny - 1) + ny * (nx - 1)           # square lattice neighbours
    assert s.solid.mass.sum() == pytest.approx(rho * 0.01 * 0.1)  # mass per area is ρ
    assert np.allclose(s.solid.volumes(), d * d)
    e_ps = E / (1 - nu * nu)                                     # plane strain
    assert float(s.bond.kn) * 1.01 == pytest.approx(e_ps / d)     # K42 with 1 % to contacts
    assert s.kn * 1.01 == pytest.approx(0.01 * e_ps)
    assert np.all(s.solid.structure)


def test_clamp_and_move_set_kinematic_discs():
    s = build.bonded_rectangle(0.0, 0.0, 0.01, 0.1, 0.0025, 1.0e7, 0.3, 1100.0)
    top = build.clamp(s.solid, (-1, 0.098, 1, 1))
    assert top.size == 4 and np.all(s.solid.fixed[top]) and np.all(s.solid.v[top] == 0)
    lift = build.move(s.solid, (-1, -1, 1, 0.003), (0.0, 0.05))
    assert lift.size == 4 and np.all(s.solid.fixed[lift])
    assert np.allclose(s.solid.v[lift], [0.0, 0.05])
    assert s.solid.fixed.sum() == 8
    with pytest.raises(ParameterError, match="holds no disc"):
        build.clamp(s.solid, (5, 5, 6, 6))


def test_grain_bed_mass_and_count():
    g = build.grain_bed(0.0, 0.0, 0.05, 0.02, 0.0025, 2650.0, n=30)
    assert g.n == 30 and np.all(g.grain)
    assert np.allclose(g.mass, 2650.0 * math.pi * 0.00125 ** 2)
    assert np.all(g.x[:, 1] <= g.x[-1, 1] + 1e-12)                # bottom rows first
    with pytest.raises(ParameterError):
        build.grain_bed(0.0, 0.0, 0.05, 0.02, 0.0025, 2650.0, n=10_000)


def test_merge_shifts_bond_indices():
    g = build.grain_bed(0.0, 0.0, 0.01, 0.005, 0.0025, 2650.0)
    s = build.bonded_rectangle(0.1, 0.0, 0.005, 0.005, 0.0025, 1.0e7, 0.3, 1100.0)
    solid, bonds = build.merge(g, s)
    assert solid.n == g.n + s.solid.n
    assert bonds.n == s.bonds.n and int(bonds.i.min()) == g.n
    assert solid.grain[:g.n].all() and not solid.grain[g.n:].any()
    assert solid.structure[g.n:].all() and not solid.structure[:g.n].any()


def test_stretched_strip_has_its_end_columns_on_the_box_edges():
    """79.375 mm at d = 1.25 mm: ⌊63.5⌋ = 63 gaps of 1.2599 mm, 64 columns from x = 0 to
    x = L exactly; 4 rows d apart; the gap bonds found with gap = s − d, the diagonals not."""
    L, d = 0.079375, 0.00125
    s = build.span_spacing(L, d)
    assert s == pytest.approx(L / 63, rel=1e-15) and s >= d
    x = build.square_packing(0.0, -0.0025, L, 0.005, d, stretch=True)
    xs = np.unique(x[:, 0])
    assert xs.size == 64 and xs[0] == 0.0 and xs[-1] == pytest.approx(L, rel=1e-14)
    np.testing.assert_allclose(np.unique(x[:, 1]), [-0.001875, -0.000625, 0.000625, 0.001875])
    bonds = build.touching_pairs(x, d / 2, gap=s - d)
    assert bonds.n == 63 * 4 + 64 * 3               # along the rows + across them
    assert build.span_spacing(0.0025 * 4, 0.0025) == pytest.approx(0.0025, rel=1e-15)
    with pytest.raises(ParameterError, match="span"):
        build.span_spacing(0.001, 0.0025)


def test_strip_ends_carry_half_a_cell():
    """Lattice masses ρ·d·s per disc, halved on the end columns: the strip's mass is
    ρ·height·L (1100·0.005·0.079375 = 0.43656 kg per m of thickness)."""
    L, d, rho = 0.079375, 0.00125, 1100.0
    s = build.span_spacing(L, d)
    x = build.square_packing(0.0, -0.0025, L, 0.005, d, stretch=True)
    blk = build.disc_block(x, d / 2, rho, mass_model="lattice", packing="square",
                           column_spacing=s)
    assert blk.mass[0] == pytest.approx(rho * d * s, rel=1e-14)
    blk = build.strip_ends(blk, 0.0, L)
    assert blk.mass.sum() == pytest.approx(rho * 0.005 * L, rel=1e-12)
    assert blk.mass.sum() == pytest.approx(0.4365625, rel=1e-12)
    ends = (x[:, 0] == 0.0) | (np.abs(x[:, 0] - L) < 1e-12)
    np.testing.assert_allclose(blk.inertia[ends], 0.5 * blk.mass[ends] * (d / 2) ** 2)


def test_a_scene_is_built_the_same_whatever_precision_jax_is_in():
    # the builders call the step's own JAX functions (the Tait inverse, the grains' voidage):
    # they compute in float64 whatever JAX's process-wide x64 flag says, so a scene does not
    # depend on what ran before it in the process
    import jax

    def built():
        fluid = build.fluid_rectangle(0.0, 0.0, 0.04, 0.03, 0.002, 1000.0, 20.0, 0.003)
        grains = build.grain_bed(0.0, 0.0, 0.04, 0.01, 0.004, 2650.0)
        fluid = build.fluid_among_grains(fluid, grains.x, grains.radius, "area")
        wall = build.boundary_block(fluid.x[:5], 1000.0, 0.002, 0.003,
                                    p=np.linspace(0.0, 300.0, 5), c0=20.0)
        return fluid.rho, fluid.mass, wall.rho

    prev = jax.config.jax_enable_x64
    try:
        jax.config.update("jax_enable_x64", False)
        off = built()
        jax.config.update("jax_enable_x64", True)
        on = built()
    finally:
        jax.config.update("jax_enable_x64", prev)
    for a, b in zip(off, on):
        assert a.dtype == np.float64 and np.array_equal(a, b)
    # and in float64 indeed: the hydrostatic density at 300 Pa to 1e-12 (Tait inverse by hand)
    b_tait = 20.0 ** 2 * 1000.0 / 7.0
    assert on[2][-1] == pytest.approx(1000.0 * (1 + 300.0 / b_tait) ** (1 / 7), rel=1e-12)
