"""fpsi_jax._xla: the XLA:CPU flags are set on import, the user's own setting of a group wins,
importing after a backend started warns instead of silently doing nothing, and the
reassociation group keeps NaN and infinity visible to the driver's finiteness checks."""
from __future__ import annotations

import os
import subprocess
import sys

from fpsi_jax import _xla


def _run(code, **env):
    e = {k: v for k, v in os.environ.items()
         if k not in ("XLA_FLAGS", "FPSI_KEEP_XLA_FLAGS", "JAX_COMPILATION_CACHE_DIR",
                      "FPSI_NO_COMPILE_CACHE", "FPSI_CACHE_DIR")}
    e.update(env)
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=e,
                          timeout=120)


def test_import_sets_the_flags():
    r = _run("import os, fpsi_jax; print(fpsi_jax.XLA_FAST_SUMS); print(os.environ['XLA_FLAGS'])")
    assert r.returncode == 0, r.stderr
    first, flags = r.stdout.splitlines()
    assert first == "True"
    assert flags.split() == list(_xla.FLAGS)


def test_user_flags_are_kept():
    ynn = "--xla_cpu_experimental_ynn_fusion_type=LIBRARY_FUSION_TYPE_REDUCE"
    r = _run("import os, fpsi_jax; print(fpsi_jax.XLA_FAST_SUMS); print(os.environ['XLA_FLAGS'])",
             XLA_FLAGS=ynn)
    assert r.returncode == 0, r.stderr
    first, flags = r.stdout.splitlines()
    # the user's YNN setting is kept as it is, the other group is still added
    assert first == "False" and flags.split() == [ynn, *_xla.REASSOCIATE]
    # any flag of the reassociation group given by the user: none of that group is added
    r = _run("import os, fpsi_jax; print(fpsi_jax.XLA_FAST_SUMS); print(os.environ['XLA_FLAGS'])",
             XLA_FLAGS="--xla_cpu_enable_fast_math=false")
    first, flags = r.stdout.splitlines()
    assert first == "False" and flags.split() == ["--xla_cpu_enable_fast_math=false", _xla.FLAG]
    r = _run("import os, fpsi_jax; print(fpsi_jax.XLA_FAST_SUMS, 'XLA_FLAGS' in os.environ)",
             FPSI_KEEP_XLA_FLAGS="1")
    assert r.stdout.split() == ["False", "False"]
    # all of ours given by the user: in force, nothing added twice
    r = _run("import os, fpsi_jax; print(fpsi_jax.XLA_FAST_SUMS); print(os.environ['XLA_FLAGS'])",
             XLA_FLAGS=" ".join(_xla.FLAGS))
    first, flags = r.stdout.splitlines()
    assert first == "True" and flags.split() == list(_xla.FLAGS)


def test_import_after_backend_start_warns():
    r = _run("import jax; jax.numpy.ones(1).block_until_ready(); import fpsi_jax; "
             "print(fpsi_jax.XLA_FAST_SUMS)")
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "False"
    assert "could not switch off" in r.stderr


def test_reassociation_keeps_nan_and_inf():
    """With the flags in force a jitted 0/0 is NaN, isnan/isfinite see it, a sum and a max
    over it stay NaN, x/0 is inf (no reciprocal rewrite), and a float32 sum of integers is
    still exact (the neighbour running count relies on that)."""
    code = (
        "import fpsi_jax, jax, jax.numpy as jnp\n"
        "assert fpsi_jax.XLA_FAST_SUMS\n"
        "f = jax.jit(lambda a, b: (jnp.isnan(a / b).all(), jnp.isfinite(a / b).any(),\n"
        "    jnp.isnan(jnp.sum(a / b)), jnp.isnan(jnp.max(a / b)), jnp.isinf(1.0 / b).all(),\n"
        "    jnp.isnan(jnp.minimum(a / b, 1.0)).all()))\n"
        "print(*[bool(v) for v in f(jnp.zeros(64), jnp.zeros(64))])\n"
        "n = jnp.arange(4096, dtype=jnp.float32)\n"
        "print(int(jax.jit(jnp.sum)(n)) == 4095 * 4096 // 2)\n")
    r = _run(code)
    assert r.returncode == 0, r.stderr
    assert r.stdout.split() == ["True", "False", "True", "True", "True", "True", "True"]


# --- the compilation cache ------------------------------------------------------------------
_JIT = ("import fpsi_jax, jax, jax.numpy as jnp; "
        "print(fpsi_jax.use_compile_cache(), jax.config.jax_compilation_cache_dir); "
        "jax.jit(lambda x: jnp.sin(x) * 3.0 + x)(jnp.arange(5.0)).block_until_ready()")


def test_compiled_programs_are_kept_and_found_again(tmp_path):
    """use_compile_cache() turns on JAX's persistent cache in FPSI_CACHE_DIR; a program
    compiled in one process is written there, and a second process loads it (JAX logs the
    cache hit). Importing fpsi_jax alone leaves JAX's setting as it was."""
    cache = os.path.join(tmp_path, "xla", f"cores-{_xla.cores()}")
    logged = ("import logging; logging.basicConfig(level=logging.DEBUG); "
              "logging.getLogger('jax._src.compiler').setLevel(logging.DEBUG); " + _JIT)
    r = _run(logged, FPSI_CACHE_DIR=str(tmp_path / "xla"))
    assert r.returncode == 0, r.stderr
    assert r.stdout.split() == [cache, cache]
    assert os.listdir(cache)
    assert "Persistent compilation cache hit for 'jit__lambda'" not in r.stderr
    r = _run(logged, FPSI_CACHE_DIR=str(tmp_path / "xla"))
    assert r.returncode == 0, r.stderr
    assert "Persistent compilation cache hit for 'jit__lambda'" in r.stderr
    r = _run("import fpsi_jax, jax; print(jax.config.jax_compilation_cache_dir)",
             FPSI_CACHE_DIR=str(tmp_path / "xla"))
    assert r.stdout.split() == ["None"]


def test_programs_compiled_on_fewer_cores_are_kept_apart(tmp_path):
    """A process allowed fewer cores compiles into a folder of its own: XLA:CPU splits a
    program's loops over the cores it may use when it compiles, and a program compiled on
    one core, loaded on two, ran on one."""
    code = "import fpsi_jax, jax; print(fpsi_jax.use_compile_cache())"
    r = _run(code, FPSI_CACHE_DIR=str(tmp_path))
    assert r.stdout.split() == [os.path.join(tmp_path, f"cores-{_xla.cores()}")]
    one = sorted(os.sched_getaffinity(0))[0]
    r = _run(f"import os; os.sched_setaffinity(0, {{{one}}}); " + code,
             FPSI_CACHE_DIR=str(tmp_path))
    assert r.returncode == 0, r.stderr
    assert r.stdout.split() == [os.path.join(tmp_path, "cores-1")]


def test_the_default_folder_drops_programs_of_no_core_count(tmp_path):
    """Under the default location, programs written beside the per-core folders (no core
    count in their path) are deleted: nothing looks them up."""
    base = tmp_path / "fpsi-jax" / "xla"
    base.mkdir(parents=True)
    (base / "jit_f-0123-cache").write_bytes(b"x" * 10)
    r = _run("import fpsi_jax; print(fpsi_jax.use_compile_cache())", XDG_CACHE_HOME=str(tmp_path))
    assert r.returncode == 0, r.stderr
    assert r.stdout.split() == [str(base / f"cores-{_xla.cores()}")]
    assert os.listdir(base) == [f"cores-{_xla.cores()}"]


def test_the_users_cache_choice_and_the_opt_out_are_kept(tmp_path):
    mine = str(tmp_path / "mine")
    r = _run(_JIT, JAX_COMPILATION_CACHE_DIR=mine, FPSI_CACHE_DIR=str(tmp_path / "ours"))
    assert r.returncode == 0, r.stderr
    assert r.stdout.split() == ["None", mine]
    assert not os.path.exists(tmp_path / "ours")
    r = _run(_JIT, FPSI_NO_COMPILE_CACHE="1", FPSI_CACHE_DIR=str(tmp_path / "o"))
    assert r.stdout.split() == ["None", "None"]
    assert not os.path.exists(tmp_path / "o")


def test_prune_deletes_the_oldest_entries_above_the_limit(tmp_path):
    for k in range(10):
        f = tmp_path / f"e{k}"
        f.write_bytes(b"x" * 100)
        os.utime(f, (1000 + k, 1000 + k))
    _xla.prune(str(tmp_path), limit=2000)          # under the limit: nothing goes
    assert len(os.listdir(tmp_path)) == 10
    _xla.prune(str(tmp_path), limit=800)           # to under 600 bytes, oldest first
    assert sorted(os.listdir(tmp_path)) == [f"e{k}" for k in range(5, 10)]
