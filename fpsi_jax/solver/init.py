"""The initial state of a run: arrays on the device, neighbour lists allocated, the first
rates evaluated."""
from __future__ import annotations

import dataclasses
import functools

import jax
import jax.numpy as jnp
import numpy as np

from ..model.config import Physics
from ..model.params import Params
from ..model.scene import Scene
from ..model.state import (BondState, BoundaryState, FluidState, FpiState, FsiState,
                           SolidState, State, Status, WallState)
from ..physics import bonds as bonds_law
from ..physics import fpi, kernels
from . import neighbors, stages


def family_positions(scene: Scene, phys: Physics) -> np.ndarray:
    """The first positions of the SPH family in list order (stages.sph_positions): fluid,
    boundary, structure discs (with a fluid–structure coupling), grains (with FPI)."""
    parts = [scene.fluid.x]
    if scene.boundary is not None:
        parts.append(scene.boundary.x)
    if phys.has_fsi:
        parts.append(scene.solid.x[scene.solid.structure_indices()])
    if phys.has_fpi:
        parts.append(scene.solid.x[scene.solid.grain_indices()])
    return np.concatenate(parts, axis=0)


def breakable(phys: Physics, params: Params) -> bool:
    """Whether the scene has bonds that can break: a strength σ̄_c or τ̄_c below the
    unbreakable default 1e30 (BondParams)."""
    if not phys.n_bonds or params.bond is None:
        return False
    return bool(min(np.min(np.asarray(params.bond.sigma_c, float)),
                    np.min(np.asarray(params.bond.tau_c, float))) < 1.0e30)


def room_for_breakage(phys: Physics, params: Params) -> Physics:
    """``phys`` whose DEM list starts with the room a broken structure's discs take
    (neighbors.room_for_broken_discs) where ``params`` lets bonds break, so the run does
    not recompile when they do; not with grains, whose packed bed sizes the list already
    (FPSI I's DEM sub-step took 37 % longer with that room, and its list never regrew
    without it)."""
    if phys.dem_neighbors is None or phys.n_grain or not breakable(phys, params):
        return phys
    return dataclasses.replace(
        phys, dem_neighbors=neighbors.room_for_broken_discs(phys.dem_neighbors))


def fit_wall_width(scene: Scene, phys: Physics) -> Physics:
    """``phys`` with the width the sums read of the SPH list's wall rows
    (NeighborConfig.wall_width) measured on the scene's first positions."""
    cfg = phys.neighbors
    if cfg is None or not cfg.fluid_only_rows:
        return phys
    width = neighbors.wall_width(cfg, family_positions(scene, phys))
    return dataclasses.replace(phys, neighbors=dataclasses.replace(cfg, wall_width=width))


def init_state(scene: Scene, phys: Physics, params: Params) -> State:
    """Arrays on device, neighbour lists allocated, initial rates evaluated."""
    return initial_rates(phys, allocated_state(scene, phys), params)


def allocated_state(scene: Scene, phys: Physics) -> State:
    """The scene's arrays on the device with the neighbour lists allocated for ``phys``, the
    rates not yet evaluated (:func:`initial_rates`): the shapes of every later state."""
    dt_ = stages.dtype(phys)
    a = lambda v: jnp.asarray(v, dtype=dt_)
    z = jnp.zeros_like
    fluid = boundary = solid = bonds = walls = snbrs = fsi_state = fpi_state = None
    if scene.fluid is not None:
        fl = scene.fluid
        b = scene.boundary
        boundary = None if b is None else BoundaryState(
            x=a(b.x), rho=a(b.rho), p=a(b.p), h=a(b.h), mass=a(b.mass),
            force=a(np.zeros((b.n, 2))) if phys.wall_force else None)
        x = a(fl.x)
        fluid = FluidState(x=x, v=a(fl.v), rho=a(fl.rho), h=a(fl.h), mass=a(fl.mass),
                           acc=z(x), xsph=z(x),
                           t_out=a(np.full(fl.n, -1.0)) if phys.open_sides else None)
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
                wet=a(np.zeros(ng)), force=a(np.zeros((ng, 2))),
                m_a=a(np.zeros(ng)) if phys.added_mass else None,
                du_f=a(np.zeros((ng, 2))) if phys.added_mass else None,
                added=a(np.zeros((ng, 2))) if phys.added_mass else None)
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
            shear=jnp.zeros(snbrs.idx.shape, dt_), wall_shear=jnp.zeros((so.n, n_w), dt_),
            t_out=a(np.full(so.n, -1.0)) if phys.open_sides else None, x_ref=x, u=z(x),
            reaction=a(np.zeros((so.n, 3))) if phys.disc_reaction else None)
        if scene.walls is not None:
            walls = WallState(a=a(scene.walls.a), b=a(scene.walls.b),
                              side=a(scene.walls.sides()),
                              image_side=(None if scene.walls.image_side is None
                                          else a(scene.walls.image_sides())),
                              reaction=(a(np.zeros((scene.walls.n, 3))) if phys.wall_reaction
                                        else None))
        if scene.bonds is not None:
            i = jnp.asarray(scene.bonds.i, jnp.int32)
            j = jnp.asarray(scene.bonds.j, jnp.int32)
            d0, e0 = bonds_law.rest_geometry(x, i, j)
            nb = scene.bonds.n
            bonds = BondState(i=i, j=j, d0=d0, e0=e0, intact=jnp.ones(nb, bool),
                              fn=jnp.zeros(nb, dt_), fs=jnp.zeros(nb, dt_), m=jnp.zeros(nb, dt_),
                              t_break=jnp.full(nb, -1.0, dt_), mode=jnp.zeros(nb, jnp.int32))
    state = State(t=a(0.0), step=jnp.zeros((), jnp.int32), fluid=fluid, boundary=boundary,
                  nbrs=None, status=Status.ok(), solid=solid, bonds=bonds, solid_nbrs=snbrs,
                  walls=walls, fsi=fsi_state, fpi=fpi_state)
    if fluid is not None:
        state = state.replace(nbrs=neighbors.allocate(phys.neighbors, stages.sph_positions(state)))
    return stages.with_walls_near(phys, state)


@functools.partial(jax.jit, static_argnums=0)
def initial_rates(phys: Physics, state: State, params: Params) -> State:
    """The voidage (with grains) and :func:`refresh_rates` of an :func:`allocated_state`, as
    one compiled program. Run eagerly, the same evaluation dispatched (and compiled) each of
    its ~1 300 primitives on its own: 12.6 s of the coarse gate's 17 s set-up."""
    if phys.has_fpi:
        state = state.replace(fpi=state.fpi.replace(eps=initial_voidage(phys, state)))
    return refresh_rates(phys, state, params)


def initial_voidage(phys: Physics, state: State):
    """The fluid voidage at the state's positions (what the first step's ε_old must be). The
    scene's fluid densities are intrinsic ρ; builders give the particles mass ε ρ0 Δx²."""
    f, fp = state.fluid, state.fpi
    n_sph = state.nbrs.idx.shape[0] - fp.idx.shape[0]
    x_p = state.solid.x[fp.idx]
    rows = fpi.grain_rows(kernels.get(phys.kernel), f.x, f.h, f.mass / f.rho,
                          x_p, state.nbrs.idx[n_sph:], phys.n_fluid,
                          stages.grain_images(phys, state, x_p))
    r = state.solid.radius[fp.idx]
    eps = fpi.fluid_voidage(rows.ws, jnp.pi * r * r, rows.idx, rows.valid, phys.n_fluid,
                            phys.voidage)
    return jnp.maximum(eps, phys.eps_floor)


def refresh_rates(phys: Physics, state: State, params: Params) -> State:
    """Recompute the stored accelerations (and XSPH correction, and the fluid's force on the
    structure) at the current state (after init or a reallocation); positions, densities, h
    and histories are left as they are."""
    if phys.has_fluid:
        ev = stages.evaluate_fluid(phys, params, state, 0.0)
        state = state.replace(fluid=state.fluid.replace(acc=ev.fluid.acc, xsph=ev.fluid.xsph),
                              boundary=ev.boundary, fsi=ev.fsi, fpi=ev.fpi)
    if phys.has_solid:
        ev = stages.disc_forces(phys, params, state, 0.0, stages.fluid_force_on_discs(phys, state),
                                stages.wet_grains(phys, state),
                                stages.grain_added_mass(phys, state))
        state = state.replace(solid=state.solid.replace(acc=ev.solid.acc, alpha=ev.solid.alpha))
    return state
