"""Probes against hand values on hand-made states, and recorded by simulate into the
result, the HDF5 file and the CSV."""
from types import SimpleNamespace as NS

import jax.numpy as jnp
import numpy as np
import pytest

from fpsi_jax.build import disc_block, fluid_rectangle, sph_params, touching_pairs
from fpsi_jax.model.errors import ParameterError
from fpsi_jax.model.params import DemParams, Params
from fpsi_jax.model.scene import Scene
from fpsi_jax.physics import eos
from fpsi_jax.run import probes as P
from fpsi_jax.run.driver import simulate
from fpsi_jax.run.io import read

DX = 0.01


def scene(fluid=True, solid=True):
    sp = sph_params(1000.0, 20.0, 1e-3, DX, 0.01, 0.5, 0.1)
    fl = fluid_rectangle(0.0, 0.0, 0.1, 0.05, DX, 1000.0, 20.0, 1.3 * DX) if fluid else None
    blk = None
    if solid:
        blk = disc_block(np.array([[0.2, 0.01], [0.21, 0.01], [0.22, 0.01], [0.4, 0.02]]),
                         0.005, 2000.0)
        blk.structure = np.array([True, True, True, False])
    return Scene(name="probe_test", params=Params(sph=sp if fluid else None,
                                                  dem=DemParams() if solid else None),
                 domain_lo=(-0.1, -0.1), domain_hi=(0.6, 0.3), v_max=1.0, fluid=fl,
                 solid=blk, options={"fsi": "stationary"} if fluid and solid else {})


def solid_state(x, **kw):
    """A state with just what the solid probes read (float32, as a run)."""
    return NS(solid=NS(x=jnp.asarray(x), radius=jnp.full(len(x), 0.005)), **kw)


def test_displacement_is_the_mean_shift_of_the_selected_discs():
    sc = scene(fluid=False)
    p = P.displacement("tip", sc, [0, 1])
    x = sc.solid.x.copy()
    x[0] += (0.003, -0.001)
    x[1] += (0.001, 0.003)
    x[3] += (1.0, 1.0)                      # not selected
    np.testing.assert_allclose(p(solid_state(x)), [0.002, 0.001], atol=1e-7)
    assert p.components == ("ux", "uy") and p.units == ("m", "m")


def test_force_sums_the_fluid_force_and_its_moment_about_the_centroid():
    sc = scene()
    p = P.force("load", sc, [0, 1, 2])
    f = np.array([[1.0, 2.0], [3.0, -1.0], [0.5, 0.5]])
    s = solid_state(sc.solid.x, fsi=NS(force=jnp.asarray(f), idx=jnp.arange(3)))
    c = sc.solid.x[:3].mean(axis=0)                               # (0.21, 0.01)
    r = sc.solid.x[:3] - c
    m = float(np.sum(r[:, 0] * f[:, 1] - r[:, 1] * f[:, 0]))      # −0.01·2 + 0.01·0.5
    np.testing.assert_allclose(p(s), [4.5, 1.5, m], atol=1e-7)
    assert m == pytest.approx(-0.015)


def test_force_refuses_discs_that_are_not_coupled_structure():
    with pytest.raises(ParameterError, match="structure disc or a grain"):
        P.force("f", scene(), [3])


def test_force_on_grains_is_the_fluids_force_on_them(tmp_path):
    """A bed of 4 mm grains at rest under still water (a scene file): the probe reads
    Σ FpiState.force of its grains, and its vertical force is about their buoyancy, ρ g Σ V
    (the start's pressure carries it within the kernel's error at a floor, ~10 %)."""
    from fpsi_jax import scenefile
    path = tmp_path / "bed.toml"
    path.write_text(GRAIN_BED)
    sf = scenefile.load(str(path))
    res = simulate(sf.scene, probes=sf.probes, progress=False)
    f = np.asarray(res.probes["lift"])[-1]
    np.testing.assert_allclose(f[:2], np.asarray(res.state.fpi.force).sum(0), rtol=1e-5)
    g = sf.scene.solid.grain_indices()
    buoyancy = 1000.0 * 9.81 * float(np.sum(np.pi * np.asarray(sf.scene.solid.radius)[g] ** 2))
    assert f[1] == pytest.approx(buoyancy, rel=0.15)
    assert abs(f[0]) < 0.02 * buoyancy
    # a front probe on the same grains: their farthest edge, from the file's keys
    x, r = np.asarray(res.state.solid.x)[g], np.asarray(res.state.solid.radius)[g]
    assert res.probes["reach"][-1, 0] == pytest.approx(float(np.max(x[:, 0] + r)), abs=1e-6)
    assert res.probes["top"][-1, 0] == 0.0                # no grain above 5 cm


GRAIN_BED = """
[scene]
t_end = 0.002
[fluid]
dx = 0.005
fit_width = 0.1
[[fluid.region]]
box = [0.0, 0.0, 0.1, 0.06]
[tank]
width = 0.1
height = 0.1
[[grains]]
name = "bed"
box = [0.0, 0.0, 0.1, 0.016]
d = 0.004
rho = 2650.0
[contacts]
kn = 1.0e7
friction = 0.5
[[probe]]
name = "lift"
kind = "force"
body = "bed"
[[probe]]
name = "reach"
kind = "front"
body = "bed"
[[probe]]
name = "top"
kind = "front"
body = "bed"
above = 0.05
"""


def test_force_on_grains_of_a_registered_bed_reads_their_fluid_force_only():
    """A bed built by Python (no structure flags: every disc counts as structure to
    structure_indices) has no FSI coupling: the probe reads the grains' FpiState.force."""
    from fpsi_jax import cases
    sc = cases.build("grain_bed", t_end=0.01)
    p = P.force("f", sc, range(5))
    g = sc.solid.grain_indices()
    f = np.zeros((g.size, 2))
    f[:5] = [[1.0, 2.0]] * 5
    s = solid_state(sc.solid.x, fsi=None, fpi=NS(force=jnp.asarray(f), idx=jnp.asarray(g)))
    np.testing.assert_allclose(p(s)[:2], [5.0, 10.0], rtol=1e-6)


def test_force_on_discs_of_a_dry_scene_is_refused_before_the_run():
    # it is the fluid's force: a dry scene has none (a run crashed with a traceback)
    with pytest.raises(ParameterError, match="no fluid.*obstacle"):
        P.force("f", scene(fluid=False), [0, 1, 2])


def test_obstacle_force_sums_its_rows_and_their_moment_about_their_centroid():
    """Rows (1, 4) of a boundary of five: the sum of their recorded forces and
    Σ (x_B − c) × F_B, c their centroid; the other rows' forces are not read."""
    xb = np.array([[0.0, 0.0], [0.1, 0.0], [0.2, 0.0], [0.3, 0.0], [0.9, 0.9]])
    sc = NS(boundary=NS(n=5, x=xb))
    p = P.obstacle_force("pier", sc, (1, 4))
    f = np.array([[9.0, 9.0], [1.0, 2.0], [3.0, -1.0], [0.5, 0.5], [9.0, 9.0]])
    m = -0.1 * 2.0 + 0.1 * 0.5                    # about (0.2, 0): rows 1 and 3 lever ±0.1
    np.testing.assert_allclose(p(NS(boundary=NS(force=jnp.asarray(f)))), [4.5, 1.5, m],
                               atol=1e-7)
    assert P.wall_force_rows([p, P.obstacle_force("b", sc, (3, 5))]) == (1, 5)
    assert P.wall_force_rows([]) == ()
    with pytest.raises(ParameterError, match="out of range"):
        P.obstacle_force("pier", sc, (2, 6))


def test_obstacle_force_adds_its_walls_reaction_with_the_moment_moved_to_about():
    """Walls (1, 3) of four: their recorded (F_x, F_y, moment about the origin) summed, the
    moment moved to ``about`` c: M_c = M_0 − c × F; with boundary rows as well, both add."""
    walls = NS(n=4, a=np.zeros((4, 2)), b=np.ones((4, 2)))
    sc = NS(walls=walls, boundary=NS(n=2, x=np.array([[0.0, 0.0], [0.2, 0.0]])))
    r = np.array([[9.0, 9.0, 9.0], [1.0, -2.0, 0.3], [0.5, -1.0, 0.1], [9.0, 9.0, 9.0]])
    p = P.obstacle_force("pier", sc, walls=(1, 3), about=(0.1, 0.2))
    m = 0.4 - (0.1 * -3.0 - 0.2 * 1.5)
    st = NS(walls=NS(reaction=jnp.asarray(r)), boundary=NS(force=jnp.asarray([[1.0, 0.0],
                                                                               [0.0, 2.0]])))
    np.testing.assert_allclose(p(st), [1.5, -3.0, m], rtol=1e-6)
    both = P.obstacle_force("pier", sc, (0, 2), (0.1, 0.2), (1, 3))
    m_rows = (-0.1 * 0.0 + 0.2 * 1.0) + (0.1 * 2.0 + 0.2 * 0.0)       # (x_B − c) × F_B
    np.testing.assert_allclose(both(st), [2.5, -1.0, m + m_rows], rtol=1e-6)
    assert P.wall_reaction([p]) and not P.wall_reaction([P.obstacle_force("b", sc, (0, 2))])
    with pytest.raises(ParameterError, match="out of range"):
        P.obstacle_force("pier", sc, walls=(2, 5))
    with pytest.raises(ParameterError, match="neither"):
        P.obstacle_force("pier", sc)


STONES = """
[scene]
t_end = 0.1
[tank]
width = 0.3
height = 0.25
[[obstacle]]
name = "block"
box = [0.1, 0.0, 0.2, 0.05]
[[discs]]
name = "stones"
points = [[0.12, 0.055], [0.17, 0.06]]
radius = 0.005
rho = 2700.0
[contacts]
kn = 1.0e5
beta_n = 0.3
[[probe]]
name = "load"
kind = "force"
body = "block"
"""


def test_force_on_an_obstacle_is_the_weight_of_the_stones_resting_on_it(tmp_path):
    """Two stones (R = 5 mm, ρ 2700: m g = 2.0803 N/m each) dropped onto a block, dry: once
    they rest, its DEM walls carry their weight, −2 m g, with the moment about the block's
    centre (0.15, 0.025) of their levers −0.03 and +0.02 m: +0.01 m g."""
    from fpsi_jax import scenefile
    path = tmp_path / "stones.toml"
    path.write_text(STONES)
    sf = scenefile.load(str(path))
    assert sf.scene.options["wall_reaction"] and sf.probes[0].spec["dem_walls"] == [3, 7]
    res = simulate(sf.scene, probes=sf.probes, progress=False)
    mg = 2700.0 * np.pi * 0.005 ** 2 * 9.81
    np.testing.assert_allclose(res.probes["load"][-1], [0.0, -2 * mg, 0.01 * mg],
                               rtol=1e-4, atol=1e-5 * mg)


def test_force_on_the_tanks_floor_is_the_weight_of_the_stones_on_it(tmp_path):
    """The same stones dropped on the tank's floor beside the block: `tank.floor` reads
    their weight through the floor's DEM wall; the block and the side walls carry none."""
    from fpsi_jax import scenefile
    path = tmp_path / "stones.toml"
    text = STONES.replace("[[0.12, 0.055], [0.17, 0.06]]", "[[0.03, 0.0051], [0.25, 0.0052]]")
    path.write_text(text + '[[probe]]\nname = "floor"\nkind = "force"\nbody = "tank.floor"\n'
                    '[[probe]]\nname = "left"\nkind = "force"\nbody = "tank.left"\n')
    sf = scenefile.load(str(path))
    assert [p.spec["dem_walls"] for p in sf.probes] == [[3, 7], [0, 1], [1, 2]]
    res = simulate(sf.scene, probes=sf.probes, progress=False)
    mg = 2700.0 * np.pi * 0.005 ** 2 * 9.81
    np.testing.assert_allclose(res.probes["floor"][-1, :2], [0.0, -2 * mg], atol=1e-4 * mg)
    np.testing.assert_allclose(res.probes["load"][-1, :2], 0.0, atol=1e-6)
    np.testing.assert_allclose(res.probes["left"][-1, :2], 0.0, atol=1e-6)


KINEMATIC_BLOCK = STONES.replace("""[[obstacle]]
name = "block"
box = [0.1, 0.0, 0.2, 0.05]""", """[[kinematic]]
name = "block"
box = [0.1, 0.0, 0.2, 0.05]
d = 0.005
rho = 7800.0
velocity = [0.0, 0.0]""")


def test_force_on_kinematic_discs_is_the_weight_of_the_stones_resting_on_them(tmp_path):
    """The same two stones dropped onto a block of kinematic discs (at rest), dry: once they
    rest, the probe on the block reads their weight, −2 m g, and its moment about the
    block's centroid, −Σ (x_s − c_x) m g with x_s where the stones came to rest (between
    two of the block's discs)."""
    from fpsi_jax import scenefile
    path = tmp_path / "stones.toml"
    path.write_text(KINEMATIC_BLOCK)
    sf = scenefile.load(str(path))
    held = sf.probes[0].spec["held_discs"]
    assert tuple(sf.scene.options["disc_reaction"]) == tuple(held) and len(held) == 200
    res = simulate(sf.scene, probes=sf.probes, progress=False)
    mg = 2700.0 * np.pi * 0.005 ** 2 * 9.81
    stones = np.flatnonzero(~np.asarray(sf.scene.solid.fixed))
    xs = np.asarray(res.state.solid.x)[stones, 0]
    c = sf.probes[0].spec["about"]
    np.testing.assert_allclose(res.probes["load"][-1],
                               [0.0, -2 * mg, -np.sum(xs - c[0]) * mg],
                               rtol=1e-4, atol=1e-4 * mg)   # F_x: a groove's two contacts
    #                                                          cancel to float32 round-off


CLAMPED_ARM = """
[scene]
t_end = 0.3
[tank]
width = 0.1
height = 0.05
[[structure]]
name = "arm"
box = [0.02, 0.02, 0.06, 0.025]
d = 0.0025
E = "1 MPa"
rho = 1000.0
clamp = [0.019, 0.019, 0.0225, 0.026]
[contacts]
alpha = 0.7
[physics]
x64 = true
[[probe]]
name = "root"
kind = "force"
body = "arm"
region = [0.019, 0.019, 0.0225, 0.026]
"""


def test_force_on_a_clamp_is_the_weight_and_moment_of_the_arm_it_holds(tmp_path):
    """A bonded arm 40 × 5 mm clamped by its first column of discs sags under gravity to
    rest (local damping α = 0.7): the probe on the clamp's discs reads what its bonds and
    contacts take, the weight of the free discs W = Σ m g and the moment of their weights
    about the clamp, −Σ (x_i − c_x) m_i g at their resting positions, within 10⁻⁴. (In
    float32 the same run creeps there an order of magnitude more slowly, 2.7 % off at
    0.3 s: physics.md, local damping.)"""
    from fpsi_jax import scenefile
    path = tmp_path / "arm.toml"
    path.write_text(CLAMPED_ARM)
    sf = scenefile.load(str(path))
    res = simulate(sf.scene, probes=sf.probes, progress=False)
    so = sf.scene.solid
    free = ~np.asarray(so.fixed)
    w = np.asarray(so.mass)[free] * 9.81
    x = np.asarray(res.state.solid.x)[free, 0]
    c = sf.probes[0].spec["about"]
    np.testing.assert_allclose(res.probes["root"][-1], [0.0, -w.sum(), -np.sum((x - c[0]) * w)],
                               rtol=1e-4, atol=1e-5 * w.sum())


SQUEEZED = """
[scene]
t_end = 0.01
[tank]
width = 0.1
height = 0.1
[[structure]]
name = "specimen"
box = [0.03, 0.0, 0.05, 0.04]
d = 0.0025
E = "10 MPa"
rho = 1000.0
packing = "square"
clamp = [0.029, 0.0, 0.051, 0.0026]
move = {region = [0.029, 0.0374, 0.051, 0.041], velocity = [0.0, -0.02]}
[contacts]
alpha = 0.7
[physics]
x64 = true
[[probe]]
name = "top"
kind = "force"
body = "specimen"
region = [0.029, 0.0374, 0.051, 0.041]
[[probe]]
name = "bottom"
kind = "force"
body = "specimen"
region = [0.029, 0.0, 0.051, 0.0026]
[[probe]]
name = "top_u"
kind = "displacement"
body = "specimen"
region = [0.029, 0.0374, 0.051, 0.041]
"""


def test_a_specimen_squeezed_by_its_own_end_rows_reads_e_through_the_probes(tmp_path):
    """A square lattice of bonded discs 20 × 40 mm (d = 2.5 mm, E = 10 MPa), its bottom row
    clamped and its top row driven down at 20 mm/s (``move``), slowly against its first
    mode: each column is a chain of bars E·d/d0 (K42 with the contact split: in
    compression bond and contact springs add to E), so the load on the top row over the
    width W = 20 mm against the strain over the H = 37.5 mm between the rows' centres is E:
    within 1 % at 0.5 % strain, and the clamp carries the same load within 1 %."""
    from fpsi_jax import scenefile
    path = tmp_path / "squeeze.toml"
    path.write_text(SQUEEZED)
    sf = scenefile.load(str(path))
    res = simulate(sf.scene, probes=sf.probes, progress=False)
    top, bottom, u = (np.asarray(res.probes[k])[-1] for k in ("top", "bottom", "top_u"))
    strain = -u[1] / 0.0375
    assert strain == pytest.approx(0.02 * float(res.times[-1]) / 0.0375, rel=1e-6)
    assert top[1] / 0.02 / strain == pytest.approx(10e6, rel=0.01)
    assert bottom[1] == pytest.approx(-top[1], rel=0.01)


BLOCK = """
[scene]
t_end = 0.15
[fluid]
density = 1000.0
viscosity = 1.0e-3
dx = 0.005
alpha = 0.02
[[fluid.region]]
box = [0.0, 0.0, 0.12, 0.15]
[[fluid.region]]
box = [0.18, 0.0, 0.3, 0.15]
[[fluid.region]]
box = [0.12, 0.05, 0.18, 0.15]
surface = 0.15
[tank]
width = 0.3
height = 0.25
[[obstacle]]
name = "block"
box = [0.12, 0.0, 0.18, 0.05]
[[probe]]
name = "load"
kind = "force"
body = "block"
"""


def test_force_on_an_obstacle_under_still_water_is_the_weight_of_the_water_above_it(
        tmp_path):
    """A block w = 6 cm wide and a = 5 cm high on the floor of still water H = 15 cm deep
    (a scene file, Δx = 5 mm): the water presses it down with ρ g (H − a) w = 58.86 N/m
    and not sideways; the mean over 0.05–0.15 s within 2 % (the lattice start's
    pressure waves swing the force by ±5 % about it)."""
    from fpsi_jax import scenefile
    path = tmp_path / "block.toml"
    path.write_text(BLOCK)
    sf = scenefile.load(str(path))
    assert list(sf.scene.options["wall_force"]) == sf.probes[0].spec["boundary_rows"]
    res = simulate(sf.scene, probes=sf.probes, progress=False)
    f = res.probes["load"][np.asarray(res.times) >= 0.05].mean(axis=0)
    weight = 1000.0 * 9.81 * (0.15 - 0.05) * 0.06
    assert f[1] == pytest.approx(-weight, rel=0.02)
    assert abs(f[0]) < 0.005 * weight
    assert abs(f[2]) < 0.005 * weight * 0.03         # the moment: a lever of 3 cm


def test_pressure_interpolates_a_uniform_state_exactly_and_is_zero_when_dry():
    sc = scene(solid=False)
    fl = sc.fluid
    rho = np.full(fl.n, 1001.0)
    s = NS(fluid=NS(x=jnp.asarray(fl.x), rho=jnp.asarray(rho), mass=jnp.asarray(fl.mass),
                    h=jnp.asarray(fl.h)))
    want = float(eos.pressure(jnp.asarray(rho[:1]), 1000.0, 20.0, 7.0)[0])   # same float32
    assert float(P.pressure("p", sc, (0.05, 0.02))(s)[0]) == pytest.approx(want, rel=1e-6)
    assert float(P.pressure("p", sc, (0.5, 0.2))(s)[0]) == 0.0


def test_water_level_front_and_dry_floor():
    sc = scene(solid=False)
    s = NS(fluid=NS(x=jnp.asarray(sc.fluid.x)))
    # the lattice's top row is at 0.045 and its last column at 0.095 (spacing 0.01)
    assert float(P.water_level("h", sc, 0.05)(s)[0]) == pytest.approx(0.05)
    assert float(P.water_level("h", sc, 0.3, floor=-1.0)(s)[0]) == -1.0
    assert float(P.front("f", sc)(s)[0]) == pytest.approx(0.1)
    assert float(P.front("f", sc, "-x")(s)[0]) == pytest.approx(0.0)


def test_front_above_a_level_and_of_discs():
    """``above``: only water higher than it counts (a bore over tailwater); with discs the
    farthest disc edge, max x + R, of the selected ones."""
    sc = scene(solid=False)
    x = np.asarray(sc.fluid.x, float).copy()
    low = x[:, 1] < 0.02
    x[low, 0] += 0.3                       # a thin sheet of 'tailwater' far downstream
    s = NS(fluid=NS(x=jnp.asarray(x)))
    assert float(P.front("f", sc)(s)[0]) == pytest.approx(0.4)
    assert float(P.front("f", sc, above=0.02)(s)[0]) == pytest.approx(0.1)
    assert float(P.front("f", sc, above=1.0)(s)[0]) == 0.0          # nothing counts
    sd = scene(fluid=False)
    d = solid_state(sd.solid.x)
    assert float(P.front("g", sd, idx=[0, 1, 2])(d)[0]) == pytest.approx(0.225)
    assert float(P.front("g", sd, "-x", idx=[1, 3])(d)[0]) == pytest.approx(0.205)


def test_water_level_between_two_columns_keeps_still_water_level_as_they_jitter():
    """Columns at 0.045 and 0.055, the probe between them at 0.05: particles drifting a
    little sideways (as still water's do) leave the level at the top row's 0.05."""
    sc = scene(solid=False)
    x = np.asarray(sc.fluid.x, float).copy()
    level = P.water_level("h", sc, 0.05)
    for shift in (-0.002, 0.0, 0.002):
        x2 = x.copy()
        x2[:, 0] += np.where(x2[:, 0] < 0.05, -abs(shift), abs(shift))   # columns part
        s = NS(fluid=NS(x=jnp.asarray(x2)))
        assert float(level(s)[0]) == pytest.approx(0.05)


def test_bed_profile_takes_the_top_of_the_grains_in_each_column():
    sc = scene(fluid=False)
    p = P.bed_profile("bed", sc, [0, 1, 2, 3], 0.195, 0.425, 2)   # columns split at 0.31
    x = sc.solid.x.copy()
    x[1, 1] = 0.05
    np.testing.assert_allclose(p(solid_state(x)), [0.055, 0.025], atol=1e-7)
    np.testing.assert_allclose(p.spec["x_centres"], [0.2525, 0.3675])


def test_broken_bonds_counts_the_broken_ones_in_the_set():
    sc = scene(fluid=False)
    sc.bonds = touching_pairs(sc.solid.x, 0.005)                 # 0–1, 1–2
    s = solid_state(sc.solid.x, bonds=NS(intact=jnp.asarray([False, True])))
    assert float(P.broken_bonds("n", sc)(s)[0]) == 1.0
    assert float(P.broken_bonds("n", sc, [1, 2])(s)[0]) == 0.0


def test_probe_names_must_be_unique():
    sc = scene(fluid=False)
    with pytest.raises(ParameterError, match="used twice"):
        P.check_names([P.displacement("a", sc, [0]), P.displacement("a", sc, [1])])


def test_simulate_records_probes_every_step_in_result_hdf5_and_csv(tmp_path):
    sc = scene()
    sc.params = sc.params.replace(dem=DemParams(kn=1e4, ks=5e3))
    sc.solid.structure = None
    sc.t_end = 0.01
    probes = [P.displacement("disc", sc, [3]), P.front("front", sc)]
    out = str(tmp_path / "run.h5")
    res = simulate(sc, output=out, probes=probes, progress=False, every=0.004)
    n = res.n_steps
    assert res.probes["disc"].shape == (n, 2) and res.probes["front"].shape == (n, 1)
    # the free disc falls under gravity: uy = −g t²/2 to the leapfrog's accuracy
    t = res.times
    np.testing.assert_allclose(res.probes["disc"][:, 1], -0.5 * 9.81 * t ** 2, rtol=0.02,
                               atol=1e-7)
    run = read(out)
    np.testing.assert_allclose(run.probes["disc"], res.probes["disc"])
    np.testing.assert_allclose(run.probes["time"], t)
    table = np.loadtxt(str(tmp_path / "run_probes.csv"), delimiter=",", skiprows=1)
    assert table.shape == (n, 4)
    head = open(tmp_path / "run_probes.csv").readline().strip()
    assert head == "t [s],disc.ux [m],disc.uy [m],front.x [m]"


def test_probe_csv_of_a_run_that_stopped_before_its_first_step_has_the_header_only(tmp_path):
    """A run unstable at its first step leaves no probe row: the CSV is its header (the
    driver then reports the instability, not a reshape of the empty columns)."""
    sc = scene()
    probes = [P.displacement("disc", sc, [3]), P.front("front", sc)]
    path = P.write_csv(str(tmp_path / "p.csv"), probes, np.zeros(0),
                       {"disc": np.zeros((0, 2)), "front": np.zeros((0, 1))})
    lines = open(path).read().splitlines()
    assert lines == ["t [s],disc.ux [m],disc.uy [m],front.x [m]"]


def test_a_run_unstable_at_its_first_step_reports_the_instability_with_probes(tmp_path):
    from fpsi_jax.model.errors import SimulationError
    sc = scene()
    sc.params = sc.params.replace(dem=DemParams(kn=1e4, ks=5e3))
    sc.solid.structure = None
    sc.t_end = 0.01
    sc.solid.v = np.array(sc.solid.v, float)
    sc.solid.v[3] = [0.0, -1e5]            # out of the domain within the first step
    out = str(tmp_path / "run.h5")
    with pytest.raises(SimulationError, match="step 1"):
        simulate(sc, output=out, probes=[P.displacement("disc", sc, [3])], progress=False,
                 every=0.004)
    assert read(out).status == "unstable"
    assert open(tmp_path / "run_probes.csv").read().splitlines() == \
        ["t [s],disc.ux [m],disc.uy [m]"]
