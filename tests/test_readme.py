"""Every command and Python block of the README runs.

The README's commands are read from its ```bash blocks (``fpsi …`` lines, continuations
joined) and must be exactly the keys of :data:`COMMANDS`, so a command added to the README
without a test here fails. Each is run through ``fpsi_jax.cli.main`` in a scratch folder
(with ``examples/`` linked in) with the flags of its value appended: a shorter ``--t-end``,
a coarser ``--set``, one optimiser step. The literal commands, at full size, run under
``-m slow``. The Python blocks run with the sizes in :data:`PYTHON` substituted.
"""
import json
import os
import pathlib
import re
import shlex

import numpy as np
import pytest

from fpsi_jax import cli

ROOT = pathlib.Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text()

GATE = "--set dx=0.0035 --set d=0.0025 --set dx_boundary=0.0025 --set h0=0.004375"

#: README command -> the flags appended in the default suite ("" = run as written)
COMMANDS = {
    "fpsi list": "",
    "fpsi run dam_break --t-end 0.4 --out results/dam_break.h5 --plot": "--set dx=0.02",
    "fpsi run examples/dam_break_on_post.toml --plot": "--t-end 0.004",
    "fpsi run elastic_gate --set coupling=pressure_gradient --out results/gate.h5 --plot":
        f"{GATE} --t-end 0.004",
    "fpsi validate --quick": None,                    # every quick case: tests/cases, slow here
    "fpsi validate hydrostatic_plate --set water_height=0.1 --json v.json":
        "--set dx=0.005 --set d=0.0035 --set dx_boundary=0.0035 --set t_end=0.02",
    # the same fit runs in tests/cli/test_calibrate_cli.py; as written under -m slow
    "fpsi calibrate examples/calibrate/cantilever_synthetic.toml --out results/cal": None,
    "fpsi run examples/dam_break_on_post.toml --plot --out results/post.h5": "--t-end 0.004",
    "fpsi calibrate examples/dam_break_on_post.toml --data my_recording.csv --probe top "
    "--fit post.E,damping --start damping=0.5 --window 0,0.3 --holdout 0.3,0.6": None,   # 0.6 s per step: slow
}

#: README Python block (its first code line) -> substitutions for the default suite
PYTHON = {
    "from fpsi_jax.cases import build": [("dx=0.005", "dx=0.02"), ("t_end=0.2", "t_end=0.01")],
    "import jax": [("2000)", "20)")],
}


def readme_commands():
    cmds = []
    for block in re.findall(r"```bash\n(.*?)```", README, re.S):
        text = block.replace("\\\n", " ")
        for line in text.splitlines():
            line = line.split("#")[0].strip()
            if line.startswith("fpsi "):
                cmds.append(" ".join(line.split()))
    return cmds


def readme_python():
    return re.findall(r"```python\n(.*?)```", README, re.S)


def test_every_readme_command_is_tested_here():
    assert sorted(readme_commands()) == sorted(COMMANDS)
    assert sorted(b.splitlines()[0] for b in readme_python()) == sorted(PYTHON)


@pytest.fixture
def scratch(tmp_path, monkeypatch):
    (tmp_path / "examples").symlink_to(ROOT / "examples")
    monkeypatch.chdir(tmp_path)
    return tmp_path


def _recording(path, t_end):
    """A made-up recording for the dam-break-on-post calibration: the post's top pushed
    downstream and sinking a little, linearly in time."""
    t = np.linspace(0.0, t_end, 21)
    np.savetxt(path, np.stack([t, 2.0 * t / t_end, -0.1 * t / t_end], 1), delimiter=",",
               header="t [s], top.ux [mm], top.uy [mm]", comments="")


def _run(command, extra, scratch, allowed=(0,)):
    argv = shlex.split(command)[1:] + shlex.split(extra)
    assert cli.main(argv) in allowed, command


@pytest.mark.parametrize("command", [c for c, e in COMMANDS.items() if e is not None])
def test_readme_command_runs(command, scratch):
    shortened = "validate" in command    # a shortened validation may miss its tolerance: 1
    _run(command, COMMANDS[command], scratch, (0, 1) if shortened else (0,))
    if "--out results/" in command and "calibrate" not in command:
        out = scratch / command.split("--out ")[1].split()[0]
        assert out.exists() and out.with_suffix(".xdmf").exists()
    if "--json" in command:
        rec, = json.loads((scratch / "v.json").read_text())
        assert rec["case"] == "hydrostatic_plate" and np.isfinite(rec["value"])


@pytest.mark.slow        # a scene-file fit also runs in tests/calibrate/test_usercase.py
def test_readme_calibration_of_a_scene_file_runs_short(scratch):
    """The scene-file calibration with a recording of its own length, a short window and
    one step (the README's 0.6 s windows run under -m slow)."""
    _recording(scratch / "my_recording.csv", 0.006)
    _run("fpsi calibrate examples/dam_break_on_post.toml --data my_recording.csv --probe top "
         "--fit post.E,damping --start damping=0.5 --window 0,0.004 --holdout 0.004,0.006 "
         "--steps 1", "", scratch)


@pytest.mark.slow
@pytest.mark.parametrize("command", list(COMMANDS))
def test_readme_command_runs_as_written(command, scratch):
    if "my_recording.csv" in command:
        _recording(scratch / "my_recording.csv", 0.6)
    # fpsi validate exits 1 when a row misses its tolerance, which the README's table says
    # some do (the dam break's front, the gate's time of peak, ...)
    _run(command, "", scratch, (0, 1) if "validate" in command else (0,))
    if "--json" in command:
        rec, = json.loads((scratch / "v.json").read_text())
        assert rec["case"] == "hydrostatic_plate" and np.isfinite(rec["value"])


@pytest.mark.parametrize("first", list(PYTHON))
def test_readme_python_block_runs(first, scratch):
    block = next(b for b in readme_python() if b.splitlines()[0] == first)
    for old, new in PYTHON[first]:
        assert old in block, old
        block = block.replace(old, new)
    exec(compile(block, "README.md", "exec"), {})
    if "output=" in block:
        assert os.path.exists("out.h5")
