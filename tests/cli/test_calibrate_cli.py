"""``fpsi calibrate``: bad input is one line and exit code 2 before anything is compiled;
a short fit writes its JSON record and plot."""
import json

import pytest

from fpsi_jax import cli


@pytest.mark.parametrize("argv, word", [
    (["calibrate", "nope"], "unknown calibration case 'nope'"),
    (["calibrate", "cantilever_damping", "--set", "foo=1"], "unknown key 'foo'"),
    (["calibrate", "elastic_gate", "--set", "resolution=fine"], "resolution = 'fine'"),
    (["calibrate", "cantilever_damping", "--steps", "0"], "--steps = 0 out of range"),
    (["calibrate", "cantilever_damping", "--set", "damping_bounds=[5, 10]"], "out of range"),
])
def test_bad_input_exits_2(argv, word, tmp_path, capsys):
    rc = cli.main(argv + ["--out", str(tmp_path / "c")])
    err = capsys.readouterr().err.strip()
    assert rc == 2
    assert len(err.splitlines()) == 1 and word in err
    assert not (tmp_path / "c").exists()


def test_calibrate_recovers_synthetic_truth_and_writes_json_and_png(tmp_path, capsys):
    """Short strip (length 40 mm, discs 2.5 mm), free vibration over 2 periods, float64:
    from stiffness ×2 and damping ×3 the Levenberg–Marquardt fit recovers both within 1 %
    (the full-size fit is experiments/calibrate_cantilever.py) and writes its record."""
    out = tmp_path / "c"
    rc = cli.main(["calibrate", "cantilever_synthetic", "--set", "d=0.0025", "--set",
                   "length=0.04", "--set", "periods=2.0", "--steps", "15", "--quiet",
                   "--out", str(out)])
    assert rc == 0
    rec = json.load(open(out / "cantilever_synthetic.json"))
    assert rec["names"] == ["stiffness", "dem.damping"]
    assert rec["start"]["stiffness"] == pytest.approx(2.0)
    assert rec["start"]["dem.damping"] == pytest.approx(3 * rec["extra"]["truth"]["dem.damping"])
    assert rec["steps"] <= 15
    assert rec["best"]["stiffness"] == pytest.approx(1.0, rel=0.01)
    assert rec["best"]["dem.damping"] == pytest.approx(rec["extra"]["truth"]["dem.damping"],
                                                       rel=0.01)
    assert rec["loss_best"] < 1e-4 * rec["loss_start"]
    assert len(rec["history"]) == rec["steps"] + 1 and rec["wall_s"] > 0
    assert (out / "cantilever_synthetic.png").stat().st_size > 1000
