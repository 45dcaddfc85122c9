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

DEM discs use the same kick–drift–kick for translation and rotation (W6, K5):

    v½ = v + ½Δt a,  ω½ = ω + ½Δt α,  x' = x + Δt v½,  θ' = θ + Δt ω½
    forces at (x', θ', v½, ω½): contacts (shear increment V_s(v½)Δt), walls, bonds,
    gravity, external loads, then local damping with sign(v½), sign(ω½)
    v' = v½ + ½Δt a',  ω' = ω½ + ½Δt α'

which is the central-difference scheme of PFC/K (velocities at half steps) written with
whole-step velocities. Clamped discs keep v = ω = 0.
"""
from __future__ import annotations

import functools

import math
from typing import Callable

import jax
import jax.numpy as jnp
import numpy as np

from . import bonds as bonds_mod
from . import dem, fpi, fsi, kernels, neighbors, sph
from .params import ParameterError, Params
from .scene import Physics, Scene
from .state import (BondState, BoundaryState, FluidState, FpiState, FsiState, SolidState, State,
                    Status, WallState)


def dtype(phys: Physics):
    """Floating-point type of the compiled step."""
    return jnp.float64 if phys.x64 else jnp.float32


def _cat(*parts):
    """Concatenate the per-family arrays that are present (None: family absent)."""
    parts = [p for p in parts if p is not None]
    return parts[0] if len(parts) == 1 else jnp.concatenate(parts)


def sph_positions(state: State):
    """Positions of the SPH family in list order: fluid, boundary, structure, grains."""
    b, f, g = state.boundary, state.fsi, state.fpi
    return _cat(state.fluid.x, None if b is None else b.x,
                None if f is None else state.solid.x[f.idx],
                None if g is None else state.solid.x[g.idx])


# --- forces ------------------------------------------------------------------------------
def fluid_update(phys: Physics, params: Params, x, v, rho, h, mass, boundary, nbrs, dt,
                 structure=None, grains=None):
    """One SPH evaluation at positions ``x`` and velocities ``v`` (v½ in a step):
    returns (ρ', h', a', δv_XSPH, boundary, fsi, fpi) with ρ' = ρ + dt Dρ/Dt (dt = 0: no
    drift).

    ``structure`` = (x_S, v_S, a_S, FsiState) puts the structure discs into the sums (fsi.py);
    the returned FsiState then carries the fluid's force on them (and, for the pressure
    approximation, their new P_S and ρ_S).

    ``grains`` = (x_p, v_p, R_p, FpiState) couples the grains (fpi.py). The conserved density is
    then ερ (W42): continuity advances ε_old ρ, the voidage ε at the new positions turns it
    back into the intrinsic ρ that the EOS, the viscosity and the walls see, the pressure
    bracket carries ε (``sph.voidage_bracket``), and the grains' drag and buoyancy go back
    to the fluid by kernel weights (W47–W48). The returned FpiState carries the new ε and
    the force on each grain. Without grains none of this is traced."""
    sp, kern, nf = params.sph, kernels.get(phys.kernel), phys.n_fluid
    g = jnp.asarray(params.gravity)
    b = boundary
    nb = 0 if b is None else b.x.shape[0]
    xs_, vs_, as_, fs = structure if structure is not None else (None, None, None, None)
    xp_, vp_, rp_, fp = grains if grains is not None else (None, None, None, None)
    n_sph = nf + nb + (0 if fs is None else fs.idx.shape[0])
    idx = nbrs.idx
    if fp is not None:
        idx, idx_g = jnp.minimum(idx[:n_sph], n_sph), idx[n_sph:]  # grains leave the sums
        rho_c = fp.eps * rho
        vol_p = jnp.pi * rp_ * rp_        # V_p per unit thickness, like the disc's mass
    else:
        rho_c = rho
    opt = lambda blk, k: None if blk is None else getattr(blk, k)
    all_x = _cat(x, opt(b, "x"), xs_)
    all_v = _cat(v, None if b is None else jnp.zeros_like(b.x), vs_)
    all_h = _cat(h, opt(b, "h"), opt(fs, "h"))
    all_m = _cat(mass, opt(b, "mass"), opt(fs, "mass"))
    pr = sph.pairs(kern, nf, all_x, all_v, all_h, all_m,
                   _cat(rho_c, opt(b, "rho"), opt(fs, "rho")), idx[:nf])
    if fp is None:
        drho = sph.density_rate(phys, sp, rho_c, pr)
    else:
        drho = sph.density_rate(phys, sp, rho_c, pr, fp.eps,
                                _cat(rho, opt(b, "rho"), opt(fs, "rho")))
    rho_c_new = rho_c + dt * drho
    if phys.variable_h:
        with jax.named_scope("sph.variable_h"):
            h_new = h + dt * sph.smoothing_length_rate(h, rho_c, drho)
    else:
        h_new = h
    if fp is not None:
        with jax.named_scope("fpi.voidage"):
            rows = fpi.grain_rows(kern, x, h, mass / rho_c_new, xp_, idx_g, nf)
            eps_raw = fpi.fluid_voidage(rows.w, vol_p, rows.idx, rows.valid, nf,
                                        phys.voidage)
            eps = jnp.maximum(eps_raw, phys.eps_floor)
        rho_new = rho_c_new / eps
    else:
        rho_new = rho_c_new
    with jax.named_scope("sph.eos"):
        p_new = sph.eos_pressure(rho_new, sp.rho0, sp.c0, sp.gamma)
    if b is not None and phys.boundary_pressure == "extrapolated":
        with jax.named_scope("boundary.extrapolated"):
            pb, rhob = sph.extrapolated_boundary_pressure(
                nf, kern, sp, g, all_x, all_h, _cat(rho_new, b.rho, opt(fs, "rho")),
                _cat(p_new, b.p, opt(fs, "p")), idx[nf:nf + nb])
        b = b.replace(p=pb, rho=rhob)
    if fs is not None and phys.fsi == "extrapolated":
        with jax.named_scope("fsi.extrapolated"):
            ps, rhos = sph.extrapolated_boundary_pressure(
                nf, kern, sp, g, all_x, all_h, _cat(rho_new, opt(b, "rho"), fs.rho),
                _cat(p_new, opt(b, "p"), fs.p), idx[nf + nb:n_sph], acc_b=as_,
                first=nf + nb)
        fs = fs.replace(p=ps, rho=rhos)
    if fs is not None and phys.fsi == "pressure_approximation":
        with jax.named_scope("fsi.pressure_approximation"):
            ps, rhos = fsi.approximate_pressure(
                kern, nf, all_x, all_h, _cat(rho_new, opt(b, "rho"), fs.rho),
                _cat(p_new, opt(b, "p"), fs.p), all_m, idx[nf + nb:n_sph], sp)
        fs = fs.replace(p=ps, rho=rhos)
    rho_all = _cat(rho_new, opt(b, "rho"), opt(fs, "rho"))
    acc, xs, pair = sph.momentum_rate(
        phys, kern, sp, g, rho_all, _cat(p_new, opt(b, "p"), opt(fs, "p")), pr,
        with_pairs=fs is not None,
        eps=None if fp is None else _cat(eps, None if b is None else jnp.ones_like(b.rho),
                                         None if fs is None else jnp.ones_like(fs.rho)))
    if fs is not None:
        with jax.named_scope("fsi.reaction"):
            fs = fs.replace(force=fsi.reaction(pair, mass, pr.idx, nf + nb, phys.n_structure))
    if fp is not None:
        with jax.named_scope("fpi.drag"):
            eps_p, u_f, wet, drag = fpi.grain_drag(rows, eps_raw, v, vp_, vol_p, 2.0 * rp_, sp.rho0,
                                                   sp.mu, phys.voidage)
        with jax.named_scope("fpi.buoyancy"):
            if phys.fpi_pressure == "archimedes":
                lift = -(sp.rho0 * vol_p)[:, None] * g[None, :]
            else:
                lift = fpi.pressure_force(rows, p_new, vol_p)
            force = drag + jnp.where((wet > 0)[:, None], lift, 0.0)
        with jax.named_scope("fpi.reaction"):
            wall = None if b is None else fpi.wall_share(kern, b.x, b.h, b.mass / b.rho, xp_,
                                                         idx_g, nf)
            acc = acc + fpi.reaction_acceleration(rows, force, mass, wall)
        fp = fp.replace(eps=eps, eps_p=eps_p, u_f=u_f, wet=wet, force=force)
    return rho_new, h_new, acc, xs, b, fs, fp


# --- DEM forces ---------------------------------------------------------------------------
def solid_update(phys: Physics, params: Params, solid: SolidState, x, v, omega, theta, shear,
                 idx, walls: WallState | None, bonds: BondState | None, t, dt, f_fluid=None,
                 wet=None):
    """All forces on the discs at (x, θ, v, ω): returns (a, α, shear history, wall shear
    history, bonds). ``dt`` is the shear-spring increment (0: no increment); ``f_fluid``
    (n, 2) the fluid's force on each disc (held over the DEM sub-steps), or None; ``wet``
    (n,) bool marks the wet grains that lubricate each other (W24), or None."""
    dp = params.dem
    with jax.named_scope("dem.contacts"):
        force, torque, shear, _ = dem.disc_contacts(dp, x, v, omega, solid.radius, solid.mass,
                                                    solid.fixed, idx, shear, dt)
    wall_shear = solid.wall_shear
    if walls is not None:
        with jax.named_scope("dem.walls"):
            fw, tw, wall_shear, _ = dem.wall_contacts(dp, x, v, omega, solid.radius, solid.mass,
                                                      walls.a, walls.b, wall_shear, dt)
        force, torque = force + fw, torque + tw
    if bonds is not None:
        with jax.named_scope("bonds"):
            fb, tb, alive, mode, fn, fs, m = bonds_mod.bond_forces(
                params.bond, phys.bond_section, phys.n_solid, x, theta, solid.radius,
                bonds.i, bonds.j, bonds.d0, bonds.e0, bonds.intact)
            new = bonds.intact & ~alive
            bonds = bonds.replace(intact=alive, fn=fn, fs=fs, m=m,
                                  t_break=jnp.where(new, t, bonds.t_break),
                                  mode=jnp.where(new, mode, bonds.mode))
        force, torque = force + fb, torque + tb
    g = jnp.asarray(params.gravity, x.dtype)
    force = force + solid.mass[:, None] * g + solid.f_ext * dem.load_factor(dp.load_ramp, t)
    if f_fluid is not None:
        force = force + f_fluid
    if wet is not None:
        with jax.named_scope("fpi.lubrication"):
            fp = params.fpi
            force = force + fpi.lubrication_on_discs(x, v, solid.radius, wet, idx, params.sph.mu,
                                                     fp.lub_gap_min, fp.lub_cutoff)
    with jax.named_scope("dem.local_damping"):
        force = dem.local_damping(dp.alpha, force, v)
        torque = dem.local_damping(dp.alpha, torque, omega)
    with jax.named_scope("dem.viscous_damping"):
        force = force + dem.viscous_damping(dp.damping, solid.mass[:, None], v)
        torque = torque + dem.viscous_damping(dp.damping, solid.inertia, omega)
    free = ~solid.fixed
    acc = jnp.where(free[:, None], force / solid.mass[:, None], 0.0)
    alpha = jnp.where(free, torque / solid.inertia, 0.0)
    return acc, alpha, shear, wall_shear, bonds


def _solid_step(phys: Physics, params: Params, s: SolidState, bonds, nbrs_old, walls, t, dt,
                f_fluid=None, wet=None):
    """One DEM kick–drift–kick of length ``dt`` ending at time ``t``."""
    with jax.named_scope("integrate.solid_kick_drift"):
        v_half = s.v + 0.5 * dt * s.acc
        w_half = s.omega + 0.5 * dt * s.alpha
        x_new = s.x + dt * v_half
        th_new = s.theta + dt * w_half
    with jax.named_scope("neighbors.dem_update"):
        nbrs, rebuilt = neighbors.update(phys.dem_neighbors, nbrs_old, x_new)
        shear = jax.lax.cond(rebuilt, dem.remap_history, lambda o, h, n: h,
                             nbrs_old.idx, s.shear, nbrs.idx)
    acc, alpha, shear, wshear, bonds = solid_update(
        phys, params, s, x_new, v_half, w_half, th_new, shear, nbrs.idx, walls, bonds, t, dt,
        f_fluid, wet)
    with jax.named_scope("integrate.solid_kick"):
        solid = s.replace(x=x_new, theta=th_new, v=v_half + 0.5 * dt * acc,
                          omega=w_half + 0.5 * dt * alpha, acc=acc, alpha=alpha, shear=shear,
                          wall_shear=wshear)
    return solid, bonds, nbrs, rebuilt


def structure_particles(phys: Physics, state: State):
    """(x_S, v_S, a_S, FsiState) of the structure discs in the SPH sums, or None."""
    if not phys.has_fsi:
        return None
    k = state.fsi.idx
    s = state.solid
    return s.x[k], s.v[k], s.acc[k], state.fsi


def grain_particles(phys: Physics, state: State):
    """(x_p, v_p, R_p, FpiState) of the grains coupled to the fluid, or None."""
    if not phys.has_fpi:
        return None
    k = state.fpi.idx
    return state.solid.x[k], state.solid.v[k], state.solid.radius[k], state.fpi


def fluid_force_on_discs(phys: Physics, state: State):
    """The fluid's force on every disc (n_solid, 2) from the last SPH evaluation (pressure
    and viscosity on structure discs, pressure and drag on grains), or None."""
    if not (phys.has_fsi or phys.has_fpi):
        return None
    f = jnp.zeros_like(state.solid.x)
    if phys.has_fsi:
        f = f.at[state.fsi.idx].add(state.fsi.force)
    if phys.has_fpi:
        f = f.at[state.fpi.idx].add(state.fpi.force)
    return f


def wet_grains(phys: Physics, state: State):
    """(n_solid,) bool: grains with fluid neighbours, which lubricate each other (W24); None
    when the scene has no lubrication."""
    if not (phys.has_fpi and phys.lubrication):
        return None
    return jnp.zeros(state.solid.x.shape[0], bool).at[state.fpi.idx].set(state.fpi.wet > 0)


def _solid_substeps(phys: Physics, state: State, params: Params):
    """``phys.dem_substeps`` DEM steps of Δt/n covering one SPH step (multi-rate stepping),
    the fluid's force on the discs held at its value of the last SPH evaluation.
    Returns (solid, bonds, list, rebuilds, overflow)."""
    n = phys.dem_substeps
    dts = params.dt / n
    f_fluid = fluid_force_on_discs(phys, state)
    wet = wet_grains(phys, state)

    def one(k, carry):
        solid, bonds, nbrs, rebuilds, overflow = carry
        t = state.t + (k + 1) * dts
        solid, bonds, nbrs, rb = _solid_step(phys, params, solid, bonds, nbrs, state.walls,
                                             t, dts, f_fluid, wet)
        return (solid, bonds, nbrs, rebuilds + rb.astype(jnp.int32),
                overflow | nbrs.did_buffer_overflow.astype(bool))

    carry = (state.solid, state.bonds, state.solid_nbrs, jnp.zeros((), jnp.int32),
             jnp.zeros((), bool))
    if n == 1:
        return one(0, carry)
    with jax.named_scope("integrate.dem_substeps"):
        return jax.lax.fori_loop(0, n, one, carry)


# --- health ------------------------------------------------------------------------------
def _box(phys: Physics, dtype_):
    nb = phys.neighbors or phys.dem_neighbors
    lo = jnp.asarray(nb.origin, dtype_)
    return lo, lo + jnp.asarray(nb.box, dtype_)


def _first(status: Status, code, step) -> Status:
    bad_now = jnp.any(code > 0)
    i = jnp.argmax(code > 0).astype(jnp.int32)
    first = bad_now & ~status.bad
    return status.replace(
        bad=status.bad | bad_now,
        step=jnp.where(first, step, status.step),
        particle=jnp.where(first, i, status.particle),
        code=jnp.where(first, code[i].astype(jnp.int32), status.code))


def _check(phys: Physics, params: Params, fluid: FluidState, step, status: Status) -> Status:
    """Per-particle health codes of the fluid (see state.STATUS_CODES); remember the first."""
    lo, hi = _box(phys, fluid.x.dtype)
    rho0 = params.sph.rho0
    code = jnp.where(~jnp.all(jnp.isfinite(fluid.x), axis=1), 1,
           jnp.where(~jnp.all(jnp.isfinite(fluid.v), axis=1), 2,
           jnp.where(~jnp.isfinite(fluid.rho), 3,
           jnp.where(jnp.abs(fluid.rho / rho0 - 1.0) > phys.rho_tolerance, 4,
           jnp.where(jnp.any((fluid.x < lo) | (fluid.x >= hi), axis=1), 5, 0)))))
    return _first(status, code, step)


def _check_solid(phys: Physics, solid: SolidState, step, status: Status) -> Status:
    """Health codes 6–8 of the discs (the particle index is the disc's)."""
    lo, hi = _box(phys, solid.x.dtype)
    code = jnp.where(~jnp.all(jnp.isfinite(solid.x), axis=1), 6,
           jnp.where(~(jnp.all(jnp.isfinite(solid.v), axis=1) & jnp.isfinite(solid.omega)), 7,
           jnp.where(jnp.any((solid.x < lo) | (solid.x >= hi), axis=1), 8, 0)))
    return _first(status, code, step)


# --- the step ----------------------------------------------------------------------------
def _fluid_step(phys: Physics, state: State, params: Params):
    """The SPH leapfrog step; with a coupling, the structure discs enter at their positions
    and velocities in ``state`` (already advanced to the end of the step)."""
    dt = params.dt
    f = state.fluid
    with jax.named_scope("integrate.kick_drift"):
        v_half = f.v + 0.5 * dt * f.acc
        x_new = f.x + dt * (v_half + f.xsph)
    structure = structure_particles(phys, state)
    grains = grain_particles(phys, state)
    with jax.named_scope("neighbors.update"):
        all_x = _cat(x_new, None if state.boundary is None else state.boundary.x,
                     None if structure is None else structure[0],
                     None if grains is None else grains[0])
        nbrs, rebuilt = neighbors.update(phys.neighbors, state.nbrs, all_x)
    rho, h, acc, xs, b, fs, fp = fluid_update(phys, params, x_new, v_half, f.rho, f.h, f.mass,
                                              state.boundary, nbrs, dt, structure, grains)
    with jax.named_scope("integrate.kick"):
        fluid = f.replace(x=x_new, v=v_half + 0.5 * dt * acc, rho=rho, h=h, acc=acc, xsph=xs)
    return fluid, b, nbrs, rebuilt, fs, fp


def step(phys: Physics, state: State, params: Params) -> State:
    """Advance one time step (see the module docstring). Pure: (State, Params) → State.
    Only the phases the scene has are traced: a DEM-only scene compiles no SPH and a
    fluid-only scene no DEM.

    With both phases the discs go first, in ``phys.dem_substeps`` sub-steps under the fluid
    force of the last SPH evaluation; the fluid then steps against the discs at the end of
    the step and returns the new force (a staggered, force-holding multi-rate scheme).
    Impulse multiple time stepping (r-RESPA: half kicks by the fluid force around the DEM
    sub-steps) was tried in issue 5 and rejected: its impulses on the bonded structures
    excite their fast modes (the elastic gate's peak went from 39 to 60 mm at the quick
    resolution, the plate sagged 13 % less)."""
    n = state.step + 1
    t = n * params.dt
    st = state.status
    new = state.replace(t=t, step=n)
    if phys.has_solid:
        solid, bonds, snbrs, rebuilt, overflow = _solid_substeps(phys, state, params)
        st = st.replace(overflow=st.overflow | overflow, rebuilds=st.rebuilds + rebuilt)
        st = _check_solid(phys, solid, n, st)
        new = new.replace(solid=solid, bonds=bonds, solid_nbrs=snbrs)
    if phys.has_fluid:
        fluid, b, nbrs, rebuilt, fs, fp = _fluid_step(phys, new, params)
        st = st.replace(overflow=st.overflow | nbrs.did_buffer_overflow.astype(bool),
                        h_exceeded=st.h_exceeded
                        | (jnp.max(fluid.h) * 2.0 > phys.neighbors.r_cut),
                        rebuilds=st.rebuilds + rebuilt.astype(jnp.int32))
        st = _check(phys, params, fluid, n, st)
        new = new.replace(fluid=fluid, boundary=b, nbrs=nbrs, fsi=fs, fpi=fp)
    # the first step that is not exact: an overflowed list dropped pairs of this step; an
    # h past the cut-off (the new h) would drop pairs of the next one
    st = st.replace(redo_step=jnp.where((st.redo_step < 0) & (st.overflow | st.h_exceeded),
                                        jnp.where(st.overflow, n, n + 1), st.redo_step))
    return new.replace(status=st)


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


def advance(phys: Physics, state: State, params: Params, n, n_max: int,
            observe: Callable[[State], object] | None = None):
    """Take ``n`` ≤ ``n_max`` steps, ``n`` a traced integer: one compiled program serves
    every chunk length up to ``n_max``, so the host driver's last, shorter chunk does not
    compile a second program (2–5 s for a coupled scene). Observations fill the first ``n``
    rows of an ``n_max``-row buffer (the rest stay zero). A while loop underneath: not
    reverse-differentiable, use :func:`rollout` for gradients."""
    buf = None if observe is None else jax.tree_util.tree_map(
        lambda a: jnp.zeros((n_max,) + a.shape, a.dtype), jax.eval_shape(observe, state))

    def body(i, carry):
        s, b = carry
        s = step(phys, s, params)
        if observe is not None:
            b = jax.tree_util.tree_map(
                lambda bb, o: jax.lax.dynamic_update_index_in_dim(bb, o, i, 0), b, observe(s))
        return s, b

    return jax.lax.fori_loop(0, n, body, (state, buf))


# --- initial state -----------------------------------------------------------------------
def init_state(scene: Scene, phys: Physics, params: Params) -> State:
    """Arrays on device, neighbour lists allocated, initial rates evaluated."""
    dt_ = dtype(phys)
    a = lambda v: jnp.asarray(v, dtype=dt_)
    z = jnp.zeros_like
    fluid = boundary = nbrs = solid = bonds = walls = snbrs = fsi_state = fpi_state = None
    if scene.fluid is not None:
        fl = scene.fluid
        b = scene.boundary
        boundary = None if b is None else BoundaryState(
            x=a(b.x), rho=a(b.rho), p=a(b.p), h=a(b.h), mass=a(b.mass))
        x = a(fl.x)
        fluid = FluidState(x=x, v=a(fl.v), rho=a(fl.rho), h=a(fl.h), mass=a(fl.mass),
                           acc=z(x), xsph=z(x))
        if phys.has_fsi:
            k = scene.solid.structure_indices()
            rho0 = float(scene.params.sph.rho0)
            ns = k.size
            fsi_state = FsiState(
                idx=jnp.asarray(k, jnp.int32), mass=a(rho0 * scene.solid.volumes()[k]),
                h=a(np.full(ns, float(np.max(fl.h)))), rho=a(np.full(ns, rho0)),
                p=a(np.zeros(ns)), force=a(np.zeros((ns, 2))))
        if phys.has_fpi:
            k = scene.solid.grain_indices()
            ng = k.size
            fpi_state = FpiState(
                idx=jnp.asarray(k, jnp.int32), eps=a(np.ones(fl.n)), eps_p=a(np.ones(ng)), u_f=a(np.zeros((ng, 2))),
                wet=a(np.zeros(ng)), force=a(np.zeros((ng, 2))))
    if scene.solid is not None:
        so = scene.solid
        x = a(so.x)
        fixed = jnp.asarray(so.fixed, bool)
        snbrs = neighbors.allocate(phys.dem_neighbors, x)
        n_w = scene.walls.n if scene.walls is not None else 0
        solid = SolidState(
            x=x, v=a(so.v), omega=jnp.where(fixed, 0.0, a(so.omega)),
            theta=a(np.zeros(so.n)), acc=z(x), alpha=a(np.zeros(so.n)), radius=a(so.radius),
            mass=a(so.mass), inertia=a(so.inertia), fixed=fixed, f_ext=a(so.f_ext),
            shear=jnp.zeros(snbrs.idx.shape, dt_), wall_shear=jnp.zeros((so.n, n_w), dt_))
        if scene.walls is not None:
            walls = WallState(a=a(scene.walls.a), b=a(scene.walls.b))
        if scene.bonds is not None:
            i = jnp.asarray(scene.bonds.i, jnp.int32)
            j = jnp.asarray(scene.bonds.j, jnp.int32)
            d0, e0 = bonds_mod.rest_geometry(x, i, j)
            nb = scene.bonds.n
            bonds = BondState(i=i, j=j, d0=d0, e0=e0, intact=jnp.ones(nb, bool),
                              fn=jnp.zeros(nb, dt_), fs=jnp.zeros(nb, dt_), m=jnp.zeros(nb, dt_),
                              t_break=jnp.full(nb, -1.0, dt_), mode=jnp.zeros(nb, jnp.int32))
    state = State(t=a(0.0), step=jnp.zeros((), jnp.int32), fluid=fluid, boundary=boundary,
                  nbrs=None, status=Status.ok(), solid=solid, bonds=bonds, solid_nbrs=snbrs,
                  walls=walls, fsi=fsi_state, fpi=fpi_state)
    if fluid is not None:
        state = state.replace(nbrs=neighbors.allocate(phys.neighbors, sph_positions(state)))
    return _initial_rates(phys, state, params)


@functools.partial(jax.jit, static_argnums=0)
def _initial_rates(phys: Physics, state: State, params: Params) -> State:
    """The voidage (with grains) and :func:`refresh_rates` of a fresh state, as one compiled
    program. Run eagerly, the same evaluation dispatched (and compiled) each of its ~1 300
    primitives on its own: 12.6 s of the coarse gate's 17 s set-up."""
    if phys.has_fpi:
        state = state.replace(fpi=state.fpi.replace(eps=initial_voidage(phys, state)))
    return refresh_rates(phys, state, params)


def initial_voidage(phys: Physics, state: State):
    """The fluid voidage at the state's positions (what the first step's ε_old must be). The
    scene's fluid densities are intrinsic ρ; builders give the particles mass ε ρ0 Δx²."""
    f, fp = state.fluid, state.fpi
    n_sph = state.nbrs.idx.shape[0] - fp.idx.shape[0]
    rows = fpi.grain_rows(kernels.get(phys.kernel), f.x, f.h, f.mass / f.rho,
                          state.solid.x[fp.idx], state.nbrs.idx[n_sph:], phys.n_fluid)
    r = state.solid.radius[fp.idx]
    eps = fpi.fluid_voidage(rows.w, jnp.pi * r * r, rows.idx, rows.valid, phys.n_fluid,
                            phys.voidage)
    return jnp.maximum(eps, phys.eps_floor)


def refresh_rates(phys: Physics, state: State, params: Params) -> State:
    """Recompute the stored accelerations (and XSPH correction, and the fluid's force on the
    structure) at the current state (after init or a reallocation); positions, densities, h
    and histories are left as they are."""
    if phys.has_fluid:
        f = state.fluid
        _, _, acc, xs, b, fs, fp = fluid_update(phys, params, f.x, f.v, f.rho, f.h, f.mass,
                                                state.boundary, state.nbrs, 0.0,
                                                structure_particles(phys, state),
                                                grain_particles(phys, state))
        state = state.replace(fluid=f.replace(acc=acc, xsph=xs), boundary=b, fsi=fs, fpi=fp)
    if phys.has_solid:
        s = state.solid
        acc, alpha, _, _, _ = solid_update(phys, params, s, s.x, s.v, s.omega, s.theta, s.shear,
                                           state.solid_nbrs.idx, state.walls, state.bonds,
                                           state.t, 0.0, fluid_force_on_discs(phys, state),
                                           wet_grains(phys, state))
        state = state.replace(solid=s.replace(acc=acc, alpha=alpha))
    return state


# --- time step ---------------------------------------------------------------------------
def _grains(scene: Scene):
    """Indices of the grains coupled to the fluid (empty without option fpi)."""
    if not (scene.options.get("fpi") and scene.fluid is not None and scene.solid is not None):
        return np.zeros(0, int)
    return scene.solid.grain_indices()


# Step coefficients (issue 7). physics.md quotes 0.25 h/(c0+|v|) and 0.2 √(m/k); the sweeps
# of experiments/stability.py found those 5–6.5× below the step where the runs actually blow
# up (leapfrog's acoustic limit is ≈ 1.4–1.7 h/c0 here; a bonded or packed DEM assembly
# ≈ 1.0 √(m/k)), so they were needlessly small. The coefficients below keep a measured
# margin of 1.8–1.9 on every swept fluid-only or DEM-only case (a single contact: 2.9); the
# force and viscous bounds are physics.md's.
#
# Except in a structure coupled to the fluid (option fsi), which keeps physics.md's 0.25 and
# 0.2: there the step is sized for accuracy, not stability. The staggered coupling holds
# the fluid force over the DEM sub-steps of one SPH step, and its error grows with both
# steps. The coarse elastic gate (38.94 mm peak; half of both steps 38.89) gave 43.4 mm
# (+12 %) with both at the new coefficients, 39.6 (+1.8 %) with SPH 0.875 and DEM 0.2,
# 38.6 with SPH 0.5 and DEM 0.2 (experiments/gate_coupling_steps.py; chunk length alone
# moves the peak by up to 0.5 %). But at the seed resolution SPH 0.6 and DEM 0.2 lifted
# the peak from 39.4 to 40.9 mm (+3.9 %, against the 1 % multi-rate target of issue 4).
# The DEM sub-step at 0.55 is within 2 % while the SPH step stays at 0.25, and +12–14 %
# with an SPH step of 0.5 or 0.875. The coupled fluid is also less stable: the coarse gate
# blew up at 1.31 × the 0.875 step and at 5.25 × the 0.25 one.
SPH_CFL = 0.875
FSI_SPH_CFL = 0.25
DEM_DT_FACTOR = 0.55
FSI_DEM_DT_FACTOR = 0.2


def sph_dt(scene: Scene, params: Params, a_max: float | None = None) -> float:
    """SPH bound (physics.md §Time integration, with the acoustic coefficient SPH_CFL, or
    FSI_SPH_CFL with option fsi, instead of 0.25): Δt ≤ min(CFL h/(c0 + |v|max),
    0.125 h²/ν, 0.25 √(h/|a|max), r0/(c0 √β) with the wall backstop), h the smallest
    smoothing length, |v|max the scene's velocity scale and |a|max = max(|g|, a_max).

    With grains in the fluid (fpi) the sound speed in ερ is c0/√ε, so c0/√ε_lo replaces c0,
    ε_lo = max(EPS_MIN, 1 − n_grain V_p,max W(0)) the least voidage the grains can make (3D
    mapped for Physics.voidage 'mapped'; Physics.eps_floor does not relax it: with the bed's
    fluid floored at 0.5 the step for c0/√0.5 went unstable at 0.022 s, the step for the
    unfloored 0.26 ran); and
    the drag, held over a step, must not relax the slip faster than the step: Δt ≤ 0.5 τ,
    τ = ρ_p/(β/(1−ε)) with Ergun's β at the densest sphere packing (ε 0.26) and slip
    |v|max."""
    sp = params.sph
    h = float(np.min(scene.fluid.h))
    nu = float(sp.mu) / float(sp.rho0)
    g = float(np.linalg.norm(np.asarray(params.gravity, float)))
    acc = max(g, a_max or 0.0, 1e-12)
    c = float(sp.c0)
    grains = _grains(scene)
    bounds = []
    if grains.size:
        r = np.asarray(scene.solid.radius, float)[grains]
        w0 = float(kernels.get(scene.options.get("kernel", "wendland")).w(0.0, h))
        e_lo = max(fpi.EPS_MIN, 1.0 - grains.size * np.pi * r.max() ** 2 * w0)
        if scene.options.get("voidage", "area") == "mapped":
            e_lo = float(fpi.voidage_3d(e_lo))
        c = c / math.sqrt(e_lo)
        e = float(fpi.voidage_3d(fpi.EPS_MIN))
        d = 2.0 * r
        rho_p = (np.asarray(scene.solid.mass, float)[grains]
                 / (np.pi * np.asarray(scene.solid.radius, float)[grains] ** 2))
        rate = (150.0 * (1 - e) * float(sp.mu) / (e * d * d)
                + 1.75 * float(sp.rho0) * scene.v_max / d) / rho_p
        bounds.append(0.5 / float(np.max(rate)))
    cfl = FSI_SPH_CFL if scene.fsi_coupled else SPH_CFL
    bounds += [cfl * h / (c + scene.v_max), 0.25 * np.sqrt(h / acc)]
    beta, r0 = float(sp.wall_beta), scene.wall_range()
    if r0 > 0 and scene.options.get("wall_repulsion", Physics.wall_repulsion) and beta > 0:
        # the wall backstop's stiffness is at most β c0²/r0² (sph.wall_repulsion_scalar);
        # leapfrog needs Δt < 2 r0/(c0 √β), kept with a factor 2 of margin
        bounds.append(r0 / (c * math.sqrt(beta)))
    if nu > 0:
        bounds.append(0.125 * h * h / nu)
    return float(min(bounds))


def dem_dt(scene: Scene, params: Params, section: str = "slab") -> float:
    """DEM bound (physics.md §Time integration, with DEM_DT_FACTOR, or FSI_DEM_DT_FACTOR =
    0.2 with option fsi, instead of 0.2): Δt ≤ factor √(m_min/k_max), and the same for
    rotation, factor √(J_min/k_rot). k_max adds the contact spring and the stiffest bond
    (k̄ A); k_rot = k̄_n I + (k̄_s A + k_s) R_max² for the stiffest bond."""
    so, dp, bp = scene.solid, params.dem, params.bond
    free = ~np.asarray(so.fixed, bool)
    if not free.any():
        free = np.ones(so.n, bool)
    m = float(np.min(so.mass[free]))
    J = float(np.min(so.inertia[free]))
    r = float(np.max(so.radius))
    kn, ks = float(dp.kn), float(dp.ks)
    k_rot = ks * r * r
    if scene.bonds is not None and bp is not None:
        A, I = map(float, bonds_mod.section(section, float(bp.lam) * r, float(bp.thickness)))
        kn += float(bp.kn) * A
        ks += float(bp.ks) * A
        k_rot = float(bp.kn) * I + ks * r * r
    k = max(kn, ks)
    bound = np.sqrt(m / k)
    if k_rot > 0:
        bound = min(bound, np.sqrt(J / k_rot))
    bound = (FSI_DEM_DT_FACTOR if scene.fsi_coupled else DEM_DT_FACTOR) * bound
    c = float(getattr(dp, "damping", 0.0))
    if c > 0:                      # the lagged viscous term is stable for c·Δt < 2; keep ≤ 0.5
        bound = min(bound, 0.5 / c)
    return float(bound)


def stable_dt(scene: Scene, params: Params | None = None, a_max: float | None = None,
              section: str | None = None, substeps: int = 1) -> float:
    """Largest time step allowed by the explicit bounds of the phases the scene has; with
    ``substeps`` DEM sub-steps per step the DEM bound counts ``substeps`` times."""
    p = params or scene.params
    bounds = []
    if scene.fluid is not None:
        bounds.append(sph_dt(scene, p, a_max))
    if scene.solid is not None:
        sec = section or scene.options.get("bond_section", "slab")
        bounds.append(substeps * dem_dt(scene, p, sec))
    return float(min(bounds))


def substeps_for(scene: Scene, dt: float, params: Params | None = None) -> int:
    """Fewest DEM sub-steps that keep dt/n under the DEM bound (1 without both phases)."""
    if scene.fluid is None or scene.solid is None:
        return 1
    p = params or scene.params
    bound = dem_dt(scene, p, scene.options.get("bond_section", "slab"))
    return max(1, int(math.ceil(dt / bound * (1.0 - 1e-12))))


def check_dt(scene: Scene, dt: float, params: Params | None = None, substeps: int = 1,
             auto_substeps: bool = False) -> None:
    """Refuse a step outside (0, bound]. With ``auto_substeps`` (fluid and discs, the
    sub-step count chosen from dt) the DEM bound never limits dt, so a step that is not
    positive is told the SPH bound, the largest step it may ask for."""
    if not dt > 0 and auto_substeps and scene.fluid is not None and scene.solid is not None:
        raise ParameterError(f"dt = {dt} out of range; allowed "
                             f"(0, {sph_dt(scene, params or scene.params):.4g}] s (the DEM "
                             "sub-steps are chosen from dt)")
    bound = stable_dt(scene, params, substeps=substeps)
    if not dt > 0:
        raise ParameterError(f"dt = {dt} out of range; allowed (0, {bound:.4g}] s")
    if dt > bound * (1 + 1e-9):
        sub = f" with dem_substeps = {substeps}" if substeps > 1 else ""
        raise ParameterError(
            f"dt = {dt:.4g} s exceeds the stability bound {bound:.4g} s{sub} "
            f"(SPH: {SPH_CFL:g} h/(c0+|v|max), {FSI_SPH_CFL:g} with fsi, 0.125 h²/ν, "
            "0.25 √(h/|a|max), r0/(c0 √β) for the wall backstop; "
            f"DEM: {DEM_DT_FACTOR:g} √(m/k), {FSI_DEM_DT_FACTOR:g} √(m/k) coupled to "
            "the fluid, per "
            f"sub-step); allowed (0, {bound:.4g}] s")
