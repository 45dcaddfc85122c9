"""XLA:CPU compiler setting that the particle sums need (set once, at import).

jaxlib 0.10's CPU compiler hands elementwise-and-reduce fusions to YNNPACK
(``--xla_cpu_experimental_ynn_fusion_type``). For our pair sums — a reduction over the
neighbour axis of (N, K) and (N, K, 2) arrays — that library path is 3x slower than XLA's
own loop fusions: the full-physics dam break at 24k particles took 47 ms a step with it
and 16 ms without (experiments/bench_sph.py, README "Speed"). So fpsi_jax switches the
YNNPACK fusions off by adding ``--xla_cpu_experimental_ynn_fusion_type=`` (an empty list) to
``XLA_FLAGS`` when it is imported, unless

* the user already set that flag in ``XLA_FLAGS`` (theirs wins), or
* ``FPSI_KEEP_XLA_FLAGS=1`` is set, or
* a JAX backend was already initialised before fpsi_jax was imported (XLA reads
  ``XLA_FLAGS`` once, when the first backend starts): then a warning says how to get the
  setting (import fpsi_jax first, or export the flag).

The flag is a compiler option, not a change to the compiled program's maths; GPU
backends ignore it. Nothing inside a jitted function depends on it.
"""
from __future__ import annotations

import os
import warnings

FLAG = "--xla_cpu_experimental_ynn_fusion_type="


def _backend_started() -> bool:
    try:
        from jax._src import xla_bridge
        return bool(getattr(xla_bridge, "_backends", {}))
    except Exception:  # pragma: no cover - private API moved: assume not started
        return False


def configure() -> bool:
    """Add :data:`FLAG` to XLA_FLAGS if allowed (see module docstring); True if it is in
    force for this process (set now or by the user)."""
    flags = os.environ.get("XLA_FLAGS", "")
    if "xla_cpu_experimental_ynn_fusion_type" in flags:
        return FLAG in flags.split()
    if os.environ.get("FPSI_KEEP_XLA_FLAGS") == "1":
        return False
    if _backend_started():
        warnings.warn(
            "fpsi_jax was imported after JAX started its backend, so it could not switch off "
            "XLA:CPU's YNNPACK fusions (SPH sums run ~3x slower). Import fpsi_jax before "
            f"running any JAX computation, or export XLA_FLAGS='{FLAG}'.", stacklevel=3)
        return False
    os.environ["XLA_FLAGS"] = (flags + " " + FLAG).strip()
    return True
