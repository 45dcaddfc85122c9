"""CLI: bad input is one line naming the problem, exit code 2, nothing written."""
import json

import pytest

from fpsi_jax import cli, io


@pytest.mark.parametrize("argv, word", [
    (["run", "nope"], "unknown scene 'nope'"),
    (["run", "dam_break", "--set", "foo=1"], "unknown key 'foo'"),
    (["run", "dam_break", "--set", "dx=-1"], "dx = -1 out of range"),
    (["run", "dam_break", "--set", "eps_xsph=2"], "eps_xsph = 2 is out of range"),
    (["run", "dam_break", "--set", "kernel=gauss"], "kernel must be one of"),
    (["run", "dam_break", "--dt", "1"], "exceeds the stability bound"),
    (["run", "dam_break", "--t-end", "-1"], "t-end"),
    (["validate", "nope"], "unknown validation case 'nope'"),
])
def test_bad_input_exits_2_with_one_line(argv, word, tmp_path, capsys):
    out = tmp_path / "x.h5"
    rc = cli.main(argv + (["--out", str(out)] if argv[0] == "run" else []))
    err = capsys.readouterr().err.strip()
    assert rc == 2
    assert len(err.splitlines()) == 1 and word in err
    assert not out.exists()


def test_list_names_scenes_and_cases(capsys):
    assert cli.main(["list"]) == 0
    text = capsys.readouterr().out
    assert "dam_break" in text and "hydrostatic_tank" in text


def test_run_writes_h5_xdmf_png(tmp_path, capsys):
    out = tmp_path / "db.h5"
    rc = cli.main(["run", "dam_break", "--set", "dx=0.02", "--t-end", "0.02", "--out",
                   str(out), "--plot", "--quiet", "--set", "mu=1e-3"])
    assert rc == 0
    assert out.exists() and out.with_suffix(".xdmf").exists() and out.with_suffix(".png").exists()
    run = io.read(out)
    assert run.params["sph.mu"] == 1e-3
    assert run.time[-1] == pytest.approx(0.02, rel=0.01)
