"""Shared by the benchmark scripts: compile a rollout chunk, run one warm-up chunk, time a
chunk."""
from __future__ import annotations

import time

import jax

from fpsi_jax import integrate
from fpsi_jax.simulate import grow, reallocate

_run = jax.jit(integrate.rollout, static_argnums=(0, 3, 4))


def compile_and_warm_up(phys, state, params, steps):
    """Compile a ``steps``-long chunk (timed alone), then run one warm-up chunk, growing the
    neighbour lists and recompiling on overflow as the driver does (so the timed chunks
    never overflow at the start). Returns (phys, state after warm-up, compiled, compile_s)."""
    t0 = time.perf_counter()
    compiled = _run.lower(phys, state, params, steps, None).compile()
    compile_s = time.perf_counter() - t0
    while True:
        new, _ = timed_chunk(compiled, state, params)
        if not needs_growth(new):
            return phys, new, compiled, compile_s
        phys = grow(phys, new)
        state = reallocate(phys, state)
        compiled = _run.lower(phys, state, params, steps, None).compile()


def timed_chunk(compiled, state, params):
    """Run one compiled chunk from ``state``; returns (end state, wall seconds)."""
    t0 = time.perf_counter()
    new, _ = compiled(state, params)
    jax.block_until_ready(new)
    return new, time.perf_counter() - t0


def needs_growth(state) -> bool:
    """The chunk that ended in ``state`` overflowed a list or let h outgrow the cut-off."""
    return bool(state.status.overflow) or bool(state.status.h_exceeded)
