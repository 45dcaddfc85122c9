"""``fpsi calibrate my_case.toml --data measured.csv --fit ...``: what can be fitted and how
it maps onto Params, bad fit names, data files and windows refused with one line (exit 2,
nothing written, nothing compiled), and one fit end to end through the command line."""
import json
import math
import pathlib
import shutil

import numpy as np
import pytest

from calibrate import usercase as uc
from fpsi_jax import cli, scenefile

EXAMPLES = pathlib.Path(__file__).resolve().parents[2] / "examples" / "calibrate"
SYNTHETIC = EXAMPLES / "cantilever_synthetic.toml"


@pytest.fixture(scope="module")
def sf():
    return scenefile.load(str(SYNTHETIC))


def _settings(sf, **kw):
    kw.setdefault("data", str(EXAMPLES / "data" / "cantilever_synthetic.csv"))
    return uc.settings(sf, **kw)


# --- names ------------------------------------------------------------------------------------
def test_structure_E_scales_every_spring_it_sets_and_reads_in_pascal(sf):
    f = uc.resolve(sf, uc.parse_spec(sf, "E"), {})
    assert f.name == "beam.E" and f.scale and f.ref == 10.0e6
    assert set(f.leaves) == {"bond.kn", "bond.ks", "dem.kn", "dem.ks"}
    assert (f.lo, f.hi) == (2.0e6, 50.0e6)                      # ×0.2 – ×5 of the file's E
    # E = 12 MPa multiplies each spring by 1.2
    from calibrate import space as sp
    space = sp.ParamSpace(sf.scene.params, [f])
    p = space.params(space.z_of({"beam.E": 12.0e6}))
    for leaf in f.leaves:
        assert math.isclose(float(p.get(leaf)), 1.2 * float(sf.scene.params.get(leaf)),
                            rel_tol=1e-6)
    assert math.isclose(float(space.values(space.z_of({"beam.E": 12.0e6}))[0]),
                        12.0e6, rel_tol=1e-6)


def test_short_and_dotted_leaf_names_and_bounds(sf):
    f = uc.resolve(sf, uc.parse_spec(sf, "damping:0.1:100"), {})
    assert f.name == "dem.damping" and f.leaves == ("dem.damping",)
    assert (f.lo, f.hi, f.log) == (0.1, 100.0, True)
    g = uc.resolve(sf, uc.parse_spec(sf, "beam.tau_c"), {})
    assert g.name == "beam.tau_c" and g.leaves == ("bond.tau_c",)
    assert "stiffness" in uc.fittable(sf) and "dem.damping" in uc.fittable(sf)


def test_local_damping_takes_the_secant_jacobian_and_refuses_gradient_optimisers():
    """K25's local damping switches with sign(v): a forward-mode Jacobian through it is not
    the loss's (a squeezed specimen with alpha 0.7: d(load)/d(stiffness) −9.1e4 against a
    central difference of +1.5e3), so a file with alpha > 0 fits with the secant Jacobian
    unless --jacobian says otherwise, with a note, and adam/sgd are refused."""
    import dataclasses
    sfa = scenefile.load(str(SYNTHETIC))
    p = sfa.scene.params
    sfa.scene = dataclasses.replace(sfa.scene, params=p.replace(dem=p.dem.replace(alpha=0.7)))
    s = _settings(sfa, fit=["E"])
    assert s.jacobian == "fd" and "alpha = 0.7" in s.notes[0] and "secant" in s.notes[0]
    assert _settings(sfa, fit=["E"], jacobian="ad").jacobian == "ad"     # as asked
    with pytest.raises(scenefile.FileError, match="optimizer.*alpha = 0.7"):
        _settings(sfa, fit=["E"], optimizer="adam")
    assert _settings(scenefile.load(str(SYNTHETIC)), fit=["E"]).notes == ()


def test_start_values_of_the_file_follow_the_fitted_names(sf):
    # the file starts E at 2e7 and damping at 12; --fit E alone ignores the damping start
    s = _settings(sf, fit=["E"])
    fitted, start = uc.fitted_quantities(sf, [uc.parse_spec(sf, x) for x in s.fit],
                                         uc.start_values(sf, s.start),
                                         lenient=s.start_from_file)
    assert start == {"beam.E": 2.0e7}


def test_a_runs_own_probe_file_is_taken_with_its_last_step_past_t_end(sf, tmp_path):
    """`fpsi run` records up to its last step, ⌈t_end/Δt⌉ Δt, a sample past t_end: the
    file is taken as data, that sample left out of the default window."""
    t_end = float(sf.scene.t_end)
    t = np.append(np.arange(1, 41) * t_end / 40, t_end + 0.4 * t_end / 40)
    rows = "".join(f"{a:.9g}, {1e3 * a:.6g}, 0\n" for a in t)
    data = _csv(tmp_path, "t [s], tip.ux [mm], tip.uy [mm]\n" + rows)
    s = _settings(sf, fit=["E"], data=data)
    got_t, _, _, window, _ = uc.check_data(sf, s, uc._probe(sf, s.probe))
    assert len(got_t) == 41 and window[1] == pytest.approx(t_end)


# --- refused input ----------------------------------------------------------------------------
def _csv(tmp_path, text):
    p = tmp_path / "measured.csv"
    (p.write_bytes if isinstance(text, bytes) else p.write_text)(text)
    return str(p)


GOOD_CSV = "t [s], tip.ux [mm], tip.uy [mm]\n0.01, 0.0, 0.1\n0.05, 0.0, 0.3\n0.1, 0.0, 0.2\n"

# (label, extra arguments (DATA: the good CSV), CSV text or None, what the line contains)
BAD = [
    ("fit name not a parameter", ["--fit", "Q"], None,
     ["[calibration]", "key 'fit'", "'Q' is not a parameter", "can be fitted: stiffness"]),
    ("bounds inverted", ["--fit", "E:3e7:1e7"], None, ["key 'fit'", "lo < hi"]),
    ("bounds not numbers", ["--fit", "E:a:b"], None, ["key 'fit'", "not numbers"]),
    ("fitted twice", ["--fit", "E,beam.E"], None, ["key 'fit'", "named twice"]),
    ("start not fitted", ["--fit", "E", "--start", "damping=3"], None,
     ["key 'start'", "'damping' is not fitted"]),
    ("start outside bounds", ["--fit", "damping:1:10", "--start", "damping=30"], None,
     ["key 'start'", "damping"]),
    ("unknown probe", ["--fit", "E", "--probe", "nope"], None,
     ["key 'probe'", "'nope' names no probe", "probes: tip"]),
    ("window outside the run", ["--fit", "E", "--window", "0,9"], None,
     ["key 'window'", "outside the run [0, 0.184"]),
    ("holdout not a range", ["--fit", "E", "--holdout", "0.1,0.05"], None,
     ["key 'holdout'", "a < b"]),
    ("no time column", ["--fit", "E"], "tip.ux [mm], tip.uy [mm]\n0.1, 1\n0.2, 2\n",
     ["measured.csv", "first column must be the time"]),
    ("data outside the time span", ["--fit", "E"], "t [s], tip.ux [mm]\n0.5, 1\n0.6, 2\n",
     ["measured.csv", "outside the run's [0, 0.1841] s"]),
    ("unit of another dimension", ["--fit", "E"], "t [s], tip.ux [kPa]\n0.05, 1\n0.1, 2\n",
     ["measured.csv", "tip.ux"]),
    ("column of no probe component", ["--fit", "E"], "t [s], tip.rot [mm]\n0.05, 1\n0.1, 2\n",
     ["measured.csv", "column 'tip.rot': probe 'tip' (displacement) has components ux, uy"]),
    ("a misspelt component beside a good one", ["--fit", "E"],
     "t [s], tip.ux [mm], tip.uz [mm]\n0.05, 1, 1\n0.1, 2, 2\n",
     ["measured.csv", "column 'tip.uz': probe 'tip' (displacement) has components ux, uy"]),
    ("no column of the probe", ["--fit", "E"], "t [s], gate.ux [mm]\n0.05, 1\n0.1, 2\n",
     ["measured.csv", "no column measures probe 'tip'", "tip.ux [m], tip.uy [m]"]),
    ("samples after the run's end", ["--fit", "E"],
     "t [s], tip.ux [mm]\n0.05, 1\n0.1, 2\n0.6, 3\n0.7, 4\n",
     ["measured.csv", "2 of its 4 samples lie after the run's end", "--window"]),
    ("a force in N", ["--fit", "E"], "t [s], tip.ux [N]\n0.05, 1\n0.1, 2\n",
     ["measured.csv", "unknown unit 'N'", "per metre of out-of-plane thickness"]),
    ("data not a text file (an HDF5 output)", ["--fit", "E"], b"\x89HDF\r\n\x1a\n\x00\xff",
     ["measured.csv", "is not a text CSV file"]),
    ("no data file", ["--fit", "E", "--data", "missing.csv"], None,
     ["missing.csv", "no such data file"]),
    ("unknown target", ["--fit", "E", "--target", "spectrum"], None, ["spectrum"]),
]


@pytest.mark.parametrize("label,args,csv,expect", BAD, ids=[b[0] for b in BAD])
def test_bad_calibration_input_one_line_exit_2_nothing_written(tmp_path, capsys, label, args,
                                                               csv, expect):
    data = _csv(tmp_path, csv or GOOD_CSV)
    out = tmp_path / "out"
    argv = ["calibrate", str(SYNTHETIC)] + (["--data", data] if "--data" not in args else [])
    argv += [a if a != "missing.csv" else str(tmp_path / "missing.csv") for a in args]
    try:
        code = cli.main(argv + ["--out", str(out), "--quiet"])
    except SystemExit as e:                 # argparse's own refusals (a choice)
        code = e.code
    err = capsys.readouterr().err.strip()
    assert code == 2, err
    line = err.splitlines()[-1]
    for part in expect:
        assert part in line, (part, line)
    assert not out.exists()


# --- end to end -------------------------------------------------------------------------------
def test_damping_fit_from_the_example_file_matches_the_single_mode_value(tmp_path):
    """examples/calibrate/cantilever_damping.toml: the data decay with ζ = 0.05 at the model
    strip's own frequency f; the fitted c must be 4π f ζ (a single mode's value) within
    1 %, and the record and plot are written."""
    work = tmp_path / "case"
    shutil.copytree(EXAMPLES, work, ignore=shutil.ignore_patterns("*.png", "*.json"))
    out = tmp_path / "out"
    code = cli.main(["calibrate", str(work / "cantilever_damping.toml"), "--out", str(out),
                     "--quiet", "--steps", "8"])
    assert code == 0
    rec = json.loads((out / "cantilever_damping.json").read_text())
    assert rec["command"] == ("fpsi calibrate " + str(work / "cantilever_damping.toml")
                              + f" --out {out} --quiet --steps 8")    # as typed, to rerun
    assert (out / "cantilever_damping.png").stat().st_size > 10_000
    f_data = float(rec["target_report"]["fitted"]["frequency_ref"])
    c = rec["fitted"]["dem.damping"]
    assert rec["start"]["dem.damping"] == 2.0
    assert abs(c / (4 * math.pi * f_data * 0.05) - 1) < 0.01, (c, f_data)
    assert rec["loss_fitted"] < 1e-3 * rec["loss_start"]
    rms = rec["rms"]["window"]
    assert rms["fitted"]["uy"] < 0.2 * rms["start"]["uy"]
    assert np.isfinite(rec["std_error"]["dem.damping"])
    assert set(rec["wall_s"]) == {"setup", "fit"}


def test_summary_of_a_free_vibration_fit_gives_the_frequencies_and_damping_ratios():
    """The console summary of a vibration target says what was fitted: the data's and the
    model's frequency and damping ratio, at the start and fitted."""

    def vib(f, z):
        return {"frequency_hz": f, "damping_ratio": z, "frequency_ref": 11.5,
                "damping_ratio_ref": 0.03}
    rec = {"quantities": [{"name": "beam.E", "unit": "Pa"}], "start": {"beam.E": 2e7},
           "fitted": {"beam.E": 1e7}, "std_error": {}, "rms": {},
           "target_report": {"start": vib(16.4, 0.06), "fitted": vib(11.5, 0.031)}}
    text = uc.summary(rec)
    assert "beam.E: 2e+07 -> 1e+07 Pa" in text
    assert "free vibration: data 11.5 Hz, ζ 0.03; start f 16.4 Hz, ζ 0.06; fitted f 11.5 Hz, " \
           "ζ 0.031" in text


def test_the_standard_errors_of_a_stalled_fit_say_so():
    """A fit that stopped without improving (a local minimum of a chaotic impact's loss:
    a fit of a post's E under a bore stalled at 3.9 MPa for a truth of 2, ± 8.9 kPa) says
    its errors are the curvature where it stalled; a converged fit's note is the scale."""
    stalled = uc._stderr_note({"s_from": "RSS/(m - p)"}, "no improvement in 3 steps")
    assert stalled.startswith("RSS/(m - p); the fit stopped (no improvement in 3 steps)")
    assert "not a confidence interval" in stalled
    assert uc._stderr_note({"s_from": "RSS/(m - p)"}, "loss_tol") == "RSS/(m - p)"
