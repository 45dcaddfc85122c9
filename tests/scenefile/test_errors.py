"""Bad scene files: one line naming the file, the table and the key, exit code 2 from
``fpsi run``, nothing written, nothing compiled."""
import os

import numpy as np
import pytest

from fpsi_jax import cli, scenefile
from fpsi_jax.model.errors import ParameterError

GOOD = """
[scene]
t_end = 0.01

[fluid]
density = 1000.0
dx = 0.01

[[fluid.region]]
box = [0.0, 0.0, 0.1, 0.1]

[tank]
width = 0.4
height = 0.2

[[structure]]
name = "gate"
box = [0.2, 0.0, 0.21, 0.08]
d = 0.005
E = 1.0e6
nu = 0.3
rho = 1100.0
clamp = [0.2, 0.07, 0.21, 0.08]

[[probe]]
name = "tip"
kind = "displacement"
body = "gate"
region = [0.2, 0.0, 0.21, 0.005]
"""


def edit(text, old, new):
    assert old in text, old
    return text.replace(old, new, 1)


# (label, edit to GOOD, what the one line must contain)
BAD = [
    ("unknown key", lambda t: edit(t, "density = 1000.0", "densty = 1000.0"),
     ["[fluid]", "unknown key 'densty'", "allowed: density, viscosity"]),
    ("water without a tank", lambda t: t.split("[tank]")[0],
     ["[fluid]", "the water has nothing to hold it", "add a [tank]"]),
    ("a density in g/cm3 without its unit", lambda t: edit(t, "rho = 1100.0", "rho = 1.1"),
     ["[[structure]] 'gate'", "key 'rho'", "allowed [10.0, inf) kg/m³"]),
    ("a region without a body", lambda t: edit(t, 'body = "gate"\nregion', 'region'),
     ["[[probe]] 'tip'", "key 'region' selects discs of a `body`"]),
    ("a body named as a tank wall", lambda t: edit(t, 'name = "gate"', 'name = "tank.floor"'),
     ["[[structure]] 'tank.floor'", "names tank.* are the tank's walls"]),
    ("gravity pointing up", lambda t: edit(t, "t_end = 0.01", "t_end = 0.01\ngravity = [0, 9.81]"),
     ["[scene]", "key 'gravity' = [0.0, 9.81] points up", "[0, -9.81]"]),
    ("unknown table", lambda t: t + "\n[flud]\nx = 1\n",
     ["unknown table [flud]", "allowed:"]),
    ("wrong type", lambda t: edit(t, "dx = 0.01", 'dx = "fine"'),
     ["[fluid]", "key 'dx'", "not a number"]),
    ("wrong unit", lambda t: edit(t, "E = 1.0e6", 'E = "1 kg"'),
     ["[[structure]] 'gate'", "key 'E'", "unit 'kg'", "MPa"]),
    ("negative size", lambda t: edit(t, "width = 0.4", "width = -0.4"),
     ["[tank]", "key 'width'", "out of range; allowed (0.0, inf) m"]),
    ("inverted box", lambda t: edit(t, "box = [0.0, 0.0, 0.1, 0.1]",
                                    "box = [0.1, 0.0, 0.0, 0.1]"),
     ["[[fluid.region]] #1", "key 'box'", "x1 > x0"]),
    ("an expression for a number", lambda t: edit(t, "E = 1.0e6", 'E = "2*1e6 Pa"'),
     ["[[structure]] 'gate'", "key 'E'", "is an expression", "`oscillate` or `track`"]),
    ("disc spacing past its box", lambda t: edit(t, "d = 0.005", "d = 0.05"),
     ["[[structure]] 'gate'", "key 'd' = 0.05 m is larger than the 0.01 x 0.08 m block",
      "(its box)"]),
    ("fluid spacing past its region", lambda t: edit(t, "dx = 0.01", "dx = 0.5"),
     ["[fluid]", "key 'dx' = 0.5 m is larger than the 0.1 x 0.1 m block",
      "[[fluid.region]] #1's box"]),
    ("required key", lambda t: edit(t, "t_end = 0.01", ""),
     ["[scene]", "key 't_end' is required"]),
    ("bool for number", lambda t: edit(t, "t_end = 0.01", "t_end = true"),
     ["[scene]", "key 't_end'", "not a number"]),
    ("not TOML", lambda t: t + "\nthis is = = not toml\n", ["not valid TOML"]),
    ("fluid outside tank", lambda t: edit(t, "box = [0.0, 0.0, 0.1, 0.1]",
                                          "box = [-0.05, 0.0, 0.1, 0.1]"),
     ["[[fluid.region]]", "outside the tank"]),
    ("overlapping bodies", lambda t: t + """
[[structure]]
name = "second"
box = [0.205, 0.0, 0.215, 0.05]
d = 0.005
E = 1.0e6
nu = 0.3
rho = 1100.0
""", ["[[structure]] 'second'", "overlaps structure 'gate' by", "allowed 2 %"]),
    ("radii for fewer points", lambda t: t + """
[[discs]]
name = "mix"
points = [[0.3, 0.01], [0.32, 0.01]]
radius = [0.003]
rho = 2700.0
""", ["[[discs]] 'mix'", "key 'radius' has 1 radii for 2 points"]),
    ("radii for a structure", lambda t: t + """
[[structure]]
name = "pair"
points = [[0.3, 0.01], [0.307, 0.01]]
radius = [0.003, 0.004]
E = 1.0e6
rho = 1100.0
""", ["[[structure]] 'pair'", "key 'radius' takes one number for a structure"]),
    ("overlapping discs of one group", lambda t: t + """
[[discs]]
name = "pair"
points = [[0.3, 0.01], [0.305, 0.01]]
radius = 0.005
rho = 2700.0
""", ["[[discs]] 'pair'", "two of its discs overlap by 100 % of a radius",
      "(0.3, 0.01) and (0.305, 0.01)"]),
    ("water in a body", lambda t: edit(t, "box = [0.2, 0.0, 0.21, 0.08]",
                                       "box = [0.05, 0.0, 0.06, 0.08]").replace(
        "clamp = [0.2, 0.07, 0.21, 0.08]", "clamp = [0.05, 0.07, 0.06, 0.08]").replace(
        "region = [0.2, 0.0, 0.21, 0.005]", "region = [0.05, 0.0, 0.06, 0.005]"),
     ["[[fluid.region]]", "water overlaps structure 'gate'"]),
    ("water in an obstacle", lambda t: t + "\n[[obstacle]]\nbox = [0.0, 0.0, 0.02, 0.02]\n",
     ["[[obstacle]] #1", "water lies inside"]),
    ("discs in an obstacle", lambda t: t + '\n[[obstacle]]\nname = "pier"\n'
     'box = [0.25, 0.0, 0.3, 0.05]\n[[grains]]\nname = "gravel"\n'
     'box = [0.22, 0.0, 0.27, 0.01]\nd = 0.005\nrho = 2650.0\n',
     ["[[grains]] 'gravel'", "of its discs lie inside obstacle 'pier'", "(the first at"]),
    ("discs across a polyline obstacle", lambda t: t + '\n[[obstacle]]\n'
     'polyline = [[0.3, 0.0], [0.3, 0.05]]\n[[grains]]\nname = "gravel"\n'
     'box = [0.25, 0.0, 0.32, 0.01]\nd = 0.005\nrho = 2650.0\n',
     ["[[grains]] 'gravel'", "lie inside obstacle 0"]),
    ("probe body missing", lambda t: edit(t, 'body = "gate"', 'body = "gat"'),
     ["[[probe]] 'tip'", "key 'body' = 'gat' names no body; bodies: gate"]),
    ("probe kind", lambda t: edit(t, 'kind = "displacement"', 'kind = "strain"'),
     ["[[probe]] 'tip'", "key 'kind'", "not a choice"]),
    ("probe needs key", lambda t: t + '\n[[probe]]\nname = "p"\nkind = "pressure"\n',
     ["[[probe]] 'p'", "key 'point' is required"]),
    ("probe point outside", lambda t: t + '\n[[probe]]\nname = "p"\nkind = "pressure"\n'
     'point = [3.0, -2.0]\n', ["[[probe]] 'p'", "key 'point'", "lies outside the domain"]),
    ("level x outside", lambda t: t + '\n[[probe]]\nname = "h"\nkind = "water_level"\n'
     'x = 5.0\n', ["[[probe]] 'h'", "key 'x' = 5.0 lies outside the domain"]),
    ("structure outside the tank", lambda t: edit(edit(t, "box = [0.2, 0.0, 0.21, 0.08]",
                                                     "box = [0.45, 0.0, 0.46, 0.08]"),
                                                "clamp = [0.2, 0.07, 0.21, 0.08]",
                                                "clamp = [0.45, 0.07, 0.46, 0.08]"),
     ["[[structure]] 'gate'", "a disc centre at", "lies outside the tank [0, 0.4]"]),
    ("obstacle outside the tank", lambda t: t + '\n[[obstacle]]\nbox = [0.5, 0.0, 0.6, 0.05]\n',
     ["[[obstacle]] #1", "lies wholly outside the tank"]),
    ("obstacle read as discs", lambda t: t + '\n[[obstacle]]\nname = "pier"\n'
     'box = [0.3, 0.0, 0.32, 0.05]\n' + '\n[[probe]]\nname = "u"\nkind = "displacement"\n'
     'body = "pier"\n', ["[[probe]] 'u'", "names an obstacle: only kind 'force'"]),
    ("obstacle force of a region", lambda t: t + '\n[[obstacle]]\nname = "pier"\n'
     'box = [0.3, 0.0, 0.32, 0.05]\n' + '\n[[probe]]\nname = "f"\nkind = "force"\n'
     'body = "pier"\nregion = [0.3, 0.0, 0.31, 0.05]\n',
     ["[[probe]] 'f'", "key 'region' selects discs"]),
    ("obstacle named as a body", lambda t: t + '\n[[obstacle]]\nname = "gate"\n'
     'box = [0.3, 0.0, 0.32, 0.05]\n', ["[[obstacle]]", "name 'gate' is used by another"]),
    ("probe key of another kind", lambda t: t + '\n[[probe]]\nname = "p"\nkind = "pressure"\n'
     'point = [0.05, 0.02]\nbody = "gate"\n',
     ["[[probe]] 'p'", "key 'body' does not apply to kind 'pressure'"]),
    ("probe reference missing", lambda t: edit(t, 'kind = "displacement"',
                                               'kind = "displacement"\nreference = "no.csv"'),
     ["[[probe]] 'tip'", "key 'reference'", "no such file"]),
    ("clamp misses", lambda t: edit(t, "clamp = [0.2, 0.07, 0.21, 0.08]",
                                    "clamp = [0.3, 0.07, 0.31, 0.08]"),
     ["[[structure]] 'gate'", "key 'clamp'", "holds none"]),
    ("move misses", lambda t: edit(t, "clamp = [0.2, 0.07, 0.21, 0.08]",
                                   "clamp = [0.2, 0.07, 0.21, 0.08]\nmove = {region = "
                                   "[0.3, 0.0, 0.31, 0.01], velocity = [0.0, 0.1]}"),
     ["[[structure]] 'gate'", "key 'move'", "holds none"]),
    ("move without velocity", lambda t: edit(t, "clamp = [0.2, 0.07, 0.21, 0.08]",
                                             "move = {region = [0.2, 0.0, 0.21, 0.01]}"),
     ["[[structure]] 'gate'", "key 'move' needs 'velocity'",
      "{region = [...], velocity = [...]}"]),
    ("move with a bad velocity", lambda t: edit(t, "clamp = [0.2, 0.07, 0.21, 0.08]",
                                                "move = {region = [0.2, 0.0, 0.21, 0.01], "
                                                "velocity = [0.0, \"2 kg\"]}"),
     ["[[structure]] 'gate'", "key 'move': velocity = '2 kg': unit 'kg' is not a unit of "
      "m/s"]),
    ("two materials", lambda t: t + """
[[structure]]
name = "second"
box = [0.3, 0.0, 0.31, 0.05]
d = 0.005
E = 2.0e6
nu = 0.3
rho = 1100.0
""", ["[[structure]] 'second'", "material", "differs from structure 'gate'"]),
    ("bad choice", lambda t: t + '\n[physics]\ncoupling = "glue"\n',
     ["[physics]", "key 'coupling'", "not a choice", "'extrapolated'"]),
    ("array written as table", lambda t: t.replace("[[structure]]", "[structure]"),
     ["[structure] must be an array of tables", "write [[structure]]"]),
    ("no shape", lambda t: edit(t, "box = [0.2, 0.0, 0.21, 0.08]\n", ""),
     ["[[structure]] 'gate'", "give exactly one of box, polygon, points"]),
    ("contacts without material", lambda t: edit(t, "E = 1.0e6\n", ""),
     ["[contacts]", "key 'kn' is required", "N/m"]),
    ("bonds without material", lambda t: edit(t, "E = 1.0e6\n", "") + "\n[contacts]\nkn = 1e5\n",
     ["[bonds]", "keys 'kn' and 'ks' are required"]),
]


@pytest.mark.parametrize("label,change,expect", BAD, ids=[b[0] for b in BAD])
def test_bad_file_one_line_exit_2_nothing_written(tmp_path, capsys, label, change, expect):
    path = tmp_path / "flume.toml"
    path.write_text(change(GOOD))
    out = tmp_path / "out" / "run.h5"
    code = cli.main(["run", str(path), "--out", str(out), "--quiet"])
    err = capsys.readouterr().err.strip()
    assert code == 2, err
    assert len(err.splitlines()) == 1, err
    assert err.count("flume.toml") == 1, err          # located once, not twice
    for piece in expect:
        assert piece in err, (piece, err)
    assert not os.path.exists(tmp_path / "out")


@pytest.mark.parametrize("curve,expect", [
    ("t [s], gate.ux [m]\n0.0, 0.0\n0.01, 0.001\n", "no column measures probe 'tip'"),
    (b"\x89HDF\r\n\x1a\n\x00\x00\xff", "is not a text CSV file"),
], ids=["wrong probe", "binary"])
def test_a_bad_reference_curve_stops_before_the_run(tmp_path, capsys, curve, expect):
    """The reference CSV is read with the scene file, so a curve that cannot be plotted
    stops the run before anything is compiled or written (not after the run)."""
    ref = tmp_path / "ref.csv"
    (ref.write_bytes if isinstance(curve, bytes) else ref.write_text)(curve)
    path = tmp_path / "flume.toml"
    path.write_text(edit(GOOD, 'kind = "displacement"', 'kind = "displacement"\nreference = "ref.csv"'))
    out = tmp_path / "out" / "run.h5"
    code = cli.main(["run", str(path), "--out", str(out), "--quiet", "--plot"])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1, err
    assert "[[probe]] 'tip'" in err and "key 'reference'" in err and expect in err, err
    assert not os.path.exists(tmp_path / "out")


def test_the_good_file_loads_and_quantities_with_units_convert(tmp_path):
    path = tmp_path / "flume.toml"
    path.write_text(edit(edit(GOOD, "dx = 0.01", 'dx = "1 cm"'), "E = 1.0e6", 'E = "1MPa"'))
    case = scenefile.load(str(path))
    assert case.scene.params.sph.dp == pytest.approx(0.01)
    assert case.materials["gate"]["E"] == pytest.approx(1.0e6)     # the space is optional
    assert [p.name for p in case.probes] == ["tip"]
    assert case.scene.solid.n == 2 * 16


def test_discs_of_a_settled_packing_may_overlap_slightly(tmp_path):
    """Contacts 1 % of a radius deep, as a packing settled in an earlier run holds them,
    within a group and between groups: accepted (allowed 2 %)."""
    path = tmp_path / "flume.toml"
    path.write_text(GOOD + """
[[discs]]
name = "pile"
points = [[0.3, 0.005], [0.30995, 0.005]]
radius = 0.005
rho = 2700.0
[[discs]]
name = "top"
points = [[0.305, 0.01361]]
radius = 0.005
rho = 2700.0
""")
    assert scenefile.load(str(path)).scene.solid.n == 2 * 16 + 3


def test_points_may_carry_one_radius_each(tmp_path):
    path = tmp_path / "flume.toml"
    path.write_text(GOOD + """
[[discs]]
name = "mix"
points = [[0.3, 0.003], [0.31, 0.004], [0.325, 0.005]]
radius = ["3 mm", 0.004, 0.005]
rho = 2700.0
""")
    sf = scenefile.load(str(path))
    k = sf.bodies["mix"]
    np.testing.assert_allclose(sf.scene.solid.radius[k], [0.003, 0.004, 0.005])
    np.testing.assert_allclose(sf.scene.solid.mass[k],
                               2700.0 * np.pi * np.array([3, 4, 5]) ** 2 * 1e-6)


def test_components_of_points_boxes_and_regions_may_carry_units(tmp_path):
    path = tmp_path / "flume.toml"
    text = edit(GOOD, "box = [0.2, 0.0, 0.21, 0.08]", 'box = ["20 cm", 0.0, "210 mm", 0.08]')
    text = edit(text, "region = [0.2, 0.0, 0.21, 0.005]", 'region = [0.2, 0.0, "21 cm", "5mm"]')
    case = scenefile.load(str(path.write_text(text) and path))
    assert case.scene.solid.n == 2 * 16
    plain = tmp_path / "plain.toml"
    plain.write_text(GOOD)
    np.testing.assert_array_equal(case.scene.solid.x, scenefile.load(str(plain)).scene.solid.x)


def test_errors_are_parameter_errors_in_python_too(tmp_path):
    path = tmp_path / "flume.toml"
    path.write_text(edit(GOOD, "density = 1000.0", "density = 0.0"))
    with pytest.raises(ParameterError, match=r"flume.toml: \[fluid\]: key 'density'"):
        scenefile.load(str(path))


def test_docs_scene_file_md_lists_every_key_as_the_schema_does():
    from fpsi_jax.scenefile.schema import markdown
    here = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    with open(os.path.join(here, "docs", "scene-file.md")) as fh:
        doc = fh.read()
    assert doc.strip() == markdown().strip(), (
        "docs/scene-file.md is out of date: python -c \"from fpsi_jax.scenefile.schema "
        "import markdown; print(markdown())\" > docs/scene-file.md")


def test_kinematic_bodies_alone_need_no_contact_stiffness_and_no_sub_steps(tmp_path):
    """A rigid pier as a [[kinematic]] body at rest, the only discs: no DEM force is ever
    integrated, so the file needs no [contacts] kn and the step takes one DEM sub-step
    (the SPH bound alone), with the pier's force probe recorded."""
    from fpsi_jax.run.driver import setup
    from fpsi_jax.solver import timestep
    path = tmp_path / "pier.toml"
    water_and_tank = GOOD.split("[[structure]]")[0]
    path.write_text(water_and_tank + """[[kinematic]]
name = "pier"
box = [0.2, 0.0, 0.22, 0.08]
d = 0.01
rho = 2400.0
velocity = [0.0, 0.0]

[[probe]]
name = "F"
kind = "force"
body = "pier"
""")
    sf = scenefile.load(str(path))
    assert timestep.dem_dt(sf.scene, sf.scene.params) == float("inf")
    phys, params = setup(sf.scene)
    assert phys.dem_substeps == 1
    assert float(params.dt) == pytest.approx(timestep.sph_dt(sf.scene, sf.scene.params,
                                                             phys=phys))
