"""The stages of a step, each ``(physics, params, state) -> state``.

:func:`fpsi_jax.solver.forward.step` chains them; this module composes the physics modules
(``fpsi_jax.physics``), which never call each other. Integration is leapfrog (velocity
Verlet, W6/K5) with one neighbour pass per step, the density treated like a position (it is
drifted with the velocity at the half step):

    v½ = v + ½Δt a
    x' = x + Δt (v½ + δv_XSPH)
    Dρ/Dt at (x', v½)                       (continuity, δ-SPH)
    ρ' = ρ + Δt Dρ/Dt,  h' = h + Δt Dh/Dt,  P' = P(ρ')
    a' at (x', ρ', P', v½)                  (pressure, anti-clump, viscosity, gravity)
    v' = v½ + ½Δt a'

For the acoustic mode this is the symplectic leapfrog, stable up to ωΔt = 2 (kicking ρ by
half steps with a stored rate, like v, is unconditionally unstable: see
tests/solver/test_forward.py::test_density_update_is_stable_for_acoustic_oscillator). Both
passes use the pair geometry of the start of the step (each builds it where it sums it:
:func:`pair_pass`); the kernel uses h of the start of the step. The XSPH correction δv_XSPH used in a drift is the
one of the previous step; it smooths the transport velocity, so the O(Δt) lag is harmless.

DEM discs use the same kick–drift–kick for translation and rotation (W6, K5):

    v½ = v + ½Δt a,  ω½ = ω + ½Δt α,  x' = x + Δt v½,  θ' = θ + Δt ω½
    forces at (x', θ', v½, ω½): contacts (shear increment V_s(v½)Δt), walls, bonds,
    gravity, external loads, then local damping with sign(v½), sign(ω½)
    v' = v½ + ½Δt a',  ω' = ω½ + ½Δt α'

which is the central-difference scheme of PFC/K (velocities at half steps) written with
whole-step velocities. Clamped discs keep v = ω = 0.

With fluid and discs together the step is multi-rate and staggered: the discs take
``physics.dem_substeps`` sub-steps under the fluid force of the last SPH evaluation (held
over the sub-steps), then the fluid steps against the discs at the end of the step and
returns the new force (docs/design.md says why impulse splitting was rejected).
"""
from __future__ import annotations

import functools
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from ..model import motion
from ..model.config import Physics
from ..model.options import BoundaryPressure, FpiPressure, FsiMethod
from ..model.params import Params
from ..model.state import State
from ..physics import bonds as bonds_law
from ..physics import boundary, dem, eos, fpi, fsi, kernels, sph
from ..physics.pairs import (gather, over_row_blocks, pair_table, pairs_at, pairs_of, rows_of,
                             take_rows)
from . import exits, health, neighbors


def dtype(phys: Physics):
    """Floating-point type of the compiled step."""
    return jnp.float64 if phys.x64 else jnp.float32


def _cat(*parts):
    """Concatenate the per-family arrays that are present (None: family absent)."""
    parts = [p for p in parts if p is not None]
    return parts[0] if len(parts) == 1 else jnp.concatenate(parts)


def _opt(block, name):
    return None if block is None else getattr(block, name)


def sph_positions(state: State):
    """Positions of the SPH family in list order: fluid, boundary, structure, grains."""
    b, f, g = state.boundary, state.fsi, state.fpi
    return _cat(state.fluid.x, _opt(b, "x"),
                None if f is None else state.solid.x[f.idx],
                None if g is None else state.solid.x[g.idx])


# --- clock ---------------------------------------------------------------------------------
def clock(phys: Physics, params: Params, state: State) -> State:
    """Advance the step counter and the time to the end of the step."""
    n = state.step + 1
    return state.replace(step=n, t=n * params.dt)


# --- DEM -------------------------------------------------------------------------------------
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
    """((n_solid,) bool: grains with fluid neighbours, which lubricate each other (W24);
    (n_grain,) the grains' disc indices, the only rows lubrication can act on), or None
    when the scene has no lubrication."""
    if not (phys.has_fpi and phys.lubrication):
        return None
    mask = jnp.zeros(state.solid.x.shape[0], bool).at[state.fpi.idx].set(state.fpi.wet > 0)
    return mask, state.fpi.idx


def grain_added_mass(phys: Physics, state: State):
    """(n_solid,) each grain's added mass of the last SPH evaluation on its disc row
    (FpiState.m_a; 0 elsewhere), or None when Physics.added_mass is off."""
    if not (phys.has_fpi and phys.added_mass):
        return None
    fp, s = state.fpi, state.solid
    return jnp.zeros_like(s.mass).at[fp.idx].set(fp.m_a)


def _moving_rows(phys: Physics):
    """The rows the contact and wall sums run over (Physics.moving_discs), or None: all."""
    return jnp.asarray(phys.moving_discs, jnp.int32) if phys.moving_discs else None


def wall_capacity(phys: Physics) -> int:
    """Room for the discs near a wall (WallState.near): a quarter of the free discs, at
    least 16, in multiples of 8 (granular scenes put one layer of grains on their floor;
    when more discs than this are near, the sub-steps evaluate every disc)."""
    n = len(phys.moving_discs) if phys.moving_discs else phys.n_solid
    return int(min(phys.n_solid, 8 * -(-max(16, n // 4) // 8)))


def walls_near(phys: Physics, solid, walls, x):
    """(the discs that may touch a wall while the DEM list built at ``x`` holds, every
    disc within skin/2 of its build position, as (c,) rows padded with n_solid: c =
    ``walls.near``'s length or :func:`wall_capacity`; how many there are). A clamped or
    kinematic disc (its force is never read) counts as apart (:func:`dem.walls_near`)."""
    n = x.shape[0]
    c = wall_capacity(phys) if walls.near is None else walls.near.shape[0]
    held = solid.fixed
    if phys.moving_discs:                   # the kinematic discs: a constant of the scene
        kinematic = np.ones(n, bool)
        kinematic[list(phys.moving_discs)] = False
        held = held | kinematic
    near = dem.walls_near(x, solid.radius, walls.a, walls.b, walls.side,
                          0.5 * phys.dem_neighbors.skin, held)
    rows = jnp.nonzero(near, size=c, fill_value=n)[0].astype(jnp.int32)
    return rows, jnp.sum(near, dtype=jnp.int32)


def with_walls_near(phys: Physics, state: State) -> State:
    """``state`` with ``walls.near`` for a DEM list built at the current positions (after
    an allocation)."""
    if state.walls is None:
        return state
    rows, count = walls_near(phys, state.solid, state.walls, state.solid.x)
    return state.replace(walls=state.walls.replace(near=rows, n_near=count))


def _wall_forces(dp, own, s, walls, dt, reaction=False):
    """The walls' force (n, 2), torque (n,) and new history (n, W) on every disc, from the
    discs ``walls.near`` lists (zeros elsewhere: a history of 0 is what the contact law
    leaves on pairs apart), from none while it lists none, and from the rows ``own``
    picks while more discs are near than it has room for (or without ``walls.near``).
    ``reaction``: also the discs' force and moment on each wall, (W, 3)
    (:func:`dem.wall_contacts`)."""
    n = s.x.shape[0]
    zero = (jnp.zeros_like(s.x), jnp.zeros_like(s.omega), jnp.zeros_like(s.wall_shear))
    if reaction:
        zero = zero + (jnp.zeros((walls.a.shape[0], 3), s.x.dtype),)

    def contacts(pick, counted):
        out = dem.wall_contacts(dp, pick(s.x), pick(s.v), pick(s.omega), pick(s.radius),
                                pick(s.mass), walls.a, walls.b, pick(s.wall_shear), dt,
                                walls.side, counted if reaction else None)
        return out[:3] + out[4:]

    def every():
        rows = own(jnp.arange(n, dtype=jnp.int32))
        out = contacts(own, jnp.ones(rows.shape, bool))
        return tuple(z.at[rows].set(v) for z, v in zip(zero[:3], out[:3])) + out[3:]

    if walls.near is None:
        return every()

    def near():
        rows = walls.near                           # padded with n: dropped on the way back
        pick = functools.partial(take_rows, rows=jnp.minimum(rows, n - 1))
        out = contacts(pick, rows < n)
        return (tuple(z.at[rows].set(v, mode="drop") for z, v in zip(zero[:3], out[:3]))
                + out[3:])

    branch = jnp.where(walls.n_near == 0, 0, jnp.where(walls.n_near <= walls.near.shape[0],
                                                       1, 2))
    return jax.lax.switch(branch, [lambda: zero, near, every])


def held_reaction(dp, s, idx, shear, rows, dt, f_bond=None, t_bond=None):
    """The other discs' force on the held (clamped or kinematic) discs ``rows`` (r,): their
    contacts with the free discs over the DEM list's rows ``idx`` (r, K), pairs of two held
    discs left out (neither moves under its force), plus their bonds' force ``f_bond``
    (n, 2) and torque ``t_bond`` (n,) when given. Returns ((r, 3): F_x, F_y and the moment
    about the origin, x × F + τ; the rows' new contact history (r, K)).

    A held disc's row of the contact law is the free disc's reversed: the same overlap,
    reduced mass (the free disc's) and shear history, so Σ over the held discs is minus the
    free discs' contact force from them (tests/solver/test_stages.py)."""
    n = s.x.shape[0]
    free = (idx < n) & ~s.fixed[jnp.minimum(idx, n - 1)]
    f, tq, hist, _ = dem.disc_contacts(dp, s.x, s.v, s.omega, s.radius, s.mass, s.fixed,
                                       jnp.where(free, idx, n), shear, dt, rows)
    if f_bond is not None:
        f, tq = f + f_bond[rows], tq + t_bond[rows]
    x = s.x[rows]
    m = x[:, 0] * f[:, 1] - x[:, 1] * f[:, 0] + tq
    return jnp.concatenate([f, m[:, None]], axis=-1), hist


def disc_forces(phys: Physics, params: Params, state: State, dt, f_fluid=None,
                wet=None, m_added=None) -> State:
    """Every force on the discs at the state's (x, θ, v, ω): contacts, walls, bonds (with
    fracture at time state.t), gravity, external loads, the fluid's force ``f_fluid`` (held
    over the sub-steps), lubrication between ``wet`` grains (W24; :func:`wet_grains`),
    local and viscous damping. Stores the accelerations, the contact histories and the bond
    state; with Physics.wall_reaction, the discs' force on each wall at these positions in
    ``walls.reaction``. ``dt`` is the shear-spring increment (0: none). ``m_added``
    (n_solid,): the grains' added mass (:func:`grain_added_mass`), which joins their
    translational inertia."""
    dp, s, b = params.dem, state.solid, state.bonds
    x, v, omega = s.x, s.v, s.omega
    # the contact and wall sums run over the rows of the discs that move under their forces
    # (Physics.moving_discs); a kinematic disc's force is never read
    rows = _moving_rows(phys)
    own = functools.partial(take_rows, rows=rows)      # this call's rows of an (n, …) array
    with jax.named_scope("dem.contacts"):
        force, torque, shear, _ = dem.disc_contacts(dp, x, v, omega, s.radius, s.mass, s.fixed,
                                                    own(state.solid_nbrs.idx), own(s.shear),
                                                    dt, rows)
    if rows is not None:
        force = jnp.zeros_like(x).at[rows].set(force)
        torque = jnp.zeros_like(omega).at[rows].set(torque)
        shear = s.shear.at[rows].set(shear)
    wall_shear, walls = s.wall_shear, state.walls
    if state.walls is not None:
        with jax.named_scope("dem.walls"):
            fw, tw, wall_shear, *reaction = _wall_forces(dp, own, s, state.walls, dt,
                                                         phys.wall_reaction)
        force, torque = force + fw, torque + tw
        if reaction:
            walls = state.walls.replace(reaction=reaction[0])
    if wet is not None:
        # on the grains' rows only: a structure disc is never wet
        mask, grains = wet
        with jax.named_scope("fpi.lubrication"):
            fp = params.fpi
            force = force.at[grains].add(fpi.lubrication_on_discs(
                x, v, s.radius, mask, state.solid_nbrs.idx[grains], params.sph.mu,
                fp.lub_gap_min, fp.lub_cutoff, grains))
    if b is not None:
        with jax.named_scope("bonds"):
            fb, tb, alive, mode, fn, fs, m = bonds_law.bond_forces(
                params.bond, phys.bond_section, phys.n_solid, s.u, s.theta, s.radius,
                b.i, b.j, b.d0, b.e0, b.intact)
            new = b.intact & ~alive
            b = b.replace(intact=alive, fn=fn, fs=fs, m=m,
                          t_break=jnp.where(new, state.t, b.t_break),
                          mode=jnp.where(new, mode, b.mode))
        force, torque = force + fb, torque + tb
    reaction = s.reaction
    if phys.disc_reaction:              # what a probe on held discs reads
        held = jnp.asarray(phys.disc_reaction, jnp.int32)
        with jax.named_scope("dem.held_reaction"):
            r, hist = held_reaction(dp, s, state.solid_nbrs.idx[held], s.shear[held], held,
                                    dt, *((fb, tb) if b is not None else ()))
        reaction, shear = jnp.zeros_like(reaction).at[held].set(r), shear.at[held].set(hist)
    g = jnp.asarray(params.gravity, x.dtype)
    force = force + s.mass[:, None] * g + s.f_ext * dem.load_factor(dp.load_ramp, state.t)
    if f_fluid is not None:
        force = force + f_fluid
    with jax.named_scope("dem.local_damping"):
        force = dem.local_damping(dp.alpha, force, v)
        torque = dem.local_damping(dp.alpha, torque, omega)
    with jax.named_scope("dem.viscous_damping"):
        force = force + dem.viscous_damping(dp.damping, s.mass[:, None], v)
        torque = torque + dem.viscous_damping(dp.damping, s.inertia, omega)
    free = ~s.fixed
    inertia = s.mass if m_added is None else s.mass + m_added
    acc = jnp.where(free[:, None], force / inertia[:, None], 0.0)
    alpha = jnp.where(free, torque / s.inertia, 0.0)
    return state.replace(solid=s.replace(acc=acc, alpha=alpha, shear=shear,
                                         wall_shear=wall_shear, reaction=reaction),
                         bonds=b, walls=walls)


def _dem_list_update(phys: Physics, state: State, rebuild_now=None) -> State:
    """The DEM list at the discs' present positions: rebuilt when a disc moved more than
    half the skin since the build (jax-md's test), or when ``rebuild_now`` (a traced bool)
    holds; a rebuild re-addresses the contact histories and asks the walls again."""
    s, old, walls = state.solid, state.solid_nbrs, state.walls
    cfg = phys.dem_neighbors
    with jax.named_scope("neighbors.dem_update"):
        if rebuild_now is None:
            nbrs, rebuilt, need = neighbors.update(cfg, old, s.x, about_centre=False)
        else:
            nbrs, rebuilt, need = neighbors.rebuild_if(cfg, old, s.x, rebuild_now)
        if walls is None or walls.near is None:
            shear = jax.lax.cond(rebuilt, dem.remap_history, lambda o, h, n: h,
                                 old.idx, s.shear, nbrs.idx)
        else:
            shear, near, n_near = jax.lax.cond(
                rebuilt,
                lambda: (dem.remap_history(old.idx, s.shear, nbrs.idx),
                         *walls_near(phys, s, walls, s.x)),
                lambda: (s.shear, walls.near, walls.n_near))
            walls = walls.replace(near=near, n_near=n_near)
    st = state.status
    return state.replace(
        solid_nbrs=nbrs, walls=walls, solid=s.replace(shear=shear),
        status=st.replace(dem_rebuilds=st.dem_rebuilds + rebuilt.astype(jnp.int32),
                          overflow=st.overflow | nbrs.did_buffer_overflow.astype(bool),
                          dem_need=jnp.maximum(st.dem_need, need)))


def _list_reach(phys: Physics, params: Params, state: State):
    """(the largest displacement of a disc since the DEM list's build, the step's reach),
    the reach being twice the largest travel a disc's present motion predicts over the
    step, max_i (Δt|v_i| + ½Δt²|a_i|). The factor 2 leaves room for discs whose
    acceleration changes within the step; the acceleration term covers a structure at the
    turn of its swing, nearly at rest but accelerating, where Δt max|v| alone predicts no
    travel. :func:`discs` rebuilds the list at the step's start when the two together pass
    half the skin, and tests it at every sub-step when the reach alone does (a fresh list
    may not hold through the step)."""
    cfg, s = phys.dem_neighbors, state.solid
    d = neighbors.shift(cfg, s.x) - state.solid_nbrs.reference_position
    moved = jnp.sqrt(jnp.max(jnp.sum(d * d, axis=-1)))
    dt = params.dt
    travel = (dt * jnp.sqrt(jnp.sum(s.v * s.v, axis=-1))
              + 0.5 * dt * dt * jnp.sqrt(jnp.sum(s.acc * s.acc, axis=-1)))
    return moved, 2.0 * jnp.max(travel)


def scheduled(phys: Physics, solid, t0, dt):
    """``solid`` with the velocity of each kinematic group that has a prescribed motion
    (Physics.kinematic_motion, model/motion.py): its mean over the sub-step [t0, t0 +
    dt] it moves the group over, which keeps the group on its prescribed path to
    round-off."""
    if not phys.kinematic_motion:
        return solid
    v = solid.v
    for m in phys.kinematic_motion:
        vel = motion.mean_velocity(m, t0, dt, v.dtype)
        v = v.at[m.a:m.b].set(jnp.broadcast_to(vel, (m.b - m.a, 2)))
    return solid.replace(v=v)


def _disc_substep(phys: Physics, params: Params, state: State, t, dt, f_fluid, wet,
                  check_list: bool = True, m_added=None) -> State:
    """One DEM kick–drift–kick of length ``dt`` ending at time ``t``; ``check_list``: the
    DEM list's skin test at the new positions (:func:`_dem_list_update`). Kinematic
    groups with a prescribed motion move at its mean velocity over the sub-step
    (:func:`scheduled`)."""
    s = scheduled(phys, state.solid, t - dt, dt)
    with jax.named_scope("step.solid_kick_drift"):
        v_half = s.v + 0.5 * dt * s.acc
        w_half = s.omega + 0.5 * dt * s.alpha
        u_new = s.u + dt * v_half          # the displacement, then x (SolidState)
        th_new = s.theta + dt * w_half
    state = state.replace(t=t, solid=s.replace(x=s.x_ref + u_new, u=u_new, theta=th_new,
                                                v=v_half, omega=w_half))
    if check_list:
        state = _dem_list_update(phys, state)
    before = state.walls.reaction if phys.wall_reaction and state.walls is not None else None
    held_before = state.solid.reaction
    state = disc_forces(phys, params, state, dt, f_fluid, wet, m_added)
    share = dt / params.dt          # the sub-steps' mean: the impulse over the step / Δt
    if before is not None:
        walls = state.walls
        state = state.replace(walls=walls.replace(reaction=before + share * walls.reaction))
    if held_before is not None:
        s = state.solid
        state = state.replace(solid=s.replace(reaction=held_before + share * s.reaction))
    s = state.solid
    with jax.named_scope("step.solid_kick"):
        return state.replace(solid=s.replace(v=s.v + 0.5 * dt * s.acc,
                                             omega=s.omega + 0.5 * dt * s.alpha))


def discs(phys: Physics, params: Params, state: State) -> State:
    """``phys.dem_substeps`` DEM steps of Δt/n covering one step (multi-rate stepping), the
    fluid's force on the discs held at its value of the last SPH evaluation. ``state.t`` is
    the time at the end of the step.

    The DEM list is tested once for the step (:func:`_list_reach`: rebuilt now if a disc
    could pass half the skin before the step ends), not at every sub-step: the test, its
    conditionals and the history remap were a third of a sub-step of a few hundred discs.
    The sub-steps track each disc's largest squared displacement from the list's build
    positions; one past half the skin flags ``Status.dem_stale`` (and ``overflow``), and
    the host redoes the chunk with ``Physics.dem_list_substeps``, the test at every
    sub-step. A step whose predicted reach alone passes half the skin (a disc so fast
    that even a fresh list may not hold through the step: the gate's free end striking,
    1.5 m/s and 2·10⁵ m/s²) takes the test at every sub-step in the same program, so the
    chunk is neither redone nor the step compiled again."""
    n = phys.dem_substeps
    dts = params.dt / n
    t0 = (state.step - 1) * params.dt      # the time at the start of the step
    f_fluid = fluid_force_on_discs(phys, state)
    wet = wet_grains(phys, state)
    m_added = grain_added_mass(phys, state)
    walls = state.walls
    if phys.wall_reaction and walls is not None:    # the sub-steps add up their mean
        walls = walls.replace(reaction=jnp.zeros_like(walls.reaction))
    solid = state.solid
    if solid.reaction is not None:                  # and so do the held discs' reactions
        solid = solid.replace(reaction=jnp.zeros_like(solid.reaction))
    # the loop carries the DEM part of the state only
    part = State(t=state.t, step=state.step, fluid=None, boundary=None, nbrs=None,
                 status=state.status, solid=solid, bonds=state.bonds,
                 solid_nbrs=state.solid_nbrs, walls=walls)

    def one(k, p):
        return _disc_substep(phys, params, p, t0 + (k + 1) * dts, dts, f_fluid, wet,
                             m_added=m_added)

    if n == 1:
        part = one(0, part)
    elif phys.dem_list_substeps:
        with jax.named_scope("step.dem_substeps"):
            part = jax.lax.fori_loop(0, n, one, part)
    else:
        cfg = phys.dem_neighbors
        half = 0.5 * cfg.skin
        moved, reach = _list_reach(phys, params, part)

        def tested_once(part):
            # the list's skin test once for the step; the sub-steps track how far each
            # disc has moved from the list's build positions
            part = _dem_list_update(phys, part, moved + reach > half)
            ref = part.solid_nbrs.reference_position + jnp.asarray(cfg.origin,
                                                                    part.solid.x.dtype)

            def tracked(k, carry):
                p, far = carry
                p = _disc_substep(phys, params, p, t0 + (k + 1) * dts, dts, f_fluid, wet,
                                  check_list=False, m_added=m_added)
                d = p.solid.x - ref
                return p, jnp.maximum(far, jnp.sum(d * d, axis=-1))

            with jax.named_scope("step.dem_substeps"):
                part, far = jax.lax.fori_loop(0, n, tracked,
                                              (part, jnp.zeros(ref.shape[:1], ref.dtype)))
            stale = jnp.any(far > half ** 2)
            st = part.status
            return part.replace(status=st.replace(overflow=st.overflow | stale,
                                                  dem_stale=st.dem_stale | stale))

        def tested_each_substep(part):
            with jax.named_scope("step.dem_substeps_tested"):
                return jax.lax.fori_loop(0, n, one, part)

        part = jax.lax.cond(reach > half, tested_each_substep, tested_once, part)
    status = part.status
    if state.walls is not None:
        status = health.check_wall_crossings(part.solid, state.solid.x, state.walls,
                                             state.step, status)
    fp = state.fpi
    if m_added is not None:
        # what the grains' added mass took over the step goes back to the fluid with the
        # drag at the step's SPH evaluation (grain_forces)
        k = fp.idx
        fp = fp.replace(added=fpi.added_mass_force(
            m_added[k], fp.du_f, part.solid.v[k] - state.solid.v[k], params.dt))
    return state.replace(solid=part.solid, bonds=part.bonds, solid_nbrs=part.solid_nbrs,
                         walls=part.walls, status=status, fpi=fp)


def disc_exits(phys: Physics, params: Params, state: State) -> State:
    """Discs that crossed an open side leave the computation (solver.exits)."""
    with jax.named_scope("step.disc_exits"):
        solid, bonds = exits.park_discs(phys, state.solid, state.bonds, state.t)
    return state.replace(solid=solid, bonds=bonds)


def check_discs(phys: Physics, params: Params, state: State) -> State:
    """Health codes 6–8 of the discs (non-finite, out of the domain); remember the first."""
    return state.replace(status=health.check_solid(phys, state.solid, state.step,
                                                   state.status))


# --- SPH -------------------------------------------------------------------------------------
def fluid_kick_drift(phys: Physics, params: Params, state: State) -> State:
    """v½ = v + ½Δt a, x' = x + Δt (v½ + δv_XSPH): the fluid's ``v`` holds v½ until
    :func:`fluid_kick`."""
    dt, f = params.dt, state.fluid
    with jax.named_scope("step.kick_drift"):
        v_half = f.v + 0.5 * dt * f.acc
        x_new = f.x + dt * (v_half + f.xsph)
    return state.replace(fluid=f.replace(x=x_new, v=v_half))


def fluid_neighbours(phys: Physics, params: Params, state: State) -> State:
    """Update the SPH family's list at the new positions (rebuilt when the displacements
    since its build no longer fit in a circle of radius skin/2,
    neighbors.moved_past_half_skin); an overflow is flagged for the host to redo the chunk."""
    with jax.named_scope("neighbors.update"):
        nbrs, rebuilt, need = neighbors.update(phys.neighbors, state.nbrs,
                                                sph_positions(state))
    st = state.status
    return state.replace(nbrs=nbrs, status=st.replace(
        overflow=st.overflow | nbrs.did_buffer_overflow.astype(bool),
        rebuilds=st.rebuilds + rebuilt.astype(jnp.int32),
        sph_need=jnp.maximum(st.sph_need, need)))


def fluid_forces(phys: Physics, params: Params, state: State) -> State:
    """Density, smoothing length and pressure at the new time level and the fluid's
    acceleration (:func:`evaluate_fluid` with the step's Δt)."""
    return evaluate_fluid(phys, params, state, params.dt)


class SphFamily(NamedTuple):
    """The SPH neighbour family of one evaluation, in list order [fluid; boundary;
    structure] (the grains have rows of their own at the end of the list, never columns).

    x, v, h, m   (n_sph, …) positions, velocities (walls: 0), smoothing lengths, masses
    idx          (n_sph, K) neighbour list of those rows (grain columns masked out)
    idx_g        (n_grain, K) the grains' rows, or None
    first_s      index of the first structure particle (n_fluid + n_boundary)
    a_s          (n_structure, 2) the structure discs' acceleration, or None (none, or
                 Physics.structure_acceleration off: their pressure then sees g alone)
    x_p, v_p, r_p, vol_p   the grains' position, velocity, radius and area V_p = πR², or None
    """
    x: jax.Array
    v: jax.Array
    h: jax.Array
    m: jax.Array
    idx: jax.Array
    idx_g: Any
    first_s: int
    a_s: Any
    x_p: Any
    v_p: Any
    r_p: Any
    vol_p: Any


class NewLevel(NamedTuple):
    """The fluid at the new time level: ρ' (intrinsic), h', P', and with grains the voidage
    ε (floored for the fluid equations), ε unfloored (for the drag) and the grains' rows."""
    rho: jax.Array
    h: jax.Array
    p: jax.Array
    eps: Any = None
    eps_raw: Any = None
    rows: Any = None


def prescribed_acceleration(phys: Physics, t, idx, a_s):
    """``a_s`` (the structure particles' acceleration, or None) with the prescribed
    acceleration of the kinematic groups that move (Physics.kinematic_motion) at time
    ``t`` on their rows (``idx`` the structure particles' disc indices): a wave maker's
    piston accelerates the water, and Adami's extrapolated pressure on a moving wall is
    that of g − a_w (model/motion.py, :func:`~fpsi_jax.model.motion.acceleration`)."""
    moving = [m for m in phys.kinematic_motion if not isinstance(m, motion.Window)]
    if not moving:
        return a_s
    out = jnp.zeros((idx.shape[0], 2), jnp.result_type(t)) if a_s is None else a_s
    for m in moving:
        on = (idx >= m.a) & (idx < m.b)
        out = jnp.where(on[:, None], motion.acceleration(m, t, out.dtype), out)
    return out


def sph_family(phys: Physics, state: State) -> SphFamily:
    """Gather the SPH family's arrays of ``state`` (see :class:`SphFamily`)."""
    f, b, fs, fp = state.fluid, state.boundary, state.fsi, state.fpi
    nb = 0 if b is None else b.x.shape[0]
    n_sph = phys.n_fluid + nb + (0 if fs is None else fs.idx.shape[0])
    xs_ = vs_ = a_s = None
    if fs is not None:
        s = state.solid
        xs_, vs_ = s.x[fs.idx], s.v[fs.idx]
        a_s = s.acc[fs.idx] if phys.structure_acceleration else None
        a_s = prescribed_acceleration(phys, state.t, fs.idx, a_s)
    idx, idx_g = state.nbrs.idx, None
    x_p = v_p = r_p = vol_p = None
    if fp is not None:
        idx, idx_g = jnp.minimum(idx[:n_sph], n_sph), idx[n_sph:]  # grains leave the sums
        s = state.solid
        x_p, v_p, r_p = s.x[fp.idx], s.v[fp.idx], s.radius[fp.idx]
        vol_p = jnp.pi * r_p * r_p        # V_p per unit thickness, like the disc's mass
    return SphFamily(
        x=_cat(f.x, _opt(b, "x"), xs_),
        v=_cat(f.v, None if b is None else jnp.zeros_like(b.x), vs_),
        h=_cat(f.h, _opt(b, "h"), _opt(fs, "h")), m=_cat(f.mass, _opt(b, "mass"), _opt(fs, "mass")),
        idx=idx, idx_g=idx_g, first_s=phys.n_fluid + nb, a_s=a_s, x_p=x_p, v_p=v_p, r_p=r_p,
        vol_p=vol_p)


def _all(state: State, fluid_value, name: str):
    """A fluid array followed by the boundary's and the structure's ``name`` array."""
    return _cat(fluid_value, _opt(state.boundary, name), _opt(state.fsi, name))


def pair_pass(phys: Physics, fam: SphFamily, rho_c_all, fn, table=None):
    """fn(Pairs) over the fluid rows of the SPH list, all at once or, if set, in row blocks
    of ``phys.pair_block`` (pairs.over_row_blocks): the pair geometry of each block
    (pairs.pairs, with ρ of the volumes m_j/ρ_j from ``rho_c_all``) is built where it is
    summed, so the density pass and the momentum pass each recompute it rather than reading
    it back from memory. ``table``: the family's pair_table, where the caller has built it
    already."""
    kern = kernels.get(phys.kernel)
    if table is None:
        table = pair_table(fam.x, fam.v, fam.h, fam.m, rho_c_all)

    def block(row0, rows):
        return fn(pairs_of(kern, phys.n_fluid, table, rows_of(fam.idx, row0, rows), row0))
    return over_row_blocks(block, phys.n_fluid, phys.pair_block)


def grain_images(phys: Physics, state: State, x_p):
    """The grains' images in the DEM walls for the voidage (fpi.wall_images), or None
    (option wall_images off, or no walls)."""
    if not phys.wall_images or state.walls is None:
        return None
    w = state.walls
    return fpi.wall_images(x_p, w.a, w.b, w.side if w.image_side is None else w.image_side)


def continuity_velocity(phys: Physics, fluid):
    """The fluid velocity continuity moves the density with: v + δv_XSPH, the velocity the
    particles drift with (:func:`fluid_kick_drift`), with ``phys.transport_continuity``;
    else v (K32)."""
    return fluid.v + fluid.xsph if phys.transport_continuity else fluid.v


def transported(phys: Physics, fam: SphFamily, fluid) -> SphFamily:
    """The family with the fluid's velocity v + δv_XSPH, the velocity its particles drift
    with (:func:`fluid_kick_drift`): continuity then gives the rate of the density the
    particles' motion makes, Σ_j m_j (ṽ_i − ṽ_j)·∇_iW_ij with ṽ = v + δv (the rate of the
    summation density of particles moving with ṽ). With ``v`` alone the XSPH part of the
    motion compresses or spreads the fluid without the density seeing it."""
    v = jnp.concatenate([continuity_velocity(phys, fluid), fam.v[phys.n_fluid:]])
    return fam._replace(v=v)


def new_level(phys: Physics, params: Params, state: State, fam: SphFamily, rho_c_all,
              dt) -> NewLevel:
    """Continuity (K32) with δ-SPH, ρ' = ρ + dt Dρ/Dt, h' by K37, with grains the voidage at
    the new positions (W42: the conserved density is ερ), and P' from the EOS (W46, K35).
    ``phys.transport_continuity``: continuity with the velocity the particles drift with
    (:func:`transported`).

    With the 'shared' pressure the intrinsic ρ is advanced by the mixture's continuity
    (:func:`fpi.mixture_flux`, :func:`mixture_density_rate`), the discrete adjoint of the
    shared pressure force; otherwise ερ is advanced and ρ' = (ερ)'/ε'."""
    sp, f, fp = params.sph, state.fluid, state.fpi
    if fp is not None and phys.fpi_pressure is FpiPressure.SHARED:
        return _mixture_level(phys, params, state, fam, dt)
    if phys.transport_continuity:
        fam = transported(phys, fam, f)
    rho_c = f.rho if fp is None else fp.eps * f.rho
    if fp is None:
        drho = pair_pass(phys, fam, rho_c_all,
                         lambda pr: sph.density_rate(phys, sp, pr.own(rho_c), pr,
                                                     gravity=params.gravity))
    else:
        rho_all = _all(state, f.rho, "rho")
        drho = pair_pass(phys, fam, rho_c_all,
                         lambda pr: sph.density_rate(phys, sp, pr.own(rho_c), pr,
                                                     pr.own(fp.eps), rho_all,
                                                     params.gravity))
    rho_c_new = rho_c + dt * drho
    h_new = f.h
    if phys.variable_h:
        with jax.named_scope("sph.variable_h"):
            h_new = f.h + dt * sph.smoothing_length_rate(f.h, rho_c, drho)
    eps = eps_raw = rows = None
    rho_new = rho_c_new
    if fp is not None:
        with jax.named_scope("fpi.voidage"):
            rows = fpi.grain_rows(kernels.get(phys.kernel), f.x, f.h, f.mass / rho_c_new,
                                  fam.x_p, fam.idx_g, phys.n_fluid,
                                  grain_images(phys, state, fam.x_p))
            eps_raw = fpi.fluid_voidage(rows.ws, fam.vol_p, rows.idx, rows.valid, phys.n_fluid,
                                        phys.voidage)
            eps = jnp.maximum(eps_raw, phys.eps_floor)
        rho_new = rho_c_new / eps
    with jax.named_scope("sph.eos"):
        p_new = eos.pressure(rho_new, sp.rho0, sp.c0, sp.gamma)
    return NewLevel(rho=rho_new, h=h_new, p=p_new, eps=eps, eps_raw=eps_raw, rows=rows)


def mixture_voidage(phys: Physics, state: State, fam: SphFamily):
    """The grains' rows of the fluid at its present positions, the voidage there (unfloored,
    and floored for the fluid equations) and the mixture's volume flux
    J = εu + (1 − ε) v̄_grains (fpi.mixture_flux): what the 'shared' pressure's continuity
    needs before the density is advanced."""
    f, fp = state.fluid, state.fpi
    with jax.named_scope("fpi.voidage"):
        rows = fpi.grain_rows(kernels.get(phys.kernel), f.x, f.h, f.mass / (fp.eps * f.rho),
                              fam.x_p, fam.idx_g, phys.n_fluid,
                              grain_images(phys, state, fam.x_p))
        eps_raw = fpi.fluid_voidage(rows.ws, fam.vol_p, rows.idx, rows.valid, phys.n_fluid,
                                    phys.voidage)
        eps = jnp.maximum(eps_raw, phys.eps_floor)
        flux = fpi.mixture_flux(rows, eps, continuity_velocity(phys, f), fam.v_p, fam.vol_p,
                                phys.n_fluid)
    return rows, eps_raw, eps, flux


def mixture_density_rate(phys: Physics, params: Params, state: State, fam: SphFamily, eps,
                         flux):
    """Dρ_i/Dt of the intrinsic density by the mixture's continuity (W42 with the grains'
    volume flux), (ρ_i/ε_i) Σ_j V_j (J_i − J_j)·∇_iW_ij, V_j = m_j/(ε_j ρ_j), plus δ-SPH on
    ρ: the pair sums of sph.density_rate with the particles' velocities replaced by J (the
    walls' and the structure's own velocities, ε = 1)."""
    f = state.fluid
    rho_c_all = _all(state, eps * f.rho, "rho")
    rho_all = _all(state, f.rho, "rho")
    mix = fam._replace(v=_cat(flux, fam.v[phys.n_fluid:]))
    return pair_pass(phys, mix, rho_c_all,
                     lambda pr: sph.density_rate(phys, params.sph, pr.own(f.rho / eps), pr,
                                                 1.0, rho_all, params.gravity))


def _mixture_level(phys: Physics, params: Params, state: State, fam: SphFamily,
                   dt) -> NewLevel:
    """The new level with the 'shared' pressure. The shared pressure force on fluid
    particle i is −ε_i Σ_j V_i V_j (P_i + P_j) ∇_iW_ij and its grains get the rest, by
    their part of the solid fraction, the weights of v̄ in J; the rate of the fluid's
    internal energy Σ m_i (P_i/ρ_i²) Dρ_i/Dt under :func:`mixture_density_rate` is minus
    the power of exactly these forces, pair by pair (tests/solver/test_stages.py checks it
    to round-off). ρ = ερ/ε(x) with ε from the grains at the new positions (the other
    modes) has no such partner: moving a fluid particle up the voidage gradient changes its
    pressure without work, which pumped energy into a packed bed's pore fluid until it
    blew up (docs/physics.md, Packed beds). ε' and J at the new positions come first, then
    ρ' = ρ + dt Dρ/Dt, and h' follows the intrinsic density (K37 with ρ), the spacing of
    the fluid's particles, unless the particle's superficial volume m/(ε'ρ') outgrows what
    its h can resolve (Physics.pore_neighbours, sph.smoothing_length_among_grains).
    (Following ερ both ways, a particle moving from ε = 0.16 to 0.22 shrank its h by 15 %,
    and a packed bed under still water blew up after 0.2–1.7 s.)"""
    sp, f = params.sph, state.fluid
    rows, eps_raw, eps, flux = mixture_voidage(phys, state, fam)
    drho = mixture_density_rate(phys, params, state, fam, eps, flux)
    rho_new = f.rho + dt * drho
    h_new = f.h
    if phys.pore_neighbours > 0 and phys.h_over_dp > 0:
        with jax.named_scope("sph.pore_neighbours"):
            h_new = sph.smoothing_length_among_grains(phys.h_over_dp, f.mass, eps, rho_new,
                                                      sp.dp, sp.rho0, phys.pore_neighbours,
                                                      phys.variable_h)
    elif phys.variable_h:
        with jax.named_scope("sph.variable_h"):
            h_new = f.h + dt * sph.smoothing_length_rate(f.h, f.rho, drho)
    rows = rows._replace(vol=gather(f.mass / (eps * rho_new), rows.idx, 0.0))
    with jax.named_scope("sph.eos"):
        p_new = eos.pressure(rho_new, sp.rho0, sp.c0, sp.gamma)
    return NewLevel(rho=rho_new, h=h_new, p=p_new, eps=eps, eps_raw=eps_raw, rows=rows)


def wall_pressure(phys: Physics, params: Params, state: State, fam: SphFamily,
                  lvl: NewLevel) -> State:
    """The pressure (and density) of the fixed boundary particles (extrapolated mode, Adami
    et al. 2012) and of the structure particles (the coupling's rule, fsi.py)."""
    sp, nf, g = params.sph, phys.n_fluid, jnp.asarray(params.gravity)
    kern, b, fs = kernels.get(phys.kernel), state.boundary, state.fsi
    nb = fam.first_s - nf
    if b is not None and phys.boundary_pressure is BoundaryPressure.EXTRAPOLATED:
        with jax.named_scope("boundary.extrapolated"):
            pb = boundary.extrapolated_pressure(
                nf, kern, g, fam.x, fam.h, _cat(lvl.rho, b.rho, _opt(fs, "rho")),
                _cat(lvl.p, b.p, _opt(fs, "p")),
                neighbors.wall_rows(phys.neighbors, fam.idx, nf, nb))
        b = b.replace(p=pb, rho=eos.density(pb, sp.rho0, sp.c0, sp.gamma))
    if fs is not None and phys.fsi in (FsiMethod.EXTRAPOLATED,
                                       FsiMethod.PRESSURE_APPROXIMATION):
        rho_all = _cat(lvl.rho, _opt(b, "rho"), fs.rho)
        p_all = _cat(lvl.p, _opt(b, "p"), fs.p)
        idx_s = neighbors.wall_rows(phys.neighbors, fam.idx, fam.first_s, fs.idx.shape[0])
        if phys.fsi is FsiMethod.EXTRAPOLATED:
            with jax.named_scope("fsi.extrapolated"):
                ps = boundary.extrapolated_pressure(nf, kern, g, fam.x, fam.h, rho_all, p_all,
                                                    idx_s, acc_b=fam.a_s, first=fam.first_s)
        else:
            with jax.named_scope("fsi.pressure_approximation"):
                ps = fsi.approximate_pressure(kern, nf, fam.x, fam.h, rho_all, p_all, fam.m,
                                              idx_s)
        fs = fs.replace(p=ps, rho=eos.density(ps, sp.rho0, sp.c0, sp.gamma))
    return state.replace(boundary=b, fsi=fs)


def fluid_momentum(phys: Physics, params: Params, state: State, fam: SphFamily, rho_c_all,
                   lvl: NewLevel):
    """The fluid's acceleration and XSPH correction (sph.momentum_rate: W43, K34–K39) at the
    new level, the reaction of the fluid–structure pairs on the structure
    (:func:`structure_reaction`, fsi.py) and, with Physics.wall_force, on those boundary
    rows (:func:`wall_force`). With the 'shared' pressure the reaction is the whole pair
    force of the fluid particle's cell, the fluid's ε_F share and the grains' 1 − ε_F.
    Returns (state, the grains' part of the cells' pressure force per unit fluid mass with
    the 'shared' pressure, else None)."""
    fs, b, first = state.fsi, state.boundary, phys.n_fluid + phys.n_boundary
    bracket = None
    if fs is not None and phys.fsi is FsiMethod.PRESSURE_GRADIENT:
        n_s = phys.n_structure
        bracket = (lambda coef, p_i, inv_rho_i, inv_rho_j, ix:
                   fsi.pressure_gradient_bracket(coef, p_i, inv_rho_i, inv_rho_j, ix, first,
                                                 n_s))
    eps_all = None
    if lvl.eps is not None:
        eps_all = _cat(lvl.eps, None if b is None else jnp.ones_like(b.rho),
                       None if fs is None else jnp.ones_like(fs.rho))
    shared = lvl.eps is not None and phys.fpi_pressure is FpiPressure.SHARED
    rho_all, p_all = _all(state, lvl.rho, "rho"), _all(state, lvl.p, "p")

    def rate(pr, gravity, shared=shared):
        return sph.momentum_rate(phys, kernels.get(phys.kernel), params.sph, gravity, rho_all,
                                 p_all, pr, eps=eps_all, structure_bracket=bracket,
                                 shared=shared, h=fam.h, dt=params.dt)

    table = pair_table(fam.x, fam.v, fam.h, fam.m, rho_c_all)
    out = pair_pass(phys, fam, rho_c_all, lambda pr: rate(pr, jnp.asarray(params.gravity)),
                    table)
    acc, xs = out[:2]
    # a wall or structure particle takes the whole pair force of the mixture's cell: with
    # the 'shared' pressure the fluid keeps ε_F of it and the grains in the cell take the
    # rest, and the wall pushes on both (Newton's third law over the three)
    no_gravity = lambda pr: rate(pr, jnp.zeros_like(acc[0]), shared=False)[0]
    if fs is not None:
        with jax.named_scope("fsi.reaction"):
            fs = fs.replace(force=structure_reaction(phys, fam, table, no_gravity))
    if phys.wall_force:
        with jax.named_scope("boundary.force"):
            b = b.replace(force=wall_force(phys, fam, table, no_gravity))
    state = state.replace(fluid=state.fluid.replace(acc=acc, xsph=xs), fsi=fs, boundary=b)
    return state, (out[3] if shared else None)


def structure_reaction(phys: Physics, fam: SphFamily, table, fluid_rate):
    """The fluid's force on each structure particle, −Σ_F m_F a_{F←S} (fsi.reaction), with
    each fluid–structure pair's term computed as the fluid particle's own row computes it:
    the structure rows of the list (their fluid neighbours, NeighborConfig.wall_width)
    give the pairs, and each pair becomes a row of one slot whose particle is F and whose
    neighbour is S (pairs.pairs_at), passed through ``fluid_rate`` (the momentum pass's own
    pair law, without gravity). The momentum pass over the fluid rows then writes no
    per-pair array: keeping its (n_f, K, 2) pair accelerations for this sum cost the elastic
    gate a quarter of its step (docs/performance.md)."""
    return _reaction_on_rows(phys, fam, table, fluid_rate, fam.first_s, phys.n_structure)


def wall_force(phys: Physics, fam: SphFamily, table, fluid_rate):
    """The fluid's force on the boundary particles a … b − 1 of ``phys.wall_force``, as
    :func:`structure_reaction` computes it for the structure (each fluid–boundary pair's
    momentum term as the fluid row computes it, pressure, viscosity and the wall backstop);
    (n_b, 2), zero on the other boundary rows. What a force probe on an obstacle reads."""
    a, b = phys.wall_force
    f = _reaction_on_rows(phys, fam, table, fluid_rate, phys.n_fluid + a, b - a)
    return jnp.zeros((phys.n_boundary, 2), f.dtype).at[a:b].set(f)


def _reaction_on_rows(phys: Physics, fam: SphFamily, table, fluid_rate, first: int, n: int):
    """−Σ_F m_F a_{F←W} for the wall rows ``first`` … ``first`` + n − 1 of the SPH family
    (boundary or structure particles, whose rows list their fluid neighbours)."""
    idx_w = neighbors.wall_rows(phys.neighbors, fam.idx, first, n)
    found = idx_w < phys.n_fluid
    # an empty slot becomes fluid particle 0 with the padding particle far away as its
    # neighbour, as a padded slot of a fluid row is: every term of it is exactly zero
    f = jnp.where(found, idx_w, 0).reshape(-1)
    w = jnp.where(found, first + jnp.arange(n, dtype=idx_w.dtype)[:, None],
                  table.shape[0] - 1).reshape(-1, 1)
    acc = fluid_rate(pairs_at(kernels.get(phys.kernel), phys.n_fluid, table, f, w))
    return fsi.reaction(acc.reshape(idx_w.shape + (2,)), fam.m[f].reshape(idx_w.shape), found)


def grain_forces(phys: Physics, params: Params, state: State, fam: SphFamily,
                 lvl: NewLevel, solid_share=None) -> State:
    """The fluid's force on the grains, drag (W19–W23) and buoyancy (fpi.py), and its
    reaction on the fluid by kernel weights (W47–W48)."""
    sp, f, b, fp = params.sph, state.fluid, state.boundary, state.fpi
    g = jnp.asarray(params.gravity)
    kern, rows = kernels.get(phys.kernel), lvl.rows
    with jax.named_scope("fpi.drag"):
        eps_p, u_f, wet, drag = fpi.grain_drag(rows, lvl.eps_raw, f.v, fam.v_p, fam.vol_p,
                                               2.0 * fam.r_p, sp.rho0, sp.mu, phys.voidage,
                                               phys.drag)
    with jax.named_scope("fpi.buoyancy"):
        if phys.fpi_pressure is FpiPressure.ARCHIMEDES:
            lift = -(sp.rho0 * fam.vol_p)[:, None] * g[None, :]
        elif phys.fpi_pressure is FpiPressure.GRADIENT:
            lift = fpi.pressure_force(rows, lvl.p, fam.vol_p)
        else:       # the grains' part of their cells' pressure force (fluid_momentum)
            lift = fpi.cell_share_on_grains(rows, solid_share * f.mass[:, None], fam.vol_p,
                                            phys.n_fluid)
        force = drag + jnp.where((wet > 0)[:, None], lift, 0.0)
    with jax.named_scope("fpi.reaction"):
        if solid_share is not None:
            # with the shared pressure the buoyancy is the grains' own part of the cells'
            # pressure force, not a force on the fluid: only the drag goes back, by the
            # weights of the fluid velocity ū it was computed from, so that it only ever
            # dissipates (a wall share would let it pump energy near a wall)
            acc, back = f.acc, drag
            reaction = functools.partial(fpi.reaction_acceleration, rows, m_f=f.mass)
        else:
            wall = None if b is None else fpi.wall_share(kern, b.x, b.h, b.mass / b.rho,
                                                         fam.x_p, fam.idx_g, phys.n_fluid)
            reaction = functools.partial(fpi.reaction_acceleration, rows, m_f=f.mass,
                                         wall=wall)
            acc, back = f.acc, force
            if phys.added_mass:      # the buoyancy back first: Du/Dt is read after it
                acc, back = acc + reaction(force - drag), drag
    held, du_f, m_a = force, None, None
    if phys.added_mass:
        # Du/Dt is the fluid's acceleration under its pressure, viscosity and gravity with
        # the grains' buoyancy handed back, not their drag; the grains hold m_a Du/Dt with
        # the drag and buoyancy, and the added-mass force they took over this step's
        # sub-steps (discs) goes back to the fluid with the drag
        with jax.named_scope("fpi.added_mass"):
            du_f = fpi.fluid_acceleration(rows, acc)
            m_a = jnp.minimum(fpi.added_mass(params.fpi.added_mass, sp.rho0, fam.vol_p, wet),
                              fpi.added_mass_limit(rows, f.mass))
            held = force + m_a[:, None] * du_f
            back = back + fp.added
    with jax.named_scope("fpi.reaction"):
        acc = acc + reaction(back)
    return state.replace(fluid=f.replace(acc=acc),
                         fpi=fp.replace(eps=lvl.eps, eps_p=eps_p, u_f=u_f, wet=wet,
                                        force=held, m_a=m_a, du_f=du_f))


def evaluate_fluid(phys: Physics, params: Params, state: State, dt) -> State:
    """One SPH evaluation at the fluid's x and v (v½ in a step): ρ' = ρ + dt Dρ/Dt (dt = 0:
    no drift), h', P', the walls' and the structure's pressure, then a' and δv_XSPH and the
    fluid's force on the structure discs (fsi.py) and on the grains (fpi.py).

    With grains the conserved density is ερ (W42): continuity advances ε_old ρ, the voidage
    ε at the new positions turns it back into the intrinsic ρ that the EOS, the viscosity
    and the walls see, the pressure bracket carries ε (``sph.voidage_bracket``), and the
    grains' drag and buoyancy go back to the fluid by kernel weights (W47–W48); with the
    'shared' pressure the fluid keeps ε of its cell's pressure force, the grains get the
    rest, and only the drag goes back. Without grains none of this is traced."""
    fam = sph_family(phys, state)
    rho_c = state.fluid.rho if state.fpi is None else state.fpi.eps * state.fluid.rho
    rho_c_all = _all(state, rho_c, "rho")
    lvl = new_level(phys, params, state, fam, rho_c_all, dt)
    state = wall_pressure(phys, params, state, fam, lvl)
    state, solid_share = fluid_momentum(phys, params, state, fam, rho_c_all, lvl)
    if state.fpi is not None:
        state = grain_forces(phys, params, state, fam, lvl, solid_share)
    return state.replace(fluid=state.fluid.replace(rho=lvl.rho, h=lvl.h))


def fluid_kick(phys: Physics, params: Params, state: State) -> State:
    """v' = v½ + ½Δt a'."""
    f = state.fluid
    with jax.named_scope("step.kick"):
        return state.replace(fluid=f.replace(v=f.v + 0.5 * params.dt * f.acc))


def fluid_exits(phys: Physics, params: Params, state: State) -> State:
    """Fluid particles that crossed an open side leave the computation (solver.exits)."""
    with jax.named_scope("step.fluid_exits"):
        return state.replace(fluid=exits.park_fluid(phys, state.fluid, state.t))


def check_fluid(phys: Physics, params: Params, state: State) -> State:
    """Health codes 1–5 of the fluid (non-finite, density out of band, out of the domain) and
    a smoothing length that outgrew the neighbour cut-off; remember the first."""
    st = state.status
    st = st.replace(h_exceeded=st.h_exceeded
                    | (jnp.max(state.fluid.h) * 2.0 > phys.neighbors.r_cut))
    return state.replace(status=health.check_fluid(phys, params, state.fluid, state.step, st))


def mark_redo(phys: Physics, params: Params, state: State) -> State:
    """Remember the first step that is not exact: an overflowed list dropped pairs of this
    step; an h past the cut-off (the new h) would drop pairs of the next one."""
    st, n = state.status, state.step
    return state.replace(status=st.replace(redo_step=jnp.where(
        (st.redo_step < 0) & (st.overflow | st.h_exceeded),
        jnp.where(st.overflow, n, n + 1), st.redo_step)))
