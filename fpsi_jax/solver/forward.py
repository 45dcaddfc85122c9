"""The step and the rollouts built on it.

:func:`step` is the whole model on one screen: a chain of the stages of
:mod:`fpsi_jax.solver.stages`, each ``(physics, params, state) -> state``. Only the phases
the scene has are traced: a DEM-only scene compiles no SPH and a fluid-only scene no DEM.
"""
from __future__ import annotations

from typing import Callable

import jax
import jax.numpy as jnp

from ..model.config import Physics
from ..model.errors import number
from ..model.params import Params
from ..model.state import State
from . import order, stages


def step(phys: Physics, state: State, params: Params) -> State:
    """Advance one time step. Pure: (State, Params) → State.

    With fluid and discs the discs go first, in ``phys.dem_substeps`` sub-steps under the
    fluid force of the last SPH evaluation; the fluid then steps against the discs at the
    end of the step and returns the new force (a staggered, force-holding multi-rate
    scheme; docs/design.md)."""
    state = stages.clock(phys, params, state)
    if phys.has_solid:
        state = stages.discs(phys, params, state)             # DEM kick–drift–kick × n
        if phys.open_sides:
            state = stages.disc_exits(phys, params, state)    # out through an open side
        state = stages.check_discs(phys, params, state)
    if phys.has_fluid:
        state = stages.fluid_kick_drift(phys, params, state)  # v½, x'
        state = stages.fluid_neighbours(phys, params, state)
        state = stages.fluid_forces(phys, params, state)      # ρ', h', P', a', couplings
        state = stages.fluid_kick(phys, params, state)        # v'
        if phys.open_sides:
            state = stages.fluid_exits(phys, params, state)   # out through an open side
        state = stages.check_fluid(phys, params, state)
    return stages.mark_redo(phys, params, state)


def rollout(phys: Physics, state: State, params: Params, n_steps: int,
            observe: Callable[[State], object] | None = None):
    """Run ``n_steps`` steps under ``jax.lax.scan``; returns (final state, observations).

    ``observe(state)`` returns a small pytree recorded after every step (e.g. a front
    position); with ``observe=None`` nothing is recorded. With ``phys.sort_fluid`` the
    steps run on the fluid re-stored in cell order (:mod:`~fpsi_jax.solver.order`); the
    final state and what ``observe`` sees keep the fluid in ``state``'s order.

    Every step takes ``params.dt``, with the neighbour lists as ``state`` holds them, and
    nothing is checked or redone: a list that ran out of room, a step past the stability
    bound or a blow-up carry on silently. Test the end state's ``status`` (``bad``: a
    non-finite or out-of-band value, with ``step`` the first such step; ``overflow``: a
    list too small) before using what it returns (:func:`fpsi_jax.run.check_rollout`);
    :func:`fpsi_jax.run.simulate` does this, grows the lists and redoes the chunk, but
    runs on the host and is not differentiable (differentiate this function). Damp with
    ``dem.damping`` (viscous) where you differentiate: K25's local damping ``dem.alpha``
    switches with each velocity's sign and reverse mode misses the switching times, so its
    gradient is not the derivative of the loss (a bonded specimen under compression:
    8·10⁸⁵ against a central difference of 1.6·10⁴; with ``dem.damping`` the two agree to
    10⁻⁸).
    """

    n_steps = int(number("n_steps", n_steps, 0, None, integer=True))

    def run(state, observe):
        def body(s, _):
            s = step(phys, s, params)
            return s, (None if observe is None else observe(s))

        return jax.lax.scan(body, state, None, length=n_steps)

    return order.sorted_chunk(phys, state, run, observe)


def advance(phys: Physics, state: State, params: Params, n, n_max: int,
            observe: Callable[[State], object] | None = None):
    """Take ``n`` ≤ ``n_max`` steps, ``n`` a traced integer: one compiled program serves
    every chunk length up to ``n_max``, so the host driver's last, shorter chunk does not
    compile a second program (2–5 s for a coupled scene). Observations fill the first ``n``
    rows of an ``n_max``-row buffer (the rest stay zero). A while loop underneath: not
    reverse-differentiable, use :func:`rollout` for gradients. The fluid's storage order as
    in :func:`rollout`."""
    buf = None if observe is None else jax.tree_util.tree_map(
        lambda a: jnp.zeros((n_max,) + a.shape, a.dtype), jax.eval_shape(observe, state))

    def run(state, observe):
        def body(i, carry):
            s, b = carry
            s = step(phys, s, params)
            if observe is not None:
                b = jax.tree_util.tree_map(
                    lambda bb, o: jax.lax.dynamic_update_index_in_dim(bb, o, i, 0), b,
                    observe(s))
            return s, b

        return jax.lax.fori_loop(0, n, body, (state, buf))

    return order.sorted_chunk(phys, state, run, observe)
