"""fpsi_jax._xla: the XLA:CPU fusion flag is set on import, the user's own setting wins, and
importing after a backend started warns instead of silently doing nothing."""
from __future__ import annotations

import os
import subprocess
import sys

from fpsi_jax import _xla


def _run(code, **env):
    e = {k: v for k, v in os.environ.items() if k not in ("XLA_FLAGS", "FPSI_KEEP_XLA_FLAGS")}
    e.update(env)
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=e,
                          timeout=120)


def test_import_sets_the_flag():
    r = _run("import os, fpsi_jax; print(fpsi_jax.XLA_FAST_SUMS, os.environ['XLA_FLAGS'])")
    assert r.returncode == 0, r.stderr
    assert r.stdout.split()[0] == "True" and _xla.FLAG in r.stdout


def test_user_flags_are_kept():
    r = _run("import os, fpsi_jax; print(fpsi_jax.XLA_FAST_SUMS, os.environ['XLA_FLAGS'])",
             XLA_FLAGS="--xla_cpu_experimental_ynn_fusion_type=LIBRARY_FUSION_TYPE_REDUCE")
    assert r.returncode == 0, r.stderr
    assert r.stdout.split() == ["False",
                                "--xla_cpu_experimental_ynn_fusion_type=LIBRARY_FUSION_TYPE_REDUCE"]
    r = _run("import os, fpsi_jax; print(fpsi_jax.XLA_FAST_SUMS, 'XLA_FLAGS' in os.environ)",
             FPSI_KEEP_XLA_FLAGS="1")
    assert r.stdout.split() == ["False", "False"]


def test_import_after_backend_start_warns():
    r = _run("import jax; jax.numpy.ones(1).block_until_ready(); import fpsi_jax; "
             "print(fpsi_jax.XLA_FAST_SUMS)")
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "False"
    assert "could not switch off" in r.stderr
