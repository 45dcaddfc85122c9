"""How many particles a scene may have on this machine, checked before any array is made.

A step needs about :data:`BYTES_PER_PARTICLE` of memory per particle (the dam break at
6.9k particles: ~50 MB of per-pair and per-particle arrays a step, 7.2 kB a particle; the
jax-md neighbour table dominates), so a lattice of more particles than the machine's memory
holds is refused with the estimate and the limit instead of failing deep inside numpy or
XLA. ``fpsi run --max-particles N`` (or :func:`allow` in Python) raises the limit for a
bigger machine or an accelerator with more memory.
"""
from __future__ import annotations

import contextlib
import os

from .errors import ParameterError

BYTES_PER_PARTICLE = 8 * 1024

_override: list[int | None] = [None]


def machine_memory() -> int:
    """Physical memory of this machine [bytes] (0 where the OS does not say)."""
    try:
        return int(os.sysconf("SC_PAGE_SIZE")) * int(os.sysconf("SC_PHYS_PAGES"))
    except (ValueError, OSError, AttributeError):
        return 0


def max_particles() -> int:
    """The limit in force: :func:`allow`'s, else memory / BYTES_PER_PARTICLE (1e7 when the
    memory is unknown)."""
    if _override[0] is not None:
        return _override[0]
    mem = machine_memory()
    return mem // BYTES_PER_PARTICLE if mem else 10_000_000


@contextlib.contextmanager
def allow(n: int):
    """Raise (or lower) the particle limit to ``n`` inside the block."""
    old = _override[0]
    _override[0] = int(n)
    try:
        yield
    finally:
        _override[0] = old


def check(n: float, what: str) -> None:
    """ParameterError if ``n`` particles exceed the limit (say the estimate and the limit)."""
    limit = max_particles()
    if n > limit:
        need = n * BYTES_PER_PARTICLE / 1e9
        mem = machine_memory() / 1e9
        raise ParameterError(
            f"{what}: {n:.3g} particles would need about {need:.3g} GB; this machine's limit "
            f"is {limit:,} particles ({mem:.3g} GB of memory); use --max-particles N to raise it")
