"""Stops of every kind, in real processes: SIGINT and SIGTERM stop at the end of a chunk with
one line and their exit code, SIGKILL leaves a file whose sidecar lists exactly its frames,
--resume continues to the same result bit for bit, and a second run on a busy file is
refused without touching it."""
import os
import signal
import subprocess
import sys
import time
import xml.etree.ElementTree as ET

import h5py
import numpy as np
import pytest

from fpsi_jax.run import io

RUN = [sys.executable, "-m", "fpsi_jax.cli", "run", "dam_break", "--set", "dx=0.02",
       "--t-end", "0.4", "--every", "0.005", "--quiet"]


def start(out, *extra, t_end=None):
    cmd = RUN + (["--t-end", str(t_end)] if t_end else [])
    return subprocess.Popen(cmd + ["--out", str(out), *extra], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)


def frames(path) -> int:
    try:
        with h5py.File(path, "r", locking=False) as f:
            return len(f["time"])
    except (OSError, KeyError):
        return 0


def wait_for_frames(path, n, proc, timeout=120):
    t0 = time.time()
    while frames(path) < n:
        assert proc.poll() is None, proc.communicate()
        assert time.time() - t0 < timeout
        time.sleep(0.05)


def sidecar_frames(path) -> int:
    root = ET.parse(io.sidecar(path)).getroot()
    return len(root.findall("./Domain/Grid/Grid"))


def final_frame(path):
    with h5py.File(path, "r", locking=False) as f:
        k = len(f["time"]) - 1
        g = f[io.frame_name(k)]
        out = {}
        g.visititems(lambda n, o: out.__setitem__(n, o[()]) if isinstance(o, h5py.Dataset)
                     else None)
        return k, float(f["time"][k]), out


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """The uninterrupted run."""
    out = tmp_path_factory.mktemp("ref") / "ref.h5"
    p = start(out)
    assert p.wait(timeout=300) == 0, p.communicate()
    return out


@pytest.mark.parametrize("sig, code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_a_signal_stops_at_the_end_of_a_chunk_and_resume_finishes_bitwise(
        sig, code, tmp_path, reference):
    out = tmp_path / "run.h5"
    p = start(out)
    wait_for_frames(out, 4, p)
    p.send_signal(sig)
    _, err = p.communicate(timeout=120)
    assert p.returncode == code
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"stopped: interrupted by {sig.name}")
    assert "Traceback" not in err
    run = io.read(out)
    assert run.status == "interrupted" and 4 <= run.frames < 81
    assert sidecar_frames(out) == run.frames
    assert not os.path.exists(str(out) + ".lock")
    if sig != signal.SIGINT:
        return                          # resuming is the same after either signal
    r = subprocess.run([sys.executable, "-m", "fpsi_jax.cli", "run", "--resume", str(out),
                        "--quiet", "--plot"], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    # --plot on the resume is heard; the dam break's own plot reads a whole run
    assert "no plot: the run was resumed" in r.stderr
    k, t, got = final_frame(out)
    k0, t0, want = final_frame(reference)
    assert (k, t) == (k0, t0) and io.read(out).status == "finished"
    assert sidecar_frames(out) == k + 1
    for name in want:
        assert np.array_equal(got[name], want[name]), name


def test_after_sigkill_the_sidecar_lists_the_frames_of_the_file(tmp_path):
    """A kill at any moment leaves every frame in /time whole and the sidecar listing the
    same frames, or one fewer when it lands in the one write of the sidecar's block (the
    sidecar is written last; io.py), never a frame the file lacks."""
    out = tmp_path / "run.h5"
    p = start(out)
    wait_for_frames(out, 3, p)
    time.sleep(0.3)
    p.kill()
    p.wait(timeout=60)
    run = io.read(out)                     # every listed frame whole
    assert run.status == "running" and run.frames >= 3
    assert sidecar_frames(out) in (run.frames - 1, run.frames)


def test_a_file_can_be_read_while_a_run_writes_it_and_a_second_run_is_refused(tmp_path):
    out = tmp_path / "run.h5"
    p = start(out, t_end=20.0)                 # still running when the second one starts
    try:
        wait_for_frames(out, 2, p)
        with h5py.File(out, "r") as f:                   # h5py's default, locking reader
            assert len(f["time"]) >= 2
        size = out.stat().st_size
        r = subprocess.run(RUN + ["--out", str(out), "--overwrite"], capture_output=True,
                           text=True, timeout=120)
        assert r.returncode == 2
        assert r.stderr.strip().splitlines() == [
            f"error: --out = {str(out)!r} is being written by another run ({out}.lock is "
            "held); choose another file"]
        assert out.stat().st_size >= size
    finally:
        p.send_signal(signal.SIGINT)
        p.wait(timeout=120)
    assert io.read(out).status == "interrupted"
