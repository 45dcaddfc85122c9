"""Composition of the mechanisms, the time stepper and rollouts.

``step`` is the one place where the physics modules meet: read it to see the whole model.
Integration is leapfrog (velocity Verlet, W6/K5) with one neighbour pass per step, the
density treated like a position (it is drifted with the velocity at the half step):

    v½ = v + ½Δt a
    x' = x + Δt (v½ + δv_XSPH)
    Dρ/Dt at (x', v½)                       (continuity, δ-SPH)
    ρ' = ρ + Δt Dρ/Dt,  h' = h + Δt Dh/Dt,  P' = P(ρ')
    a' at (x', ρ', P', v½)                  (pressure, anti-clump, viscosity, gravity)
    v' = v½ + ½Δt a'

For the acoustic mode this is the symplectic leapfrog, stable up to ωΔt = 2. (Kicking ρ by
half steps with a stored rate, like v, is unconditionally unstable: see
tests/test_integrate.py::test_density_update_is_stable_for_acoustic_oscillator.) The
geometry of the pairs is computed once and shared by the density and momentum passes; the
kernel uses h of the start of the step. The XSPH correction δv_XSPH used in a drift is the one
of the previous step; it smooths the transport velocity, so the O(Δt) lag is harmless.
"""
from __future__ import annotations

from typing import Callable

import jax
import jax.numpy as jnp
import numpy as np

from . import kernels, neighbors, sph
from .params import ParameterError, Params
from .scene import Physics, Scene
from .state import BoundaryState, FluidState, State, Status


def dtype(phys: Physics):
    """Floating-point type of the compiled step."""
    return jnp.float64 if phys.x64 else jnp.float32


def _cat(fluid_a, boundary_a):
    return fluid_a if boundary_a is None else jnp.concatenate([fluid_a, boundary_a])


# --- forces ------------------------------------------------------------------------------
def fluid_update(phys: Physics, params: Params, x, v, rho, h, mass, boundary, nbrs, dt):
    """One SPH evaluation at positions ``x`` and velocities ``v`` (v½ in a step):
    returns (ρ', h', a', δv_XSPH, boundary) with ρ' = ρ + dt Dρ/Dt (dt = 0: no drift)."""
    sp, kern, nf = params.sph, kernels.get(phys.kernel), phys.n_fluid
    g = jnp.asarray(params.gravity)
    b = boundary
    all_x = _cat(x, None if b is None else b.x)
    all_v = _cat(v, None if b is None else jnp.zeros_like(b.x))
    all_h = _cat(h, None if b is None else b.h)
    all_m = _cat(mass, None if b is None else b.mass)
    pr = sph.pairs(kern, nf, all_x, all_v, all_h, all_m,
                   _cat(rho, None if b is None else b.rho), nbrs.idx[:nf])
    drho = sph.density_rate(phys, sp, rho, pr)
    rho_new = rho + dt * drho
    if phys.variable_h:
        with jax.named_scope("sph.variable_h"):
            h_new = h + dt * sph.smoothing_length_rate(h, rho, drho)
    else:
        h_new = h
    with jax.named_scope("sph.eos"):
        p_new = sph.eos_pressure(rho_new, sp.rho0, sp.c0, sp.gamma)
    if b is not None and phys.boundary_pressure == "extrapolated":
        with jax.named_scope("boundary.extrapolated"):
            pb, rhob = sph.extrapolated_boundary_pressure(
                nf, kern, sp, g, all_x, all_h, _cat(rho_new, b.rho), _cat(p_new, b.p),
                nbrs.idx[nf:])
        b = b.replace(p=pb, rho=rhob)
    acc, xs = sph.momentum_rate(phys, kern, sp, g, _cat(rho_new, None if b is None else b.rho),
                                _cat(p_new, None if b is None else b.p), pr)
    return rho_new, h_new, acc, xs, b


# --- health ------------------------------------------------------------------------------
def _check(phys: Physics, params: Params, fluid: FluidState, step, status: Status) -> Status:
    """Per-particle health codes (see state.STATUS_CODES); remember the first failure."""
    lo = jnp.asarray(phys.neighbors.origin, fluid.x.dtype)
    hi = lo + jnp.asarray(phys.neighbors.box, fluid.x.dtype)
    rho0 = params.sph.rho0
    code = jnp.where(~jnp.all(jnp.isfinite(fluid.x), axis=1), 1,
           jnp.where(~jnp.all(jnp.isfinite(fluid.v), axis=1), 2,
           jnp.where(~jnp.isfinite(fluid.rho), 3,
           jnp.where(jnp.abs(fluid.rho / rho0 - 1.0) > phys.rho_tolerance, 4,
           jnp.where(jnp.any((fluid.x < lo) | (fluid.x >= hi), axis=1), 5, 0)))))
    bad_now = jnp.any(code > 0)
    i = jnp.argmax(code > 0).astype(jnp.int32)
    first = bad_now & ~status.bad
    return status.replace(
        bad=status.bad | bad_now,
        step=jnp.where(first, step, status.step),
        particle=jnp.where(first, i, status.particle),
        code=jnp.where(first, code[i].astype(jnp.int32), status.code))


# --- the step ----------------------------------------------------------------------------
def step(phys: Physics, state: State, params: Params) -> State:
    """Advance one time step (see the module docstring). Pure: (State, Params) → State."""
    dt = params.dt
    f = state.fluid
    with jax.named_scope("integrate.kick_drift"):
        v_half = f.v + 0.5 * dt * f.acc
        x_new = f.x + dt * (v_half + f.xsph)
    with jax.named_scope("neighbors.update"):
        all_x = _cat(x_new, None if state.boundary is None else state.boundary.x)
        nbrs, rebuilt = neighbors.update(phys.neighbors, state.nbrs, all_x)
    rho, h, acc, xs, b = fluid_update(phys, params, x_new, v_half, f.rho, f.h, f.mass,
                                      state.boundary, nbrs, dt)
    with jax.named_scope("integrate.kick"):
        fluid = f.replace(x=x_new, v=v_half + 0.5 * dt * acc, rho=rho, h=h, acc=acc, xsph=xs)
    n = state.step + 1
    st = state.status
    st = st.replace(overflow=st.overflow | nbrs.did_buffer_overflow.astype(bool),
                    h_exceeded=st.h_exceeded | (jnp.max(fluid.h) * 2.0 > phys.neighbors.r_cut),
                    rebuilds=st.rebuilds + rebuilt.astype(jnp.int32))
    st = _check(phys, params, fluid, n, st)
    return State(t=n * dt, step=n, fluid=fluid, boundary=b, nbrs=nbrs, status=st)


def rollout(phys: Physics, state: State, params: Params, n_steps: int,
            observe: Callable[[State], object] | None = None):
    """Run ``n_steps`` steps under ``jax.lax.scan``; returns (final state, observations).

    ``observe(state)`` returns a small pytree recorded after every step (e.g. a front
    position); with ``observe=None`` nothing is recorded.
    """

    def body(s, _):
        s = step(phys, s, params)
        return s, (None if observe is None else observe(s))

    return jax.lax.scan(body, state, None, length=n_steps)


# --- initial state -----------------------------------------------------------------------
def init_state(scene: Scene, phys: Physics, params: Params) -> State:
    """Arrays on device, neighbour list allocated, initial rates evaluated."""
    dt_ = dtype(phys)
    a = lambda v: jnp.asarray(v, dtype=dt_)
    fl = scene.fluid
    b = scene.boundary
    boundary = None if b is None else BoundaryState(
        x=a(b.x), rho=a(b.rho), p=a(b.p), h=a(b.h), mass=a(b.mass))
    x = a(fl.x)
    all_x = x if boundary is None else jnp.concatenate([x, boundary.x])
    nbrs = neighbors.allocate(phys.neighbors, all_x)
    z = jnp.zeros_like
    fluid = FluidState(x=x, v=a(fl.v), rho=a(fl.rho), h=a(fl.h), mass=a(fl.mass),
                       acc=z(x), xsph=z(x))
    return refresh_rates(phys, State(t=a(0.0), step=jnp.zeros((), jnp.int32), fluid=fluid,
                                     boundary=boundary, nbrs=nbrs, status=Status.ok()),
                         params)


def refresh_rates(phys: Physics, state: State, params: Params) -> State:
    """Recompute the stored acceleration and XSPH correction at the current state (after
    init or a reallocation); positions, densities and h are left as they are."""
    f = state.fluid
    _, _, acc, xs, b = fluid_update(phys, params, f.x, f.v, f.rho, f.h, f.mass,
                                    state.boundary, state.nbrs, 0.0)
    return state.replace(fluid=f.replace(acc=acc, xsph=xs), boundary=b)


# --- time step ---------------------------------------------------------------------------
def stable_dt(scene: Scene, params: Params | None = None, a_max: float | None = None) -> float:
    """Largest time step allowed by the explicit bounds of physics.md §Time integration:
    Δt ≤ min(0.25 h/(c0 + |v|max), 0.125 h²/ν, 0.25 √(h/|a|max)), h the smallest smoothing
    length, |v|max the scene's velocity scale and |a|max = max(|g|, a_max)."""
    p = params or scene.params
    sp = p.sph
    h = float(np.min(scene.fluid.h))
    nu = float(sp.mu) / float(sp.rho0)
    g = float(np.linalg.norm(np.asarray(p.gravity, float)))
    acc = max(g, a_max or 0.0, 1e-12)
    bounds = [0.25 * h / (float(sp.c0) + scene.v_max), 0.25 * np.sqrt(h / acc)]
    if nu > 0:
        bounds.append(0.125 * h * h / nu)
    return float(min(bounds))


def check_dt(scene: Scene, dt: float, params: Params | None = None) -> None:
    bound = stable_dt(scene, params)
    if not dt > 0:
        raise ParameterError(f"dt = {dt} out of range; allowed (0, {bound:.4g}] s")
    if dt > bound * (1 + 1e-9):
        raise ParameterError(
            f"dt = {dt:.4g} s exceeds the stability bound {bound:.4g} s "
            "(0.25 h/(c0+|v|max), 0.125 h²/ν, 0.25 √(h/|a|max)); allowed (0, "
            f"{bound:.4g}] s")
