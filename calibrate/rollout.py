"""Differentiable rollouts with bounded memory (docs/design.md, *Gradients and calibration*).

A :class:`Problem` is a scene made ready for gradients: the static ``Physics`` (time step
and DEM sub-steps fixed, so every parameter set in a fit runs the same compiled program),
the initial ``State`` with its neighbour lists allocated, the base ``Params`` as arrays,
and the number of steps and the per-step observation.

:func:`checkpointed_rollout` is ``solver.forward.rollout`` split into an outer ``lax.scan``
over chunks whose body is wrapped in ``jax.checkpoint``: the reverse pass stores one
state per chunk and recomputes the inside of one chunk at a time, so with chunks of
√n steps a gradient through n steps keeps ~2√n states instead of n (memory measured in
``experiments/calibration_cost.py``). The price is one extra forward pass.
With ``remat_step=True`` each step inside a chunk is checkpointed as well: the backward
pass of a chunk then keeps one *state* per step rather than every intermediate of every
step (neighbour-pair arrays, DEM sub-steps), which is what bounds memory for the coupled
gate; it costs a second recomputation of each step.
"""
from __future__ import annotations

import dataclasses
import math
from typing import Callable

import jax
import jax.numpy as jnp
import numpy as np

from fpsi_jax.model.config import Physics
from fpsi_jax.model.errors import ParameterError
from fpsi_jax.model.params import Params
from fpsi_jax.model.scene import Scene
from fpsi_jax.model.state import State
from fpsi_jax.run.driver import setup
from fpsi_jax.solver import init, stages
from fpsi_jax.solver import forward as stepper


def checkpointed_rollout(phys: Physics, state: State, params: Params, n_steps: int,
                         observe: Callable[[State], object], chunk: int | None = None,
                         remat_step: bool = False):
    """``n_steps`` steps as ⌊n/chunk⌋ checkpointed chunks plus a remainder; returns (final
    state, observations stacked over all n steps). ``chunk`` defaults to ⌈√n⌉;
    ``remat_step`` also checkpoints every single step (see module docstring)."""
    chunk = int(chunk or max(1, math.ceil(math.sqrt(n_steps))))
    n_outer, rem = divmod(int(n_steps), chunk)
    step = jax.checkpoint(stepper.step, static_argnums=0) if remat_step else None

    def inner(s, p, n):
        if step is None:
            return stepper.rollout(phys, s, p, n, observe)

        def body(c, _):
            c = step(phys, c, p)
            return c, (None if observe is None else observe(c))
        return jax.lax.scan(body, s, None, length=n)

    block = jax.checkpoint(lambda s, p: inner(s, p, chunk))
    obs = []
    if n_outer:
        state, o = jax.lax.scan(lambda s, _: block(s, params), state, None, length=n_outer)
        obs.append(jax.tree_util.tree_map(lambda a: a.reshape((-1,) + a.shape[2:]), o))
    if rem:
        tail = jax.checkpoint(lambda s, p: inner(s, p, rem))
        state, o = tail(state, params)
        obs.append(o)
    return state, jax.tree_util.tree_map(lambda *a: jnp.concatenate(a), *obs)


@dataclasses.dataclass(frozen=True, eq=False)
class Problem:
    """A scene ready for differentiable rollouts (see module docstring).

    scene    the Scene (its builder keywords describe the case)
    phys     static Physics (dt and dem_substeps fixed)
    state0   initial State (rates are re-evaluated from the parameters in :meth:`run`)
    params   base Params (arrays of the Physics' dtype), dt included
    n_steps  steps per rollout;  chunk  steps per checkpointed chunk
    observe  State → small pytree recorded every step
    dt       the time step as a Python float (the bound-checked value)
    remat_step  checkpoint each step too (lower memory, one more recomputation)
    """

    scene: Scene
    phys: Physics
    state0: State
    params: Params
    n_steps: int
    chunk: int
    observe: Callable
    dt: float = 0.0
    remat_step: bool = False

    @property
    def times(self) -> np.ndarray:
        """Times of the observations (after each step)."""
        return (np.arange(self.n_steps) + 1) * self.dt

    def run(self, params: Params):
        """(final state, observations) for ``params``: pure, jittable, differentiable."""
        state = init.refresh_rates(self.phys, self.state0, params)
        return checkpointed_rollout(self.phys, state, params, self.n_steps, self.observe,
                                    self.chunk, self.remat_step)



def prepare(scene: Scene, t_end: float, observe: Callable, *, dt: float | None = None,
            params: Params | None = None, stiffest: Params | None = None,
            chunk: int | None = None, remat_step: bool = False,
            **physics_overrides) -> Problem:
    """Make ``scene`` ready for gradients over ``t_end`` seconds.

    The time step (and the DEM sub-steps of a coupled scene) is derived for ``stiffest``
    when given, the parameter set a fit may reach that needs the smallest step (e.g. the
    upper bounds of the fitted stiffnesses), and is then fixed for every evaluation, so
    the fit neither recompiles nor steps past a stability bound. Every check of
    :func:`fpsi_jax.run.driver.setup` runs here, before anything is compiled."""
    if not t_end > 0:
        raise ParameterError(f"t_end = {t_end} out of range; allowed (0, inf)")
    base = params or scene.params
    bound_for = stiffest or base
    phys, p_bound = setup(scene, dt, bound_for, **physics_overrides)
    overrides = dict(physics_overrides)
    if phys.has_fluid and phys.has_solid:
        overrides["dem_substeps"] = phys.dem_substeps
    phys, base = setup(scene, float(p_bound.dt), base, **overrides)
    p = base.as_arrays(stages.dtype(phys))
    state = init.init_state(scene, phys, p)
    n = int(math.ceil(t_end / float(base.dt) - 1e-9))
    return Problem(scene=scene, phys=phys, state0=state, params=p, n_steps=n,
                   chunk=int(chunk or max(1, math.ceil(math.sqrt(n)))), observe=observe,
                   dt=float(base.dt), remat_step=bool(remat_step))
