"""The static configuration: :class:`Physics` (which mechanisms are compiled, with which
options) and :class:`NeighborConfig` (one neighbour list's settings).

:meth:`Physics.for_scene` derives it from a :class:`~fpsi_jax.model.scene.Scene`: a phase or
option the scene lacks is absent from the compiled program (not multiplied by zero). Every
option is checked here, before anything is compiled.
"""
from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass

import numpy as np

from . import motion
from .errors import ParameterError, fmt, number
from .options import (BondSection, BoundaryPressure, DensityDiffusion, Drag, FpiPressure,
                      FsiMethod, KernelKind, Side, Voidage, choose)
from .scene import Scene

# the kernels' support radius in units of h (both kernels of physics/kernels.py vanish at q = 2)
KERNEL_SUPPORT = 2.0
#: the SPH cells' allocation slack in scenes with grains in the fluid
#: (NeighborConfig.cell_multiplier)
GRAIN_CELL_MULTIPLIER = 2.0


@dataclass(frozen=True)
class NeighborConfig:
    """Static settings of one jax-md neighbour list (see ``neighbors.py``).

    r_cut   interaction cut-off (2·h_max for SPH)
    skin    extra radius (jax-md ``dr_threshold``); the list is rebuilt only when the
            particles' displacements since the last build no longer fit in a circle of
            radius skin/2 (neighbors.moved_past_half_skin)
    capacity_multiplier, extra_capacity   jax-md allocation slack; grown on overflow
    cell_multiplier   the cells' allocation slack (0: capacity_multiplier). Scenes with
                  grains in the fluid take 2: pore fluid packs as the bed moves (the
                  two-phase dam break's fullest cell, on the floor under the bed, went from
                  22 to 35 particles by 0.12 s), and regrowing the cells costs a recompile
                  and a redone chunk (8.7 s and ~5 s there), where wider cells cost the
                  rebuild's candidate pass (+16 % a step in that flow's surge; over its
                  0.2 s, 46 → 33 s: docs/performance.md, *Coupled scenes*)
    min_neighbors, min_cell_capacity   room per row and per cell at least (0: what the
                  allocation finds × the multiplier); set when a list overflowed
                  (``neighbors.grow``)
    origin, box   the domain rectangle: positions are shifted by ``origin`` into [0, box)
    row_block     rows per block of the rebuild's candidate pass (0: all rows at once;
                  the ``rebuild_block`` option of ``Physics.for_scene``)
    n_columns     only particles below this index are listed as neighbours (0: all). The SPH
                  family puts the grains last and no SPH sum reads a grain column (the grains'
                  own rows carry their coupling), so a scene with grains lists none: in a
                  packed bed a fluid row's ~30 grain entries would double its width
    fluid_only_rows  (first, stop, n_fluid): rows first … stop − 1 list only particles
                  below n_fluid ((): every row lists every column). The SPH family's
                  boundary and structure rows are read only for their fluid neighbours
                  (the wall's extrapolated pressure, the structure's pressure and
                  reaction), so they list no wall particle: a boundary row inside a
                  lattice finer than the fluid's set the list's width K for every row
    strips        the rebuild's candidates from five strips of cells of half the list
                  radius, contiguous in the particles' cell order (neighbors._strip_rows),
                  instead of jax-md's 3 × 3 cells of the list radius; the cell capacity is
                  then a strip's (the fullest strip × the multiplier). The SPH family's
                  rebuild reads 32–44 % fewer candidates so (docs/performance.md); the DEM
                  family, a few hundred discs, keeps jax-md's cells
    wall_width    the sums over the ``fluid_only_rows`` read only their first
                  ``wall_width`` slots (0: all K). A rebuild fills a row's slots from the
                  first, so the rest of a wall row is padding: a wall particle sees fluid
                  on one side only (elastic gate: 12 at the start, 19 in the flow, of
                  K = 50). Set by ``run.driver.setup`` from the scene's first positions ×
                  the capacity multiplier, and at least K/2 (neighbors.wall_width); a
                  rebuild that finds a wall row with more neighbours flags an overflow
                  like a full row, and ``neighbors.grow`` widens it
    """

    r_cut: float
    skin: float
    origin: tuple[float, float]
    box: tuple[float, float]
    capacity_multiplier: float = 1.25
    cell_multiplier: float = 0.0
    extra_capacity: int = 0
    min_neighbors: int = 0
    min_cell_capacity: int = 0
    row_block: int = 0
    n_columns: int = 0
    fluid_only_rows: tuple = ()
    strips: bool = False
    wall_width: int = 0

    @property
    def list_radius(self) -> float:
        """r_cut + skin: the radius pairs are listed within (jax-md's cell size too)."""
        return self.r_cut + self.skin


@dataclass(frozen=True)
class Parking:
    """Where particles that left through an open side wait (static; Scene.open_sides).

    A parked particle keeps its slot in every array but sits on a lattice of spacing
    ``spacing`` (more than any list radius) in a band ``gap`` above the domain, which both
    neighbour grids are extended to cover: it is nobody's neighbour, and nobody is its.
    Slot k (fluid particle i: k = i; disc j: k = n_fluid + j) is at
    (x0 + (k mod columns + ½)·spacing, y0 + (k div columns + ½)·spacing).
    """

    x0: float
    y0: float
    spacing: float
    columns: int
    rows: int

    @property
    def top(self) -> float:
        return self.y0 + (self.rows + 1) * self.spacing

    @staticmethod
    def for_domain(lo, hi, n_slots: int, list_radius: float) -> "Parking":
        s = 1.01 * list_radius
        columns = max(1, int((hi[0] - lo[0]) // s))
        rows = max(1, -(-n_slots // columns))
        return Parking(x0=float(lo[0]), y0=float(hi[1]) + s, spacing=s, columns=columns,
                       rows=rows)




def h_over_dp(scene) -> float:
    """η = h/Δp of the scene's fluid lattice (the median over its particles), with which a
    fluid particle's h follows its superficial volume among grains (Physics.pore_neighbours)."""
    return float(np.median(np.asarray(scene.fluid.h, float))
                 / float(scene.params.sph.dp))


#: the neighbour cut-off's room for h over the start's largest (Physics.h_margin)
H_MARGIN_DEFAULT = 1.05

#: scene-file and builder keywords whose Physics option has another name
ALIASES = {"coupling": "fsi"}

#: Physics options that are switches (true/false)
SWITCHES = ("xsph", "anticlump", "anticlump_boundary", "variable_h", "delta_sph",
            "artificial_viscosity", "wall_repulsion", "x64", "fpi", "lubrication",
            "wall_images", "sort_fluid", "transport_continuity", "dem_list_substeps",
            "structure_acceleration", "added_mass", "wall_reaction")
#: numeric Physics options: (lo, hi, lo_open, hi_open, integer)
RANGES = {"h_margin": (1.0, 2.0, False, False, False),
          "rho_tolerance": (0.0, 1.0, True, False, False),
          "skin": (0.0, 2.0, False, False, False),            # × h
          "capacity_multiplier": (1.0, 10.0, False, False, False),
          "dem_skin": (0.0, 2.0, False, False, False),        # × R_max
          "eps_floor": (0.0, 1.0, False, True, False),
          "pore_neighbours": (0.0, 1.0, False, False, False),
          "dem_substeps": (1, 10000, False, False, True),
          "pair_block": (0, 10**8, False, False, True),
          "rebuild_block": (0, 10**8, False, False, True),
          "shifting": (0.0, 0.5, False, False, False)}


#: rows per block of the SPH list rebuild's candidate pass on a CPU (the ``rebuild_block``
#: option): its (rows, 9C) candidate arrays are written out between its loops, and a block's
#: stay in cache (90k / 344k particles: 217 / 234 against 234 / 242 ns a particle-step;
#: docs/performance.md, *Pair passes in row blocks*)
CPU_REBUILD_BLOCK = 1024

#: fluid particles from which a chunk of steps runs on the fluid stored in cell order
#: (Physics.sort_fluid): below it the particle arrays stay in the CPU's cache whatever
#: their order (docs/performance.md, *Particle order*)
SORT_MIN_FLUID = 16 * 1024


def default_rebuild_block() -> int:
    """:data:`CPU_REBUILD_BLOCK` when JAX computes on a CPU, else 0 (one pass over all
    rows: an accelerator wants the widest arrays; cache blocking is a CPU matter)."""
    import jax
    return CPU_REBUILD_BLOCK if jax.default_backend() == "cpu" else 0


def check_options(opts: dict) -> dict:
    """Physics options checked by kind before anything is built: switches take true/false,
    numbers their range (:data:`RANGES`), choices one of their values (``fsi`` also None,
    ``dem_substeps`` None for "derived"). Returns the options with numbers as Python
    numbers."""
    out = {}
    for k, v in opts.items():
        if k in SWITCHES:
            if not isinstance(v, (bool, np.bool_)):
                raise ParameterError(f"{k} = {fmt(v)} is not true or false")
            v = bool(v)
        elif k in RANGES and not (k == "dem_substeps" and v is None):
            lo, hi, lo_open, hi_open, integer = RANGES[k]
            v = number(k, v, lo, hi, lo_open, hi_open, integer)
        elif k in Physics.CHOICES and not (k == "fsi" and v is None):
            v = choose(Physics.CHOICES[k], k, v)
        out[k] = v
    return out


def wall_force_rows(rows, scene) -> tuple:
    """The ``wall_force`` option checked against the scene: () or (a, b) with
    0 ≤ a < b ≤ the boundary particle count."""
    if rows is None or len(rows) == 0:
        return ()
    n_b = scene.boundary.n if scene.boundary is not None else 0
    ok = (len(rows) == 2 and all(isinstance(r, (int, np.integer)) for r in rows)
          and 0 <= rows[0] < rows[1] <= n_b)
    if not ok:
        raise ParameterError(f"wall_force = {fmt(rows)}; allowed: two boundary row indices "
                             f"(a, b) with 0 <= a < b <= {n_b}")
    return (int(rows[0]), int(rows[1]))


def held_disc_rows(rows, scene) -> tuple:
    """The ``disc_reaction`` option checked against the scene: () or the sorted indices of
    discs held at the start (clamped or kinematic: ``scene.solid.fixed``)."""
    if rows is None or (isinstance(rows, (list, tuple, np.ndarray)) and len(rows) == 0):
        return ()
    solid = scene.solid
    n = solid.n if solid is not None else 0
    fixed = np.asarray(solid.fixed, bool) if solid is not None else np.zeros(0, bool)
    ok = isinstance(rows, (list, tuple, np.ndarray)) and all(
        isinstance(r, (int, np.integer)) and 0 <= r < n and fixed[r] for r in rows)
    if not ok:
        raise ParameterError(f"disc_reaction = {fmt(rows)}; allowed: indices of discs "
                             f"held at the start (clamped or kinematic), 0 <= i < {n}")
    return tuple(sorted({int(r) for r in rows}))


def motion_windows(windows, scene) -> tuple:
    """The ``kinematic_motion`` option checked against the scene: each entry a
    :class:`~fpsi_jax.model.motion.Window` (or its plain (a, b, vx, vy, t_on, t_off)),
    :class:`~fpsi_jax.model.motion.Oscillation` or :class:`~fpsi_jax.model.motion.Track`
    of held discs a … b − 1 (:func:`~fpsi_jax.model.motion.canonical`)."""
    n = scene.solid.n if scene.solid is not None else 0
    fixed = np.asarray(scene.solid.fixed, bool) if n else np.zeros(0, bool)
    return tuple(motion.canonical(w, n, fixed) for w in windows or ())


def moving_discs(solid) -> tuple:
    """The discs free at the start, when a quarter or more of them are fixed (else (): all
    rows; Physics.moving_discs). Below that the saving is a few rows against one more
    gather and scatter per sum."""
    if solid is None:
        return ()
    free = ~np.asarray(solid.fixed, bool)
    if not free.any() or free.sum() > 0.75 * free.size:
        return ()
    return tuple(int(i) for i in np.flatnonzero(free))


@dataclass(frozen=True)
class Physics:
    """Static configuration: hashable, closed over by the compiled step.

    Phases present (n_fluid, n_boundary) and the switches of the SPH model:
      kernel               'wendland' (K28) or 'cubic'
      xsph                 XSPH position correction (K39)
      transport_continuity continuity with the velocity the particles drift with, v + δv_XSPH
                           (default; off: with v, as K32; docs/physics.md, *Continuity at the
                           velocity the particles move with*)
      shifting             particle shifting coefficient A, δr = −A h² ∇C each step
                           (sph.shifting_velocity; 0: off, the default; not in the seeds)
      anticlump            anti-clump term R_ij (W45, K38) on fluid–fluid pairs
      anticlump_boundary   also on fluid–boundary pairs (K advises against: off)
      variable_h           Dh/Dt = −h/(n_d ρ) Dρ/Dt (K37)
      delta_sph            δ-SPH density diffusion (off by default)
      density_diffusion    what δ-SPH diffuses: 'fourtakas' (default: ρ_j − ρ_i less its
                           hydrostatic part; Fourtakas et al. 2019) or 'molteni' (ρ_j − ρ_i;
                           Molteni & Colagrossi 2009), see sph.delta_pairs
      artificial_viscosity Monaghan α-viscosity (off by default; not in the seeds)
      wall_repulsion       short-range backstop against fluid creeping through a fixed wall
                           (sph.wall_repulsion_scalar; on by default, zero at rest; not in
                           the seeds); wall_range, its reach r0, is derived from the scene
                           (Scene.wall_range)
      boundary_pressure    'fixed' (W5/K5: ρ, P of boundary particles never change) or
                           'extrapolated' (Adami et al. 2012: P_b from the fluid, with the
                           hydrostatic correction)
      wall_force           boundary rows (a, b): the step records the fluid's force on
                           boundary particles a … b − 1 (BoundaryState.force; a force probe
                           on an obstacle sets it); () records none, the default
      wall_reaction        the step records the discs' force on each DEM wall
                           (WallState.reaction; a force probe on an obstacle with DEM
                           walls sets it); off by default
      kinematic_motion     prescribed motions of kinematic disc groups (model/motion.py):
                           motion.Window (a, b, vx, vy, t_on, t_off) (a [[kinematic]]
                           body's start and stop), motion.Oscillation (a wave maker's
                           sinusoidal stroke), motion.Track (a displacement time
                           series); stages.scheduled; () for none: kinematic discs keep
                           their velocity
      disc_reaction        indices of held (clamped or kinematic) discs: the step records
                           the force and moment the other discs' contacts and bonds put on
                           each (SolidState.reaction; a force probe on held discs sets it);
                           () records none, the default
      h_margin             the neighbour cut-off allows h to grow to h_margin·h0
      rho_tolerance        |ρ/ρ0 − 1| above this marks a run unstable
      x64                  float64 everywhere

    DEM phases (n_solid discs, n_bonds parallel bonds, n_walls line walls) and:
      dem_neighbors        the contact family's list (cut-off 2 R_max), None without discs
      bond_section         'slab' (2D, A = 2R̄t, I = (2/3)tR̄³) or 'circular'
                           (A = πR̄², I = πR̄⁴/4; K6.1's Itasca beam)
      moving_discs         indices of the discs free at the start when a quarter or more are
                           fixed (clamped or kinematic), else () for all: the contact and
                           wall sums of a DEM step run over these rows only (a fixed disc's
                           force is never read; a disc parked later keeps its row);
                           lubrication runs over the grains' rows

    Couplings:
      fsi, n_structure     fluid–structure method (options.FsiMethod) and structure disc count
      structure_acceleration  the structure discs' own acceleration a_S in their
                           extrapolated pressure, Adami's (g − a_S) term (default False:
                           g alone). A bonded disc's acceleration at the end of a step is
                           its lattice's vibration at the DEM sub-step's scale (the elastic
                           gate's discs: 530 m/s² RMS while the gate moves at ~10), which
                           the fluid cannot resolve; with it the gate's peak moved with the
                           steps (docs/design.md, *Time-step coefficients*)
      dem_substeps         DEM sub-steps per SPH step (multi-rate)
      dem_list_substeps    the DEM list's skin test at every sub-step (True) or once per
                           SPH step (False, the default): the list is rebuilt at the start
                           of a step when a disc's displacement since the build plus twice
                           the largest travel a disc's velocity and acceleration predict
                           for the step passes half the skin, and tested at every sub-step
                           of a step whose predicted travel alone does; otherwise the
                           sub-steps only track each disc's displacement, and a disc that
                           passed half the skin after all flags the chunk to be redone with
                           this switch on (Status.dem_stale; run.driver.grow). The test,
                           its two conditionals and the history remap made up a third of
                           a sub-step (docs/performance.md)
      fpi, n_grain         fluid–particle coupling of the grains (fpi.py): voidage in the
                           fluid equations (W42–43), pressure force (buoyancy), drag,
                           lubrication
      voidage              what the fluid equations see: 'area' (ε = 1 − Σ V_p W, default,
                           the physical one of a 2D bed) or 'mapped' (the equivalent 3D
                           packing's); the drag closure sees the 3D one either way (fpi.py)
      eps_floor            the fluid equations see max(ε, eps_floor) (the drag the true ε);
                           0 (none) unless a user raises it
      drag                 the grains' drag: 'sphere' (W19–W23, default) or 'cylinder'
                           (a disc as a cylinder per unit length); see fpi.py
      fpi_pressure         the grains' buoyancy: 'archimedes' (ρ_f V_p |g|; the default
                           where no two grains touch at the start),
                           'gradient' (−V_p ∇P of the SPH pressure) or 'shared' (each fluid
                           cell's pressure force, ε to its fluid, 1 − ε to its grains, with
                           the mixture's continuity: energy-conserving, stable in packed
                           beds; the default where grains touch at the start); see fpi.py
                           and docs/physics.md, *Which pressure coupling*
      lubrication          W24 between wet grains (cut-off and regularisation in Params.fpi)
      added_mass           the added-mass force on wet grains, C_a ρ_f V_p (Du/Dt − dv_p/dt)
                           with C_a = Params.fpi.added_mass, and its reaction on the fluid
                           (off by default: the seeds have none; fpi.py)
      pore_neighbours      φ: with the 'shared' pressure, a fluid particle among grains
                           keeps at least φ of the clear lattice's neighbours, its h growing
                           with its superficial volume, h = η √max(φ m/(ερ), Δp² ρ0/ρ)
                           (sph.smoothing_length_among_grains; η = h_over_dp, derived from
                           the scene): water that runs into a bed's pores stays resolved;
                           default 0.5; 0: off, h follows ρ alone (K37)
      wall_images          the grains' mirror images in the one-sided DEM walls count in the
                           fluid's solid fraction (fpi.wall_images): the part of a grain's
                           kernel inside a wall is put back on the fluid's side

    How the SPH pair sums are cut (no effect on the result beyond float round-off):
      pair_block           rows per block of the density and momentum pair passes
                           (pairs.over_row_blocks). Default 0: all rows in one pass, which
                           is the fastest at every size measured (their pair terms stay
                           inside one fused loop per pass; docs/performance.md)
      rebuild_block        rows per block of the SPH list rebuild's candidate pass, whose
                           (rows, 9C) candidate arrays are written out between its loops.
                           Default :data:`CPU_REBUILD_BLOCK` on a CPU, 0 on an accelerator;
                           either takes one pass below pairs.MIN_BLOCKS blocks of rows
      sort_fluid           each chunk of steps runs on the fluid re-stored in cell order
                           (solver.order; the caller sees the scene's order). Default: on
                           from :data:`SORT_MIN_FLUID` fluid particles

    The domain (health checks) and its open sides:
      domain_lo, domain_hi the rectangle every particle in the computation stays inside
      open_sides           sides (options.Side) a particle may leave through: it is then
                           parked (``parking``) and counted, not an error
      parking              :class:`Parking` of the scene with open sides, else None
      rim                  (x_lo, x_hi, y_top) of the boundary particles when the top is
                           open: beside them (x < x_lo or x > x_hi) and above y_top a particle
                           has gone over the walls, and leaves through the open top there
                           (a splash over a wall is not a leak through it); None without
                           an open top or a boundary, or when a particle starts out there
    """

    n_fluid: int
    n_boundary: int
    neighbors: NeighborConfig | None
    kernel: KernelKind = KernelKind.WENDLAND
    xsph: bool = True
    transport_continuity: bool = True
    anticlump: bool = True
    anticlump_boundary: bool = False
    variable_h: bool = True
    delta_sph: bool = False
    density_diffusion: DensityDiffusion = DensityDiffusion.FOURTAKAS
    artificial_viscosity: bool = False
    wall_repulsion: bool = True
    wall_range: float = 0.0
    boundary_pressure: BoundaryPressure = BoundaryPressure.FIXED
    h_margin: float = H_MARGIN_DEFAULT
    rho_tolerance: float = 0.3
    x64: bool = False
    n_solid: int = 0
    n_bonds: int = 0
    n_walls: int = 0
    dem_neighbors: NeighborConfig | None = None
    bond_section: BondSection = BondSection.SLAB
    moving_discs: tuple = ()
    fsi: FsiMethod | None = None
    n_structure: int = 0
    structure_acceleration: bool = False
    dem_substeps: int = 1
    dem_list_substeps: bool = False
    fpi: bool = False
    n_grain: int = 0
    voidage: Voidage = Voidage.AREA
    fpi_pressure: FpiPressure = FpiPressure.ARCHIMEDES
    drag: Drag = Drag.SPHERE
    eps_floor: float = 0.0
    lubrication: bool = True
    added_mass: bool = False
    pore_neighbours: float = 0.5
    h_over_dp: float = 0.0
    wall_images: bool = True
    domain_lo: tuple | None = None
    domain_hi: tuple | None = None
    open_sides: tuple = ()
    parking: Parking | None = None
    rim: tuple | None = None
    pair_block: int = 0
    sort_fluid: bool = False
    shifting: float = 0.0
    wall_force: tuple = ()
    wall_reaction: bool = False
    disc_reaction: tuple = ()
    kinematic_motion: tuple = ()

    OPTIONS = ("kernel", "xsph", "anticlump", "anticlump_boundary", "variable_h", "delta_sph",
               "artificial_viscosity", "wall_repulsion", "boundary_pressure", "h_margin",
               "rho_tolerance", "x64", "skin", "capacity_multiplier", "bond_section",
               "dem_skin", "fsi", "dem_substeps", "fpi", "voidage", "lubrication",
               "fpi_pressure", "eps_floor", "drag", "pair_block", "rebuild_block",
               "density_diffusion",
               "wall_images", "shifting", "sort_fluid", "transport_continuity", "added_mass",
               "pore_neighbours",
               "dem_list_substeps", "structure_acceleration", "wall_force",
               "wall_reaction", "disc_reaction", "kinematic_motion")

    CHOICES = {"kernel": KernelKind, "boundary_pressure": BoundaryPressure,
               "bond_section": BondSection, "fsi": FsiMethod, "voidage": Voidage,
               "fpi_pressure": FpiPressure, "drag": Drag,
               "density_diffusion": DensityDiffusion}

    def __post_init__(self):
        # a Physics built by hand may name its choices by string: make them members, so the
        # compiled code's identity comparisons (phys.fsi is FsiMethod.EXTRAPOLATED) hold
        for key, kind in self.CHOICES.items():
            value = getattr(self, key)
            if value is not None and not isinstance(value, kind):
                object.__setattr__(self, key, choose(kind, key, value))

    @classmethod
    def for_scene(cls, scene: Scene, **overrides) -> "Physics":
        """Derive the static configuration from a scene (scene.options, then overrides)."""
        opts = {**scene.options, **overrides}
        unknown = set(opts) - set(cls.OPTIONS)
        if unknown:
            named = [f"{k!r} is the option {ALIASES[k]!r} here" for k in sorted(unknown)
                     if k in ALIASES]
            hint = f" ({'; '.join(named)})" if named else ""
            raise ParameterError(f"unknown Physics option(s) {sorted(unknown)}{hint}; "
                                 f"allowed: {', '.join(cls.OPTIONS)}")
        opts = check_options(opts)
        if "wall_force" in opts:
            opts["wall_force"] = wall_force_rows(opts["wall_force"], scene)
        if "disc_reaction" in opts:
            opts["disc_reaction"] = held_disc_rows(opts["disc_reaction"], scene)
        if "kinematic_motion" in opts:
            opts["kinematic_motion"] = motion_windows(opts["kinematic_motion"], scene)
        # 0.4 h: with the fluid-only step (3.5× physics.md's) a 0.25 h skin was rebuilt every
        # ~5 steps of the 24k dam break and overflowed to K = 48; 0.4 h measured fastest
        # (0.25 / 0.3 / 0.35 / 0.4 / 0.45 / 0.6 h: 0.51 / 0.94 / 0.96 / 0.98 / 0.81 / 0.83 M
        # particle-steps/s on one core). A structure the fluid moves keeps physics.md's step
        # and the 0.25 h skin that suits it (Scene.fsi_coupled).
        skin_factor = opts.pop("skin", 0.25 if scene.fsi_coupled else 0.4)
        cap = opts.pop("capacity_multiplier", NeighborConfig.capacity_multiplier)
        dem_skin = float(opts.pop("dem_skin", 0.5))
        rebuild_block = int(opts.pop("rebuild_block", default_rebuild_block()))
        if "sort_fluid" not in opts:
            opts["sort_fluid"] = scene.fluid is not None and scene.fluid.n >= SORT_MIN_FLUID
        h_margin = float(opts.get("h_margin", H_MARGIN_DEFAULT))
        if opts.get("dem_substeps", 1) is None:
            opts.pop("dem_substeps")
        method = opts.get("fsi")
        n_structure = 0
        if method is not None:
            if scene.fluid is None or scene.solid is None:
                raise ParameterError("option fsi needs both fluid and solid discs in the scene")
            n_structure = int(scene.solid.structure_indices().size)
            if n_structure == 0:
                raise ParameterError("option fsi is set but no disc is marked as structure")
        n_grain = 0
        if opts.get("fpi"):
            if scene.fluid is None or scene.solid is None:
                raise ParameterError("option fpi needs both fluid and solid discs in the scene")
            if scene.params.fpi is None:
                raise ParameterError("option fpi is set but params.fpi is None")
            n_grain = int(scene.solid.grain_indices().size)
            if n_grain == 0:
                raise ParameterError("option fpi is set but no disc is a grain")
            both = np.intersect1d(scene.solid.grain_indices(), scene.solid.structure_indices())
            if method is not None and both.size:
                raise ParameterError(f"disc {int(both[0])} is both a grain and structure")
            if "fpi_pressure" not in opts:   # each is unstable or inexact for the other case
                opts["fpi_pressure"] = choose(
                    FpiPressure, "fpi_pressure",
                    "shared" if scene.solid.grains_in_contact() else "archimedes")
        lo = tuple(map(float, scene.domain_lo))
        hi = tuple(map(float, scene.domain_hi))
        box = tuple(float(h - l) for h, l in zip(hi, lo))
        nb = dem_nb = None
        if scene.fluid is not None:
            h_all = [b.h for b in (scene.fluid, scene.boundary) if b is not None]
            h_max = float(max(np.max(h) for h in h_all)) * h_margin
            n_columns = 0
            if n_grain:     # fluid, boundary, structure: the rows the SPH sums read
                n_columns = sum(b.n for b in (scene.fluid, scene.boundary) if b is not None)
                n_columns += n_structure
            n_f = scene.fluid.n
            n_walls = n_structure + (scene.boundary.n if scene.boundary is not None else 0)
            nb = NeighborConfig(r_cut=KERNEL_SUPPORT * h_max, skin=skin_factor * h_max / h_margin,
                                origin=lo, box=box, capacity_multiplier=float(cap),
                                cell_multiplier=GRAIN_CELL_MULTIPLIER if n_grain else 0.0,
                                row_block=rebuild_block, n_columns=n_columns,
                                fluid_only_rows=(n_f, n_f + n_walls, n_f) if n_walls else (),
                                strips=True)
        if scene.solid is not None:
            r_max = float(np.max(scene.solid.radius))
            reach = 1.0
            if n_grain and opts.get("lubrication", True):
                reach += float(scene.params.fpi.lub_cutoff)   # W24 acts up to a gap cut-off
            dem_nb = NeighborConfig(r_cut=2.0 * r_max * reach, skin=dem_skin * r_max, origin=lo,
                                    box=box, capacity_multiplier=float(cap))
        sides = tuple(getattr(scene, "open_sides", ()) or ())
        parking = None
        if sides:
            n_slots = sum(b.n for b in (scene.fluid, scene.solid) if b is not None)
            radius = max(c.list_radius for c in (nb, dem_nb) if c is not None)
            parking = Parking.for_domain(lo, hi, n_slots, radius)
            grid = (box[0], parking.top - lo[1])       # the lists' grid covers the band
            nb = nb and dataclasses.replace(nb, box=grid)
            dem_nb = dem_nb and dataclasses.replace(dem_nb, box=grid)
        rim = None
        if Side.TOP in sides and scene.boundary is not None and scene.boundary.n:
            xb = np.asarray(scene.boundary.x, float)
            rim = (float(xb[:, 0].min()), float(xb[:, 0].max()), float(xb[:, 1].max()))
            xs = [np.asarray(b.x, float) for b in (scene.fluid, scene.solid) if b is not None]
            if any(np.any(((x[:, 0] < rim[0]) | (x[:, 0] > rim[1])) & (x[:, 1] > rim[2]))
                   for x in xs):
                rim = None          # the walls do not hold everything: no rim to go over
        return cls(domain_lo=lo, domain_hi=hi, open_sides=sides, parking=parking, rim=rim,
                   n_fluid=scene.fluid.n if scene.fluid else 0,
                   n_boundary=scene.boundary.n if scene.boundary else 0,
                   neighbors=nb, wall_range=scene.wall_range(),
                   n_solid=scene.solid.n if scene.solid else 0,
                   n_bonds=scene.bonds.n if scene.bonds else 0,
                   n_walls=scene.walls.n if scene.walls else 0,
                   dem_neighbors=dem_nb, n_structure=n_structure, n_grain=n_grain,
                   h_over_dp=h_over_dp(scene) if n_grain else 0.0,
                   moving_discs=moving_discs(scene.solid), **opts)

    @property
    def has_fluid(self) -> bool:
        return self.n_fluid > 0

    @property
    def has_boundary(self) -> bool:
        return self.n_boundary > 0

    def mechanisms(self) -> tuple[str, ...]:
        """Names of the mechanisms compiled into the step (for logs and tests)."""
        m = []
        if self.has_fluid:
            m += ["sph.continuity", "sph.eos", "sph.pressure", "sph.viscosity"]
            m += ["sph.anticlump"] if self.anticlump else []
            m += ["sph.xsph"] if self.xsph else []
            m += ["sph.variable_h"] if self.variable_h else []
            m += ["sph.delta"] if self.delta_sph else []
            m += ["sph.artificial_viscosity"] if self.artificial_viscosity else []
        if self.has_boundary:
            m += [f"boundary.{self.boundary_pressure}"]
            m += ["sph.wall_repulsion"] if self.wall_repulsion and self.has_fluid else []
        if self.has_solid:
            m += ["dem.contacts", "dem.local_damping"]
            m += ["dem.walls"] if self.n_walls else []
            m += ["bonds"] if self.n_bonds else []
        if self.has_fsi:
            m += [f"fsi.{self.fsi}"]
        if self.has_fpi:
            m += ["fpi.voidage", f"fpi.drag.{self.drag}", f"fpi.buoyancy.{self.fpi_pressure}",
                  "fpi.reaction"]
            m += ["fpi.lubrication"] if self.lubrication else []
            m += ["fpi.added_mass"] if self.added_mass else []
            m += (["sph.pore_neighbours"] if self.pore_neighbours > 0 and self.h_over_dp > 0
                  and self.fpi_pressure is FpiPressure.SHARED else [])
        return tuple(m)

    @property
    def has_fpi(self) -> bool:
        return bool(self.fpi) and self.n_grain > 0

    @property
    def has_fsi(self) -> bool:
        return self.fsi is not None and self.n_structure > 0

    @property
    def has_solid(self) -> bool:
        return self.n_solid > 0

    def to_json(self) -> str:
        d = dataclasses.asdict(self)
        return json.dumps(d)
