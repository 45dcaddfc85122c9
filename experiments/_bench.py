"""Shared by the benchmark scripts: a rollout chunk compiled per Physics and timed per run,
the compile-and-warm-up step, and the timed chunks. Neighbour-list overflow is handled by
``fpsi_jax.run.driver.run_until_fits`` (grow the lists, reallocate, redo the chunk), as in
the driver."""
from __future__ import annotations

import time

import jax

from fpsi_jax import solver
from fpsi_jax.run.driver import run_until_fits

_run = jax.jit(solver.rollout, static_argnums=(0, 3, 4))


class Chunk:
    """A ``steps``-long rollout chunk: ``chunk(phys, state) -> (end state, wall seconds)``,
    the ``attempt`` of ``run_until_fits``. The program is lowered and compiled (untimed) for
    each new ``phys`` (after a regrowth: larger lists, other shapes), then only the run is
    timed. ``compile_s``: the last compile's wall time."""

    def __init__(self, params, steps):
        self.params, self.steps = params, steps
        self.dt = float(params.dt)
        self.phys = self.compiled = None
        self.compile_s = 0.0

    def compile(self, phys, state):
        t0 = time.perf_counter()
        self.compiled = _run.lower(phys, state, self.params, self.steps, None).compile()
        self.compile_s = time.perf_counter() - t0
        self.phys = phys

    def __call__(self, phys, state):
        if self.compiled is None or phys != self.phys:
            self.compile(phys, state)
        t0 = time.perf_counter()
        end, _ = self.compiled(state, self.params)
        jax.block_until_ready(end)
        return end, time.perf_counter() - t0


def compile_and_warm_up(phys, state, params, steps):
    """Compile a ``steps``-long chunk (timed alone), then run one warm-up chunk through
    ``run_until_fits``: lists that overflow are grown, the program recompiled and the chunk
    redone, so the chunk that counts as the warm-up is the final program's first run.
    Returns (phys, state after the warm-up, chunk, compile_s)."""
    chunk = Chunk(params, steps)
    chunk.compile(phys, state)
    compile_s = chunk.compile_s
    c = run_until_fits(chunk, phys, state, chunk.dt)
    return c.phys, c.end, chunk, compile_s


def timed_chunks(chunk, phys, state, reps, *, same_start=True):
    """Time ``reps`` chunks: every one from ``state`` (``same_start``: the same work each
    time) or each from the previous one's end (the run continues). A chunk whose lists
    overflow is grown and redone by ``run_until_fits``; the redo is the recompiled
    program's first run, so it counts as a new warm-up: the timings so far are dropped and
    the timing starts again, from the reallocated ``state`` (``same_start``) or from the
    redone chunk's end. Returns (phys, the state the timed chunks started from, the last
    chunk's end state, wall seconds of each timed chunk, regrowths)."""
    start, walls, regrowths = state, [], 0
    end = None
    while len(walls) < reps:
        c = run_until_fits(chunk, phys, state, chunk.dt)
        phys, end = c.phys, c.end
        if c.regrowths:
            regrowths += c.regrowths
            walls = []
            start = state = c.state if same_start else c.end
            continue
        walls.append(c.result)
        if not same_start:
            state = end
    return phys, start, end, walls, regrowths
