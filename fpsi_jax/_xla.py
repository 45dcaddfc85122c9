"""XLA:CPU compiler settings that the particle sums need (set once, at import).

Two groups of ``XLA_FLAGS``, each worth a large factor on the neighbour sums (reductions
over the neighbour axis of (N, K) arrays) on a CPU:

1. **No YNNPACK fusions** (``--xla_cpu_experimental_ynn_fusion_type=``, an empty list).
   jaxlib 0.10's CPU compiler hands elementwise-and-reduce fusions to YNNPACK; for our pair
   sums that library path is 3x slower than XLA's own loop fusions: the full-physics dam
   break at 24k particles took 47 ms a step with it and 16 ms without.

2. **Reassociation and contraction, with IEEE special values kept**
   (``--xla_cpu_enable_fast_math=true`` together with ``--xla_cpu_fast_math_honor_nans``,
   ``_infs``, ``_division`` and ``_functions`` all ``true``). LLVM may then reorder a float
   sum (so the reduction over the K neighbour slots is vectorised instead of summed one
   slot after another) and fuse a multiply and an add into one FMA. It does *not* assume
   away NaN or infinity (the finiteness checks of the driver still see them), does not
   replace a divide by a reciprocal, and keeps the accurate exp/log/pow. Results change at
   float round-off only (a sum over 35 slots in another order). The dam break's step went
   from 2.2 to 1.6 ms at 6.9k particles and from 10.2 to 8.0 ms at 24k (docs/performance.md).

``import fpsi_jax`` adds each group to ``XLA_FLAGS`` unless

* the user already set any flag of that group in ``XLA_FLAGS`` (theirs wins; nothing of
  that group is added), or
* ``FPSI_KEEP_XLA_FLAGS=1`` is set (nothing is added), or
* a JAX backend was already initialised before fpsi_jax was imported (XLA reads
  ``XLA_FLAGS`` once, when the first backend starts): then a warning says how to get the
  settings (import fpsi_jax first, or export the flags).

These are compiler options, not changes to the compiled program's maths; GPU backends
ignore them (XLA:GPU reassociates its reductions anyway). Nothing inside a jitted function
depends on them.

**Compiled programs on disk** (:func:`configure_cache`, ``fpsi_jax.use_compile_cache()``;
the ``fpsi`` command and the test suite call it, a Python program that imports fpsi_jax
decides for itself, since the setting is JAX's and covers all of its programs): JAX's
persistent compilation cache, in ``$FPSI_CACHE_DIR`` or ``~/.cache/fpsi-jax/xla`` (under
``$XDG_CACHE_HOME`` when set), one folder per number of usable cores (:func:`cache_dir`),
every program however quick to compile; above 1 GiB the
oldest entries are deleted when it is turned on (:func:`prune`). A run's fixed cost is
mostly compilation: the step's chunk, the set-up's and the list allocation's programs; a
repeated run of the same scene loads them instead. The cache key covers the
program, the XLA flags, the device and the JAX version, so a changed scene or setting
compiles afresh. Left alone
when the user has chosen a cache directory for JAX (``JAX_COMPILATION_CACHE_DIR`` or
``jax.config``), or with ``FPSI_NO_COMPILE_CACHE=1``. On some Intel CPUs JAX 0.9–0.10
rejects every cached CPU program on reload (jax-ml/jax#38445: an error line per program,
then an ordinary compile); there ``FPSI_NO_COMPILE_CACHE=1`` keeps the log quiet.
"""
from __future__ import annotations

import os
import warnings

#: no YNNPACK fusions (group 1 above)
FLAG = "--xla_cpu_experimental_ynn_fusion_type="
#: reassociation and FMA contraction with NaN, infinity, division and functions honoured
#: (group 2 above)
REASSOCIATE = ("--xla_cpu_enable_fast_math=true",
               "--xla_cpu_fast_math_honor_nans=true",
               "--xla_cpu_fast_math_honor_infs=true",
               "--xla_cpu_fast_math_honor_division=true",
               "--xla_cpu_fast_math_honor_functions=true")
GROUPS = ((FLAG,), REASSOCIATE)
FLAGS = tuple(f for g in GROUPS for f in g)


def _name(flag: str) -> str:
    return flag.lstrip("-").split("=", 1)[0]


def _backend_started() -> bool:
    try:
        from jax._src import xla_bridge
        return bool(getattr(xla_bridge, "_backends", {}))
    except Exception:  # pragma: no cover - private API moved: assume not started
        return False


def configure() -> bool:
    """Add :data:`GROUPS` to XLA_FLAGS where allowed (see module docstring); True if all of
    :data:`FLAGS` are in force for this process (set now or by the user)."""
    flags = os.environ.get("XLA_FLAGS", "")
    given = {_name(f) for f in flags.split()}
    missing = [g for g in GROUPS if not any(_name(f) in given for f in g)]
    if not missing:
        return all(f in flags.split() for f in FLAGS)
    if os.environ.get("FPSI_KEEP_XLA_FLAGS") == "1":
        return False
    if _backend_started():
        warnings.warn(
            "fpsi_jax was imported after JAX started its backend, so it could not switch off "
            "XLA:CPU's YNNPACK fusions or allow reassociation of the neighbour sums (SPH sums "
            "run ~3-4x slower). Import fpsi_jax before running any JAX computation, or export "
            f"XLA_FLAGS='{' '.join(FLAGS)}'.", stacklevel=3)
        return False
    added = [f for g in missing for f in g]
    os.environ["XLA_FLAGS"] = " ".join([flags] + added).strip()
    return all(f in os.environ["XLA_FLAGS"].split() for f in FLAGS)


#: most bytes the compilation cache keeps (the oldest entries go first: :func:`prune`)
CACHE_BYTES = 2 ** 30


def cache_dir() -> str:
    """Where :func:`configure_cache` keeps compiled programs: a folder per number of CPU
    cores this process may run on (:func:`cores`), in ``$FPSI_CACHE_DIR`` or
    ``~/.cache/fpsi-jax/xla``.

    XLA:CPU splits a program's loops over the cores the process may use *when it compiles
    it*, and JAX's cache key does not include that number: a program compiled in a process
    pinned to one core (``taskset -c 1``, a one-CPU container) and loaded by a process on
    two ran on one core. The elastic gate's 0.1 s took 16.3 s of stepping so, 10.1 s
    compiled on two cores (docs/performance.md, *Compiled programs and cores*)."""
    base = os.environ.get("FPSI_CACHE_DIR")
    if not base:
        home = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"),
                                                                 ".cache")
        base = os.path.join(home, "fpsi-jax", "xla")
    return os.path.join(base, f"cores-{cores()}")


def cores() -> int:
    """The CPU cores this process may run on (its affinity mask; all cores where the
    platform has none)."""
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return os.cpu_count() or 1


def configure_cache() -> str | None:
    """Turn on JAX's persistent compilation cache in :func:`cache_dir` (module docstring);
    the directory in use, or None when left off (the user's own choice, opt-out, or a
    directory that cannot be made)."""
    if os.environ.get("FPSI_NO_COMPILE_CACHE") == "1":
        return None
    if os.environ.get("JAX_COMPILATION_CACHE_DIR"):
        return None
    import jax
    if jax.config.jax_compilation_cache_dir:
        return None
    path = cache_dir()
    try:
        os.makedirs(path, exist_ok=True)
    except OSError:
        return None
    if not os.access(path, os.W_OK):
        return None
    prune(path)
    if not os.environ.get("FPSI_CACHE_DIR"):
        # programs written straight into the default folder (no folder per core count)
        # are never looked up again
        prune(os.path.dirname(path), limit=0)
    jax.config.update("jax_compilation_cache_dir", path)
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
    jax.config.update("jax_persistent_cache_min_entry_size_bytes", -1)   # any size
    return path


def prune(path: str, limit: int = CACHE_BYTES) -> None:
    """Delete the least recently written files of ``path`` (not its folders) until it holds
    under 3/4 of ``limit`` bytes, if it holds more than ``limit`` (JAX's own size limit
    needs the ``filelock`` package, which fpsi-jax does not depend on). A program deleted while
    another process wants it is only compiled again."""
    try:
        files = [(e.stat().st_mtime, e.stat().st_size, e.path) for e in os.scandir(path)
                 if e.is_file()]
    except OSError:
        return
    total = sum(size for _, size, _ in files)
    if total <= limit:
        return
    for _, size, name in sorted(files):
        try:
            os.remove(name)
        except OSError:
            continue
        total -= size
        if total < 0.75 * limit:
            return
