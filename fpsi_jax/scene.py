"""Scenes (host-side description) and the static ``Physics`` derived from them.

A :class:`Scene` holds numpy arrays per phase, the default :class:`~fpsi_jax.params.Params`
and a few settings. :meth:`Physics.for_scene` turns it into the static configuration that
decides which mechanisms are compiled: a phase or option the scene lacks is absent from the
compiled program (not multiplied by zero).
"""
from __future__ import annotations

import dataclasses
import json
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from . import kernels
from .params import ParameterError, Params


@dataclass
class FluidBlock:
    """SPH fluid particles: positions (n, 2), velocities, densities, masses, smoothing lengths."""

    x: np.ndarray
    v: np.ndarray
    rho: np.ndarray
    mass: np.ndarray
    h: np.ndarray

    @property
    def n(self) -> int:
        return int(self.x.shape[0])


@dataclass
class BoundaryBlock:
    """Fixed SPH boundary particles (W5, K5 method 1); ≥ 2 layers. ``p`` is their pressure."""

    x: np.ndarray
    rho: np.ndarray
    p: np.ndarray
    mass: np.ndarray
    h: np.ndarray

    @property
    def n(self) -> int:
        return int(self.x.shape[0])


@dataclass
class SolidBlock:
    """DEM discs (grains and bonded structures; physics.md §DEM).

    x, v (n, 2), omega (n,)   positions, velocities, angular velocities
    radius, mass, inertia     per disc (per unit thickness unless the scene says otherwise)
    fixed (n,) bool           kinematic discs: they keep their initial velocity ``v`` whatever
                              the forces (v = 0: clamped), e.g. a gate lifted at constant speed
    f_ext (n, 2)              external force (e.g. a tip load), ramped by dem.load_ramp
    structure (n,) bool       discs that take part in the SPH sums as boundary-like particles
                              when the scene couples fluid and structure (Scene.options
                              'fsi'); None: all of them
    sph_volume (n,)           area each structure disc stands for in the SPH sums (its packing
                              cell, e.g. d² for a square packing); None: (2R)²
    grain (n,) bool           free grains that feel the fluid through voidage, pressure and
                              drag when the scene has option 'fpi'; None: every disc that
                              is neither fixed nor structure
    """

    x: np.ndarray
    v: np.ndarray
    omega: np.ndarray
    radius: np.ndarray
    mass: np.ndarray
    inertia: np.ndarray
    fixed: np.ndarray
    f_ext: np.ndarray
    structure: np.ndarray | None = None
    sph_volume: np.ndarray | None = None
    grain: np.ndarray | None = None

    @property
    def n(self) -> int:
        return int(self.x.shape[0])

    def structure_indices(self) -> np.ndarray:
        s = np.ones(self.n, bool) if self.structure is None else np.asarray(self.structure, bool)
        return np.nonzero(s)[0].astype(np.int32)

    def grain_indices(self) -> np.ndarray:
        if self.grain is not None:
            return np.nonzero(np.asarray(self.grain, bool))[0].astype(np.int32)
        s = np.ones(self.n, bool) if self.structure is None else np.asarray(self.structure, bool)
        return np.nonzero(~s & ~np.asarray(self.fixed, bool))[0].astype(np.int32)

    def volumes(self) -> np.ndarray:
        if self.sph_volume is None:
            return (2.0 * np.asarray(self.radius, float)) ** 2
        return np.broadcast_to(np.asarray(self.sph_volume, float), (self.n,)).copy()


@dataclass
class BondBlock:
    """Parallel bonds between solid discs ``i[k]`` and ``j[k]`` (physics.md §Parallel bonds)."""

    i: np.ndarray
    j: np.ndarray

    @property
    def n(self) -> int:
        return int(np.asarray(self.i).shape[0])


@dataclass
class WallBlock:
    """Fixed DEM line-segment walls from ``a[k]`` to ``b[k]`` (W5)."""

    a: np.ndarray
    b: np.ndarray

    @property
    def n(self) -> int:
        return int(np.asarray(self.a).shape[0])


@dataclass
class Scene:
    """Everything needed to start a run. Built by ``fpsi_jax.scenes.<name>(**kwargs)``.

    domain_lo/domain_hi  rectangle every particle must stay inside (the neighbour grid)
    v_max                the scene's velocity scale (c0 = 10 v_max, time-step bound)
    options              Physics overrides chosen by the builder (e.g. delta_sph)
    builder_kwargs       the physical parameters the builder was called with (for output)
    dt                   the time step asked for (``--set dt=…``); None: derived from the
                         stability bounds (simulate's own ``dt`` argument wins over both)
    """

    name: str
    params: Params
    domain_lo: tuple[float, float]
    domain_hi: tuple[float, float]
    v_max: float
    fluid: FluidBlock | None = None
    boundary: BoundaryBlock | None = None
    solid: SolidBlock | None = None
    bonds: BondBlock | None = None
    walls: WallBlock | None = None
    t_end: float = 1.0
    options: dict = field(default_factory=dict)
    builder_kwargs: dict = field(default_factory=dict)
    dt: float | None = None

    @property
    def fsi_coupled(self) -> bool:
        """Structure discs coupled to the fluid (option fsi): such a scene keeps physics.md's
        step coefficients and the 0.25 h skin that suits them (integrate.FSI_SPH_CFL)."""
        return (self.fluid is not None and self.solid is not None
                and self.options.get("fsi") is not None)

    def wall_range(self) -> float:
        """Reach r0 = κ min(Δx_wall, Δp) of the wall backstop (sph.wall_repulsion_scalar),
        κ = WALL_KAPPA, Δx_wall = √(m_b/ρ0) the finest fixed-wall spacing, Δp the fluid's
        initial spacing; 0 without fluid or fixed wall particles."""
        if self.fluid is None or self.boundary is None or self.boundary.n == 0:
            return 0.0
        sp = self.params.sph
        dxb = math.sqrt(float(np.min(self.boundary.mass)) / float(sp.rho0))
        return WALL_KAPPA * min(dxb, float(sp.dp))

    def validate(self) -> "Scene":
        """Check shapes, finiteness and that every particle lies inside the domain."""
        self.params.validate()
        lo, hi = np.asarray(self.domain_lo, float), np.asarray(self.domain_hi, float)
        if not np.all(hi > lo):
            raise ParameterError(f"domain_hi {tuple(hi)} must exceed domain_lo {tuple(lo)}")
        for phase in ("fluid", "boundary", "solid"):
            blk = getattr(self, phase)
            if blk is None:
                continue
            n = blk.n
            for k, a in dataclasses.asdict(blk).items():
                if a is None:
                    continue
                a = np.asarray(a)
                want = (n, 2) if k in ("x", "v", "f_ext") else (n,)
                if a.shape != want:
                    raise ParameterError(f"{phase}.{k} has shape {a.shape}, expected {want}")
                if not np.all(np.isfinite(a)):
                    raise ParameterError(f"{phase}.{k} contains non-finite values")
            positive = ("mass", "radius", "inertia") if phase == "solid" else ("mass", "h", "rho")
            for k in positive:
                if np.any(np.asarray(getattr(blk, k)) <= 0):
                    i = int(np.argmax(np.asarray(getattr(blk, k)) <= 0))
                    raise ParameterError(f"{phase}.{k}[{i}] = {getattr(blk, k)[i]!r} out of "
                                         "range; allowed (0, inf)")
            out = np.any((blk.x < lo) | (blk.x >= hi), axis=1)
            if out.any():
                i = int(np.argmax(out))
                raise ParameterError(
                    f"{phase} particle {i} at {tuple(blk.x[i])} lies outside the domain "
                    f"[{tuple(lo)}, {tuple(hi)})")
        if self.fluid is None and self.solid is None:
            raise ParameterError("scene has neither fluid nor solid particles")
        if self.fluid is not None and self.params.sph is None:
            raise ParameterError("scene has fluid but params.sph is None")
        if self.boundary is not None and self.fluid is None:
            raise ParameterError("scene has SPH boundary particles but no fluid")
        if (self.solid is not None or self.walls is not None) and self.params.dem is None:
            raise ParameterError("scene has DEM discs or walls but params.dem is None")
        if self.walls is not None and self.solid is None:
            raise ParameterError("scene has DEM walls but no solid discs")
        if self.solid is not None and np.any(self.solid.volumes() <= 0):
            raise ParameterError("solid.sph_volume out of range; allowed (0, inf)")
        if self.bonds is not None:
            self._validate_bonds()
        if self.walls is not None:
            a, b = np.asarray(self.walls.a, float), np.asarray(self.walls.b, float)
            if a.shape != (self.walls.n, 2) or b.shape != a.shape:
                raise ParameterError(f"walls.a/b must have shape (n, 2), got {a.shape}, {b.shape}")
            if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
                raise ParameterError("walls contain non-finite end points")
            if np.any(np.linalg.norm(b - a, axis=1) <= 0):
                raise ParameterError("a wall segment has zero length (a == b)")
        return self

    def _validate_bonds(self):
        if self.solid is None:
            raise ParameterError("scene has bonds but no solid discs")
        if self.params.bond is None:
            raise ParameterError("scene has bonds but params.bond is None")
        i, j = np.asarray(self.bonds.i), np.asarray(self.bonds.j)
        n = self.solid.n
        if i.shape != j.shape or i.ndim != 1:
            raise ParameterError(f"bonds.i/j must be 1-D of equal length, got {i.shape}, {j.shape}")
        if not (np.issubdtype(i.dtype, np.integer) and np.issubdtype(j.dtype, np.integer)):
            raise ParameterError("bonds.i/j must be integer disc indices")
        if np.any((i < 0) | (i >= n) | (j < 0) | (j >= n)):
            raise ParameterError(f"bond disc index out of range; allowed [0, {n - 1}]")
        if np.any(i == j):
            raise ParameterError("a bond joins a disc to itself (i == j)")
        d = np.linalg.norm(self.solid.x[j] - self.solid.x[i], axis=1)
        if np.any(d <= 0):
            raise ParameterError("a bond joins two coincident discs")

    @property
    def n_particles(self) -> int:
        return sum(b.n for b in (self.fluid, self.boundary, self.solid) if b is not None)

    def to_json(self) -> str:
        return json.dumps({
            "name": self.name, "builder_kwargs": _jsonable(self.builder_kwargs),
            "domain_lo": list(self.domain_lo), "domain_hi": list(self.domain_hi),
            "v_max": self.v_max, "t_end": self.t_end, "dt_requested": self.dt,
            "options": _jsonable(self.options),
            "n_fluid": self.fluid.n if self.fluid else 0,
            "n_boundary": self.boundary.n if self.boundary else 0,
            "n_solid": self.solid.n if self.solid else 0,
            "n_bonds": self.bonds.n if self.bonds else 0,
            "n_walls": self.walls.n if self.walls else 0,
            "n_structure": (int(self.solid.structure_indices().size)
                            if self.solid is not None and self.options.get("fsi") else 0),
            "n_grain": (int(self.solid.grain_indices().size)
                        if self.solid is not None and self.options.get("fpi") else 0),
        })


def _jsonable(d):
    return json.loads(json.dumps(d, default=lambda o: np.asarray(o).tolist()))


@dataclass(frozen=True)
class NeighborConfig:
    """Static settings of one jax-md neighbour list (see ``neighbors.py``).

    r_cut   interaction cut-off (2·h_max for SPH)
    skin    extra radius (jax-md ``dr_threshold``); the list is rebuilt only when a particle
            has moved more than skin/2 since the last build
    capacity_multiplier, extra_capacity   jax-md allocation slack; grown on overflow
    origin, box   the domain rectangle: positions are shifted by ``origin`` into [0, box)
    """

    r_cut: float
    skin: float
    origin: tuple[float, float]
    box: tuple[float, float]
    capacity_multiplier: float = 1.25
    extra_capacity: int = 0

    @property
    def list_radius(self) -> float:
        """r_cut + skin: the radius pairs are listed within (jax-md's cell size too)."""
        return self.r_cut + self.skin


BOUNDARY_PRESSURE = ("fixed", "extrapolated")
# reach of the wall backstop in wall/fluid spacings (Scene.wall_range): the first fluid
# layer at rest sits (Δp + Δx_wall)/2 ≥ Δx_wall away, a particle squeezing between two
# wall particles comes within Δx_wall/2, and r0 > Δx_wall/√2 leaves no gap inside a
# square wall lattice
WALL_KAPPA = 0.8
BOND_SECTIONS = ("slab", "circular")
VOIDAGE = ("area", "mapped")
FPI_PRESSURE = ("archimedes", "gradient")


@dataclass(frozen=True)
class Physics:
    """Static configuration: hashable, closed over by the compiled step.

    Phases present (n_fluid, n_boundary) and the switches of the SPH model:
      kernel               'wendland' (K28) or 'cubic'
      xsph                 XSPH position correction (K39)
      anticlump            anti-clump term R_ij (W45, K38) on fluid–fluid pairs
      anticlump_boundary   also on fluid–boundary pairs (K advises against: off)
      variable_h           Dh/Dt = −h/(n_d ρ) Dρ/Dt (K37)
      delta_sph            Molteni–Colagrossi density diffusion (off by default)
      artificial_viscosity Monaghan α-viscosity (off by default; not in the seeds)
      wall_repulsion       short-range backstop against fluid creeping through a fixed wall
                           (sph.wall_repulsion_scalar; on by default, zero at rest; not in
                           the seeds); wall_range, its reach r0, is derived from the scene
                           (Scene.wall_range)
      boundary_pressure    'fixed' (W5/K5: ρ, P of boundary particles never change) or
                           'extrapolated' (Adami et al. 2012: P_b from the fluid, with the
                           hydrostatic correction)
      h_margin             the neighbour cut-off allows h to grow to h_margin·h0
      rho_tolerance        |ρ/ρ0 − 1| above this marks a run unstable
      x64                  float64 everywhere

    DEM phases (n_solid discs, n_bonds parallel bonds, n_walls line walls) and:
      dem_neighbors        the contact family's list (cut-off 2 R_max), None without discs
      bond_section         'slab' (2D, A = 2R̄t, I = (2/3)tR̄³) or 'circular'
                           (A = πR̄², I = πR̄⁴/4; K6.1's Itasca beam)

    Couplings:
      fsi, n_structure     fluid–structure method (fsi.METHODS) and structure disc count
      dem_substeps         DEM sub-steps per SPH step (multi-rate)
      fpi, n_grain         fluid–particle coupling of the grains (fpi.py): voidage in the
                           fluid equations (W42–43), pressure force (buoyancy), drag,
                           lubrication
      voidage              what the fluid equations see: 'area' (ε = 1 − Σ V_p W, default)
                           or 'mapped' (the equivalent 3D packing's; for grain beds); the
                           drag closure sees the 3D one either way (fpi.py)
      eps_floor            the fluid equations see max(ε, eps_floor) (the drag the true ε);
                           builders of packed beds raise it (fpi_cases.py)
      fpi_pressure         the grains' buoyancy: 'archimedes' (ρ_f V_p |g|, default) or
                           'gradient' (−V_p ∇P of the SPH pressure); see fpi.py
      lubrication          W24 between wet grains (cut-off and regularisation in Params.fpi)
    """

    n_fluid: int
    n_boundary: int
    neighbors: NeighborConfig | None
    kernel: str = "wendland"
    xsph: bool = True
    anticlump: bool = True
    anticlump_boundary: bool = False
    variable_h: bool = True
    delta_sph: bool = False
    artificial_viscosity: bool = False
    wall_repulsion: bool = True
    wall_range: float = 0.0
    boundary_pressure: str = "fixed"
    h_margin: float = 1.05
    rho_tolerance: float = 0.3
    x64: bool = False
    n_solid: int = 0
    n_bonds: int = 0
    n_walls: int = 0
    dem_neighbors: NeighborConfig | None = None
    bond_section: str = "slab"
    fsi: str | None = None
    n_structure: int = 0
    dem_substeps: int = 1
    fpi: bool = False
    n_grain: int = 0
    voidage: str = "area"
    fpi_pressure: str = "archimedes"
    eps_floor: float = 0.0
    lubrication: bool = True

    OPTIONS = ("kernel", "xsph", "anticlump", "anticlump_boundary", "variable_h", "delta_sph",
               "artificial_viscosity", "wall_repulsion", "boundary_pressure", "h_margin",
               "rho_tolerance", "x64", "skin", "capacity_multiplier", "bond_section", "dem_skin", "fsi", "dem_substeps", "fpi",
               "voidage", "lubrication", "fpi_pressure", "eps_floor")

    @classmethod
    def for_scene(cls, scene: Scene, **overrides) -> "Physics":
        """Derive the static configuration from a scene (scene.options, then overrides)."""
        opts = {**scene.options, **overrides}
        unknown = set(opts) - set(cls.OPTIONS)
        if unknown:
            raise ParameterError(f"unknown Physics option(s) {sorted(unknown)}; "
                                 f"allowed: {', '.join(cls.OPTIONS)}")
        # 0.4 h: with issue 7's step (3.5× physics.md's) a 0.25 h skin was rebuilt every ~5
        # steps of the 24k dam break and overflowed to K = 48; 0.4 h measured fastest
        # (0.25 / 0.3 / 0.35 / 0.4 / 0.45 / 0.6 h: 0.51 / 0.94 / 0.96 / 0.98 / 0.81 / 0.83 M
        # particle-steps/s on one core). A fluid-coupled structure keeps physics.md's step
        # and the 0.25 h skin that suits it (Scene.fsi_coupled).
        skin_factor = opts.pop("skin", 0.25 if scene.fsi_coupled else 0.4)
        cap = opts.pop("capacity_multiplier", 1.25)
        kernels.get(opts.get("kernel", "wendland"))
        bp = opts.get("boundary_pressure", "fixed")
        if bp not in BOUNDARY_PRESSURE:
            raise ParameterError(f"boundary_pressure must be one of {BOUNDARY_PRESSURE}, got {bp!r}")
        h_margin = float(opts.get("h_margin", 1.05))
        if not 1.0 <= h_margin <= 2.0:
            raise ParameterError(f"h_margin = {h_margin} out of range; allowed [1, 2]")
        if not 0.0 <= skin_factor <= 2.0:
            raise ParameterError(f"skin = {skin_factor} out of range; allowed [0, 2] (× h)")
        dem_skin = float(opts.pop("dem_skin", 0.5))
        if not 0.0 <= dem_skin <= 2.0:
            raise ParameterError(f"dem_skin = {dem_skin} out of range; allowed [0, 2] (× R_max)")
        n_sub = opts.get("dem_substeps", 1)
        if n_sub is None:
            opts.pop("dem_substeps")
        elif not (isinstance(n_sub, (int, np.integer)) and 1 <= n_sub <= 10000):
            raise ParameterError(f"dem_substeps = {n_sub!r} out of range; allowed integers "
                                 "[1, 10000]")
        method = opts.get("fsi")
        n_structure = 0
        if method is not None:
            from .fsi import METHODS
            if method not in METHODS:
                raise ParameterError(f"fsi must be one of {METHODS}, got {method!r}")
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
        if opts.get("voidage", "area") not in VOIDAGE:
            raise ParameterError(f"voidage must be one of {VOIDAGE}, got {opts['voidage']!r}")
        floor = opts.get("eps_floor", 0.0)
        if not (isinstance(floor, (int, float)) and 0.0 <= floor < 1.0):
            raise ParameterError(f"eps_floor = {floor!r} out of range; allowed [0, 1)")
        if opts.get("fpi_pressure", "archimedes") not in FPI_PRESSURE:
            raise ParameterError(f"fpi_pressure must be one of {FPI_PRESSURE}, got "
                                 f"{opts['fpi_pressure']!r}")
        section = opts.get("bond_section", "slab")
        if section not in BOND_SECTIONS:
            raise ParameterError(f"bond_section must be one of {BOND_SECTIONS}, got {section!r}")
        origin = tuple(map(float, scene.domain_lo))
        box = tuple(float(h - l) for h, l in zip(scene.domain_hi, scene.domain_lo))
        nb = None
        if scene.fluid is not None:
            h_all = [b.h for b in (scene.fluid, scene.boundary) if b is not None]
            h_max = float(max(np.max(h) for h in h_all)) * h_margin
            nb = NeighborConfig(r_cut=kernels.SUPPORT * h_max, skin=skin_factor * h_max / h_margin,
                                origin=origin, box=box, capacity_multiplier=float(cap))
        dem_nb = None
        if scene.solid is not None:
            r_max = float(np.max(scene.solid.radius))
            reach = 1.0
            if n_grain and opts.get("lubrication", True):
                reach += float(scene.params.fpi.lub_cutoff)   # W24 acts up to a gap cut-off
            dem_nb = NeighborConfig(r_cut=2.0 * r_max * reach, skin=dem_skin * r_max, origin=origin,
                                    box=box, capacity_multiplier=float(cap))
        return cls(n_fluid=scene.fluid.n if scene.fluid else 0,
                   n_boundary=scene.boundary.n if scene.boundary else 0,
                   neighbors=nb, wall_range=scene.wall_range(),
                   n_solid=scene.solid.n if scene.solid else 0,
                   n_bonds=scene.bonds.n if scene.bonds else 0,
                   n_walls=scene.walls.n if scene.walls else 0,
                   dem_neighbors=dem_nb, n_structure=n_structure, n_grain=n_grain, **opts)

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
            m += ["fpi.voidage", "fpi.drag", f"fpi.buoyancy.{self.fpi_pressure}",
                  "fpi.reaction"]
            m += ["fpi.lubrication"] if self.lubrication else []
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
