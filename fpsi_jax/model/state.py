"""The dynamic state of a run: a pytree split by phase (absent phases are ``None``)."""
from __future__ import annotations

from typing import Any

import jax.numpy as jnp

from .tree import pytree_dataclass


@pytree_dataclass
class FluidState:
    """SPH fluid: positions, velocities, densities, smoothing lengths, masses and the
    acceleration and XSPH correction of the last evaluation (the leapfrog's first kick).
    ``t_out`` (n,), in scenes with open sides only: −1 while the particle is in the
    computation, the time it left through an open side once it is parked (None: no open
    side)."""

    x: Any
    v: Any
    rho: Any
    h: Any
    mass: Any
    acc: Any
    xsph: Any
    t_out: Any = None


@pytree_dataclass
class BoundaryState:
    """Fixed SPH boundary particles (≥ 2 layers). ``p``/``rho`` are constant in the 'fixed'
    mode (W5, K5 method 1) and re-extrapolated every step in the 'extrapolated' mode.
    ``force`` (n_b, 2), only with Physics.wall_force = (a, b) (else None): the fluid's force
    on boundary particles a … b − 1 at the last SPH evaluation, F_B = −Σ_F m_F a_{F←B}
    (fsi.reaction), zero on the other rows."""

    x: Any
    rho: Any
    p: Any
    h: Any
    mass: Any
    force: Any = None


@pytree_dataclass
class SolidState:
    """DEM discs (grains and structure). ``theta`` is the rotation since the start (the bonds'
    co-rotational law needs it); ``acc``/``alpha`` are the linear and angular accelerations of
    the last evaluation (the leapfrog's first kick). ``shear`` is the contact shear-force
    history aligned with the contact neighbour list (n × K, keyed by the pair: it is
    re-addressed on every rebuild), ``wall_shear`` the same for the walls (n × n_walls).
    ``t_out`` as the fluid's: the time a disc left through an open side (−1: in; None:
    the scene has no open side).

    ``x_ref`` (n, 2) the positions at the start and ``u`` (n, 2) the displacement since
    then: the drift updates u and sets x = x_ref + u, and the bonds read their stretch from
    u (physics.bonds.bond_loads). In float32 a coordinate of 0.6 m is held to 6·10⁻⁸ m,
    while a stiff bond's disc moves 10⁻⁷ m in a DEM step: drifting x itself rounded every
    step's motion by up to half of it and the rounding, through springs of 10⁷ N/m per
    metre, heated a standing bonded wall until its bonds cracked under its own weight. A
    displacement of millimetres is held to 10⁻¹⁰ m.

    ``reaction`` (n, 3), only with Physics.disc_reaction (else None): the force (F_x, F_y)
    the free discs' contacts and the bonds put on each held disc that option lists, and
    its moment about the origin, x × F + τ, the mean over the last step's DEM sub-steps
    (the impulse over the step / Δt), as WallState.reaction for walls; zero on the other
    rows."""

    x: Any
    v: Any
    omega: Any
    theta: Any
    acc: Any
    alpha: Any
    radius: Any
    mass: Any
    inertia: Any
    fixed: Any
    f_ext: Any
    shear: Any
    wall_shear: Any
    t_out: Any = None
    x_ref: Any = None
    u: Any = None
    reaction: Any = None

    def moved_to(self, x):
        """The discs placed at ``x`` (n, 2), their displacement u = x − x_ref with them
        (whoever moves discs other than the drift: parking, a test's set-up)."""
        return self.replace(x=x, u=None if self.x_ref is None else x - self.x_ref)


@pytree_dataclass
class BondState:
    """Parallel bonds: disc indices, rest length and direction, intact flags, the forces of
    the last evaluation (F̄_n tension positive, F̄_s, M̄) and the break record (time and mode:
    0 intact, 1 tension, 2 shear)."""

    i: Any
    j: Any
    d0: Any
    e0: Any
    intact: Any
    fn: Any
    fs: Any
    m: Any
    t_break: Any
    mode: Any


@pytree_dataclass
class WallState:
    """DEM line-segment walls a[k] → b[k] (fixed) and their active sides (w,): +1 the left
    of a → b, −1 the right, 0 both (scene.WallBlock); ``image_side`` (w,) the fluid's side
    for the grains' wall images (WallBlock.image_sides; None: ``side``). ``near`` (c,) int32: the free discs
    that may touch a wall until the DEM list is next rebuilt (physics.dem.walls_near at
    the list's build positions), padded with n_solid; ``n_near`` (int32 scalar) how many
    there are. The sub-steps evaluate the wall contacts of those discs only, of none
    while n_near = 0, and of every disc while n_near > c. None: always every disc.
    ``reaction`` (w, 3), only with Physics.wall_reaction (else None): the discs' force on
    each wall (F_x, F_y) and its moment about the origin, Σ c × F with c the contact point
    (physics.dem.wall_contacts), the mean over the last step's DEM sub-steps (the impulse
    the wall took over the step / Δt)."""

    a: Any
    b: Any
    side: Any = None
    image_side: Any = None
    near: Any = None
    n_near: Any = None
    reaction: Any = None


@pytree_dataclass
class FsiState:
    """Structure discs as SPH particles (``fsi.py``): which discs (``idx`` into the solid
    arrays), their SPH mass ρ0 V_S, smoothing length, density and pressure (constant for the
    stationary method, K41 every step for the pressure approximation), and ``force``, the
    fluid's force on each of them at the last SPH evaluation: the DEM sub-steps hold it."""

    idx: Any
    mass: Any
    h: Any
    rho: Any
    p: Any
    force: Any


@pytree_dataclass
class FpiState:
    """Grains in the fluid (``fpi.py``): which discs (``idx`` into the solid arrays; their
    volume πR² and diameter 2R come from the disc radius), the fluid voidage ε of every fluid particle (W2, what the
    fluid equations W42–W43 use), and at the last SPH evaluation each grain's voidage ε_p
    (W18), Shepard fluid velocity ū_f (W21), wetness Σ_f V_f W_pf (0: dry) and ``force``,
    the fluid's force, pressure (buoyancy) + drag (W19), which the DEM sub-steps hold.
    With the added mass (Physics.added_mass; else None): ``m_a`` (n_g,), each grain's added
    mass at the last evaluation (C_a ρ_f V_p, or less where its fluid cannot exchange that
    much stably: fpi.added_mass_limit), ``du_f`` (n_g, 2), the Shepard fluid acceleration
    Du/Dt at each grain (its m_a Du/Dt is in ``force``), and ``added`` (n_g, 2), the
    added-mass force m_a (Du/Dt − Δv_p/Δt) the grain took over the last step's sub-steps,
    whose reaction goes to the fluid."""

    idx: Any
    eps: Any
    eps_p: Any
    u_f: Any
    wet: Any
    force: Any
    m_a: Any = None
    du_f: Any = None
    added: Any = None


BREAK_MODES = {0: "intact", 1: "tension", 2: "shear", 3: "a disc left the domain"}


# Status codes: what went wrong first, for the host's error message.
STATUS_CODES = {
    0: "ok",
    1: "position is not finite",
    2: "velocity is not finite",
    3: "density is not finite",
    4: "density left the allowed band |rho/rho0 - 1| <= rho_tolerance",
    5: "particle left the domain through a closed side",
    6: "solid position is not finite",
    7: "solid velocity or rotation is not finite",
    8: "solid particle left the domain through a closed side",
    9: "solid particle crossed a wall (a contact too soft for the blow: a disc of mass M "
       "at speed v presses v√(M/kn) into a wall, so raise [contacts] kn)",
}


@pytree_dataclass
class Status:
    """Health of a rollout, updated every step inside the scan.

    bad/step/particle/code  first step where a particle went bad, and which one and why
    overflow                the neighbour list overflowed (the chunk must be redone)
    dem_stale               a disc moved past half the DEM list's skin between the list's
                            checks once per SPH step (Physics.dem_list_substeps; the chunk
                            is redone with the check at every DEM sub-step; overflow is set
                            with it)
    h_exceeded              a smoothing length outgrew the neighbour cut-off (redo)
    redo_step               first step not computed exactly: an overflow's step, or the step
                            after h outgrew the cut-off (−1: none)
    rebuilds, dem_rebuilds  rebuilds of the SPH and of the DEM neighbour list so far
    sph_need, dem_need      (3,) int32: the most neighbours of a particle, the most
                            particles in a cell and the most neighbours of a wall row
                            (NeighborConfig.fluid_only_rows) that any rebuild of the SPH /
                            DEM list has found, before the cut to capacity: an overflowed
                            list is regrown to fit them (``neighbors.grow``)
    """

    bad: Any
    step: Any
    particle: Any
    code: Any
    overflow: Any
    h_exceeded: Any
    rebuilds: Any
    redo_step: Any
    sph_need: Any
    dem_need: Any
    dem_stale: Any = None
    dem_rebuilds: Any = None

    @staticmethod
    def ok():
        z = jnp.zeros((), jnp.int32)
        f = jnp.zeros((), bool)
        return Status(bad=f, step=z - 1, particle=z - 1, code=z, overflow=f, h_exceeded=f,
                      rebuilds=z, redo_step=z - 1, sph_need=jnp.zeros((3,), jnp.int32),
                      dem_need=jnp.zeros((3,), jnp.int32), dem_stale=f, dem_rebuilds=z)

    def must_redo(self) -> bool:
        """Host side: the chunk must be redone with larger lists, i.e. a list overflowed
        (or h outgrew the cut-off) and no particle had gone bad before the first step this
        made inexact (``redo_step``). A run that went unstable first is diagnosed as such:
        its state up to the bad step was computed with every pair, and regrowing the lists
        of a blown-up run only compiles ever larger programs (the tank at 12× its step:
        6 regrowths and 13 s before the diagnosis when regrowing first, 1 and 7 s this way)."""
        if not (bool(self.overflow) or bool(self.h_exceeded)):
            return False
        return not (bool(self.bad) and int(self.step) < int(self.redo_step))


@pytree_dataclass
class State:
    """Everything that changes during a run. ``nbrs`` is the jax-md neighbour list of the SPH
    family (rows: fluid, boundary, structure particles, then grains), ``solid_nbrs`` that of the DEM contacts."""

    t: Any
    step: Any
    fluid: FluidState | None
    boundary: BoundaryState | None
    nbrs: Any
    status: Status
    solid: SolidState | None = None
    bonds: BondState | None = None
    solid_nbrs: Any = None
    walls: WallState | None = None
    fsi: FsiState | None = None
    fpi: FpiState | None = None
