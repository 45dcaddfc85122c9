"""What a scene file leaves to be derived: the grains' pressure coupling by whether they
form a bed (Physics.for_scene), and an obstacle's boundary rows for a force probe."""
import re

import numpy as np
import pytest

from fpsi_jax import scenefile
from fpsi_jax.model import motion
from fpsi_jax.model.config import Physics

WATER = """
[scene]
t_end = 0.01
[fluid]
dx = 0.005
[[fluid.region]]
box = [0.0, 0.0, 0.3, 0.05]
[tank]
width = 0.3
height = 0.1
[contacts]
kn = 1.0e5
"""


def compose(tmp_path, text):
    path = tmp_path / "scene.toml"
    path.write_text(text)
    return scenefile.load(str(path))


@pytest.mark.parametrize("grains, pressure", [
    ('box = [0.1, 0.0, 0.2, 0.02]\nd = 0.004', "shared"),           # a packed bed
    ('points = [[0.1, 0.03], [0.2, 0.03]]\nd = 0.004', "archimedes"),  # two apart
    ('points = [[0.1, 0.03], [0.104, 0.03]]\nd = 0.004', "shared"),    # two touching
])
def test_grains_that_touch_share_the_pressure_and_isolated_ones_take_archimedes(
        tmp_path, grains, pressure):
    sf = compose(tmp_path, WATER + f'[[grains]]\nname = "g"\nrho = 2650.0\n{grains}\n')
    assert "fpi_pressure" not in sf.scene.options
    assert Physics.for_scene(sf.scene).fpi_pressure == pressure


def test_a_given_pressure_coupling_wins_over_the_default(tmp_path):
    sf = compose(tmp_path, WATER + '[[grains]]\nname = "g"\nrho = 2650.0\n'
                 'box = [0.1, 0.0, 0.2, 0.02]\nd = 0.004\n[physics]\n'
                 'fpi_pressure = "archimedes"\n')
    assert Physics.for_scene(sf.scene).fpi_pressure == "archimedes"


def test_the_pore_waters_share_of_neighbours_is_read_from_the_physics_table(tmp_path):
    """[physics] pore_neighbours reaches Physics (default 0.5), with η = h/Δx of the
    scene's lattice; out of [0, 1] it is refused naming the key."""
    bed = WATER + '[[grains]]\nname = "g"\nrho = 2650.0\nbox = [0.1, 0.0, 0.2, 0.02]\nd = 0.004\n'
    phys = Physics.for_scene(compose(tmp_path, bed).scene)
    assert phys.pore_neighbours == 0.5
    assert phys.h_over_dp == pytest.approx(float(np.median(
        compose(tmp_path, bed).scene.fluid.h)) / 0.005, rel=1e-12)
    sf = compose(tmp_path, bed + "[physics]\npore_neighbours = 0.8\n")
    assert Physics.for_scene(sf.scene).pore_neighbours == 0.8
    with pytest.raises(scenefile.FileError, match=r"pore_neighbours"):
        compose(tmp_path, bed + "[physics]\npore_neighbours = 1.5\n")


def test_a_force_probe_on_an_obstacle_reads_that_obstacles_particles(tmp_path):
    """Two obstacles after the tank's walls: the probe's rows are the second one's
    particles (all inside its box) and the step records the force on those rows only."""
    sf = compose(tmp_path, WATER.replace("0.3, 0.05]", "0.1, 0.05]") +
                 '[[obstacle]]\nname = "a"\nbox = [0.15, 0.0, 0.17, 0.03]\n'
                 '[[obstacle]]\nname = "b"\nbox = [0.22, 0.0, 0.25, 0.04]\n'
                 '[[probe]]\nname = "fb"\nkind = "force"\nbody = "b"\n')
    a, b = sf.probes[0].spec["boundary_rows"]
    x = np.asarray(sf.scene.boundary.x)
    assert b == len(x)                                   # the last block of particles
    inside = (x[:, 0] > 0.22) & (x[:, 0] < 0.25) & (x[:, 1] > 0.0) & (x[:, 1] < 0.04)
    assert np.array_equal(np.flatnonzero(inside), np.arange(a, b))
    assert sf.scene.options["wall_force"] == (a, b)


GATE = """
[scene]
t_end = 0.06
gravity = [0.0, 0.0]
[tank]
width = 0.2
height = 0.2
[[kinematic]]
name = "gate"
points = [[0.05, 0.05], [0.05, 0.06]]
radius = 0.005
rho = 7800.0
velocity = [1.0, 0.0]
start = 0.01
stop = 0.03
[[probe]]
name = "g"
kind = "displacement"
body = "gate"
"""


def test_a_kinematic_body_stands_before_its_start_and_after_its_stop(tmp_path):
    """A gate with start = 0.01 s, stop = 0.03 s and velocity 1 m/s stands, moves 20 mm,
    then stands; each switch falls on a step boundary (within one step of motion)."""
    from fpsi_jax.run.driver import simulate
    path = tmp_path / "gate.toml"
    path.write_text(GATE)
    sf = scenefile.load(str(path))
    assert sf.scene.options["kinematic_motion"] == ((0, 2, 1.0, 0.0, 0.01, 0.03),)
    assert np.all(sf.scene.solid.v == 0.0)                 # standing at the start
    res = simulate(sf.scene, probes=sf.probes, progress=False)
    t, u = np.asarray(res.times), np.asarray(res.probes["g"])[:, 0]
    dt = float(res.params.dt)
    assert np.all(u[t < 0.01 - dt] == 0.0)
    assert u[-1] == pytest.approx(0.02, abs=1.01 * dt)
    assert np.ptp(u[t > 0.03 + dt]) == 0.0
    mid = (t > 0.012) & (t < 0.028)
    assert np.polyfit(t[mid], u[mid], 1)[0] == pytest.approx(1.0, rel=1e-5)   # float32 u


def test_an_oscillating_body_follows_its_stroke(tmp_path):
    """A wave maker's stroke, `oscillate` = {amplitude = [1 cm, 0.5 cm], period = 20 ms,
    ramp = 10 ms} from start = 5 ms, 41 steps a period: the body's displacement is
    r(τ) A sin(2πτ/T) at every recorded step to float32 round-off (each sub-step moves it
    at its mean velocity; V at the sub-step's middle overshot the stroke by 0.1 %), and
    it stands before its start."""
    from fpsi_jax.run.driver import simulate
    path = tmp_path / "osc.toml"
    path.write_text(GATE.replace("velocity = [1.0, 0.0]", 'oscillate = {amplitude = '
                                 '["1 cm", "5 mm"], period = "20 ms", ramp = 0.01}')
                    .replace("start = 0.01", "start = 0.005").replace("stop = 0.03\n", ""))
    sf = scenefile.load(str(path))
    m = sf.scene.options["kinematic_motion"][0]
    assert m == motion.Oscillation(0, 2, 0.01, 0.005, 0.02, 0.0, 0.01, 0.005, float("inf"))
    res = simulate(sf.scene, probes=sf.probes, progress=False, every=0.002)
    t, u = np.asarray(res.times), np.asarray(res.probes["g"])[:, :2]
    want = np.array([motion.displacement(m, ti) for ti in t])
    assert np.all(u[t <= 0.005] == 0.0)
    assert np.max(np.abs(u - want)) < 1e-7          # 1e-5 of the stroke


def test_a_tracked_body_follows_its_file(tmp_path):
    """`track` = a CSV of (t, x, y) with a header: the body follows the rows piecewise
    linearly and stands after the last one."""
    from fpsi_jax.run.driver import simulate
    (tmp_path / "stroke.csv").write_text("time_s,x_m,y_m\n0.0,0,0\n0.02,0.01,0\n"
                                         "0.03,0.01,-0.005\n")
    path = tmp_path / "trk.toml"
    path.write_text(GATE.replace("velocity = [1.0, 0.0]", 'track = "stroke.csv"')
                    .replace("start = 0.01\n", "").replace("stop = 0.03\n", ""))
    sf = scenefile.load(str(path))
    res = simulate(sf.scene, probes=sf.probes, progress=False, every=0.002)
    t, u = np.asarray(res.times), np.asarray(res.probes["g"])[:, :2]
    m = sf.scene.options["kinematic_motion"][0]
    want = np.array([motion.displacement(m, ti) for ti in t])
    assert np.max(np.abs(u - want)) < 1e-7
    assert u[-1] == pytest.approx([0.01, -0.005], abs=1e-7)


@pytest.mark.parametrize("edit, csv, word", [
    (('velocity = [1.0, 0.0]', 'velocity = [1.0, 0.0]\noscillate = {amplitude = [0.01, 0], '
      'period = 0.1}'), None, "key 'oscillate' prescribes the motion: leave `velocity` out"),
    (('velocity = [1.0, 0.0]', 'oscillate = {amplitude = [0.01, 0]}'), None,
     "'period'"),
    (('velocity = [1.0, 0.0]', 'oscillate = {amplitude = [0.01, 0], period = 0.1, '
      'phaze = 1}'), None, "unknown key(s) 'phaze'"),
    (('velocity = [1.0, 0.0]', 'track = "s.csv"'), "0,0,0\n0.1,0.01,0\n",
     "key 'track': the file's times say when the body moves"),
    (('velocity = [1.0, 0.0]\nstart = 0.01\nstop = 0.03', 'track = "none.csv"'), None,
     "no such file 'none.csv'"),
    (('velocity = [1.0, 0.0]\nstart = 0.01\nstop = 0.03', 'track = "s.csv"'),
     "t,x,y\n0,0,0\n0,0.01,0\n", "strictly increasing"),
    (('velocity = [1.0, 0.0]\nstart = 0.01\nstop = 0.03', 'track = "s.csv"'),
     "0,0,0\n0.1,abc,0\n", "line 2 is not three numbers"),
])
def test_a_bad_prescribed_motion_is_refused(tmp_path, edit, csv, word):
    if csv is not None:
        (tmp_path / "s.csv").write_text(csv)
    path = tmp_path / "gate.toml"
    path.write_text(GATE.replace(*edit))
    with pytest.raises(scenefile.FileError, match=re.escape(word)):
        scenefile.load(str(path))


@pytest.mark.parametrize("edit, word", [
    (("stop = 0.03", "stop = 0.005"), "key 'stop' = 0.005 s must come after 'start'"),
    (("velocity = [1.0, 0.0]", "velocity = [[1.0, 0.0], [1.0, 0.0]]"), "one `velocity`"),
])
def test_a_bad_motion_window_is_refused(tmp_path, edit, word):
    path = tmp_path / "gate.toml"
    path.write_text(GATE.replace(*edit))
    with pytest.raises(scenefile.FileError, match=word.replace("(", r"\(")):
        scenefile.load(str(path))


def test_list_room_is_read_from_the_physics_table(tmp_path):
    """[physics] capacity_multiplier starts the neighbour lists with that room over the
    start's need (a scene that breaks apart regrows them otherwise, recompiling each
    time); the default leaves the option out."""
    path = tmp_path / "room.toml"
    path.write_text(GATE)
    assert "capacity_multiplier" not in scenefile.load(str(path)).scene.options
    path.write_text(GATE + "[physics]\ncapacity_multiplier = 2.0\n")
    sf = scenefile.load(str(path))
    assert sf.scene.options["capacity_multiplier"] == 2.0
    roomy = Physics.for_scene(sf.scene)
    path.write_text(GATE)
    plain = Physics.for_scene(scenefile.load(str(path)).scene)
    assert roomy.dem_neighbors.capacity_multiplier == 2.0
    assert plain.dem_neighbors.capacity_multiplier == 1.25


BED_ON = """
[scene]
t_end = 0.01
[fluid]
dx = 0.004
h = 0.008
fit_width = 0.1
[[fluid.region]]
box = [0.0, {y0}, 0.1, {top}]
[tank]
width = 0.1
height = 0.16
{slab}
[[grains]]
name = "bed"
box = [0.0, {y0}, 0.1, {bed}]
d = 0.004
rho = 2650.0
[contacts]
kn = 1.0e7
"""


def test_a_bed_on_an_obstacle_sees_the_voidage_of_a_bed_on_the_floor(tmp_path):
    """The grains' wall images (the part of a grain's kernel inside a wall put back on the
    fluid's side) come from an obstacle's outline too, on its outward side: the pore
    fluid's start masses of a bed on a slab equal those of the same bed on the tank's
    floor, where without the slab's images the bottom pores held 2.7× the water (ε 0.41
    against 0.15), and the bed was buoyed 8.5 % short (0.998 of Archimedes with them,
    over 2 s)."""
    slab = '[[obstacle]]\nname = "slab"\nbox = [0.0, 0.0, 0.1, 0.012]'
    scenes = []
    for y0, extra in ((0.0, ""), (0.012, slab)):
        path = tmp_path / f"bed{y0}.toml"
        path.write_text(BED_ON.format(y0=y0, top=y0 + 0.1, bed=y0 + 0.018, slab=extra))
        scenes.append(scenefile.load(str(path)).scene)
    floor, on_slab = scenes
    assert list(on_slab.walls.image_sides()[3:]) == [-1.0] * 4     # outward of the box
    assert list(on_slab.walls.sides()[3:]) == [0.0] * 4           # contacts: both sides
    np.testing.assert_allclose(on_slab.fluid.x - [0.0, 0.012], floor.fluid.x, atol=1e-12)
    np.testing.assert_allclose(on_slab.fluid.mass, floor.fluid.mass, rtol=1e-9)


def test_water_without_a_tank_is_refused_only_where_gravity_takes_it_away(tmp_path):
    """A blob of water without gravity in a closed domain of its own loads; the same water
    under gravity with nothing to hold it is refused (scene-file test_errors)."""
    path = tmp_path / "blob.toml"
    path.write_text('[scene]\nt_end = 0.01\ngravity = [0, 0]\ndomain = [-1, -1, 1, 1]\n'
                    'open_sides = ["none"]\n[fluid]\ndx = 0.01\nsound_speed = 10.0\n'
                    '[[fluid.region]]\nbox = [0.0, 0.0, 0.1, 0.1]\n')
    assert scenefile.load(str(path)).scene.fluid.n == 100
    path.write_text(path.read_text().replace("sound_speed = 10.0\n", ""))
    with pytest.raises(Exception, match=r"\[fluid\]: without gravity .* sound_speed or "
                                         r"\[scene\] v_max"):
        scenefile.load(str(path))
