"""Scenes: the host-side (numpy) description of a run.

A :class:`Scene` holds numpy arrays per phase, the default :class:`~fpsi_jax.model.params.Params`
and a few settings. :meth:`fpsi_jax.model.config.Physics.for_scene` turns it into the static
configuration that decides which mechanisms are compiled. Scenes are made by the public
builders of :mod:`fpsi_jax.build`.
"""
from __future__ import annotations

import dataclasses
import json
import math
from dataclasses import dataclass, field

import numpy as np

from .errors import ParameterError, fmt
from .options import Side, choose
from .params import Params


# reach of the wall backstop in wall/fluid spacings (Scene.wall_range): the first fluid
# layer at rest sits (Δp + Δx_wall)/2 ≥ Δx_wall away, a particle squeezing between two
# wall particles comes within Δx_wall/2, and r0 > Δx_wall/√2 leaves no gap inside a
# square wall lattice
WALL_KAPPA = 0.8


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

    def grains_in_contact(self, tol=1e-6) -> bool:
        """Whether any two grains touch or overlap, |x_i − x_j| ≤ (R_i + R_j)(1 + tol): a
        bed (the grains compared in chunks of 512 against those within reach)."""
        g = self.grain_indices()
        x, r = np.asarray(self.x, float)[g], np.asarray(self.radius, float)[g]
        reach = 2.0 * float(r.max()) if len(r) else 0.0
        for k in range(0, len(x), 512):
            b, rb = x[k:k + 512], r[k:k + 512]
            near = np.flatnonzero(np.all((x >= b.min(0) - reach) & (x <= b.max(0) + reach),
                                         axis=1))
            d = np.linalg.norm(x[near][:, None, :] - b[None, :, :], axis=2)
            other = near[:, None] != (k + np.arange(len(b)))[None, :]
            if np.any(other & (d <= (r[near][:, None] + rb[None, :]) * (1 + tol))):
                return True
        return False

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
    """Fixed DEM line-segment walls from ``a[k]`` to ``b[k]`` (W5).

    ``side`` (w,) says which side of each wall is active, as PFC's walls have an active
    side: +1 the left of a → b (the normal (−t_y, t_x), t along a → b), −1 the right, 0 both
    (a thin plate). A disc whose centre has gone past a one-sided wall's line (a contact
    spring too soft for the impact) is still pushed back out, with overlap R + depth, while
    the depth is under 2R; None: every wall two-sided.

    ``image_side`` (w,), where given, says on which side of each wall the fluid lies for
    the grains' wall images (fpi.wall_images; 0: none), where that differs from ``side``:
    an obstacle's outline pushes discs from both sides but has water only outside."""

    a: np.ndarray
    b: np.ndarray
    side: np.ndarray | None = None
    image_side: np.ndarray | None = None

    def sides(self) -> np.ndarray:
        """(w,) the active sides (0 where ``side`` is None)."""
        if self.side is None:
            return np.zeros(self.n)
        return np.broadcast_to(np.asarray(self.side, float), (self.n,)).copy()

    def image_sides(self) -> np.ndarray:
        """(w,) the fluid's side of each wall for the grains' images (``image_side``, else
        the active sides)."""
        if self.image_side is None:
            return self.sides()
        return np.broadcast_to(np.asarray(self.image_side, float), (self.n,)).copy()

    @property
    def n(self) -> int:
        return int(np.asarray(self.a).shape[0])


@dataclass
class Scene:
    """Everything needed to start a run, made from the public builders of
    :mod:`fpsi_jax.build` (the shipped scenes: ``fpsi_jax.cases.build(name, **kwargs)``).

    domain_lo/domain_hi  rectangle every particle must stay inside (the neighbour grid)
    v_max                the scene's velocity scale (c0 = 10 v_max, time-step bound)
    options              Physics overrides chosen by the builder (e.g. delta_sph)
    builder_kwargs       the physical parameters the builder was called with (for output)
    dt                   the time step asked for (``--set dt=…``); None: derived from the
                         stability bounds (simulate's own ``dt`` argument wins over both)
    open_sides           sides of the domain particles may leave through ('left', 'right',
                         'bottom', 'top'): a particle that crosses one is taken out of the
                         computation and counted (solver.stages.exits); crossing a closed
                         side stops the run with a diagnosis
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
    open_sides: tuple = ()

    @property
    def fsi_coupled(self) -> bool:
        """Structure discs that the fluid moves (option fsi and at least one structure disc
        not kinematic): such a scene takes the SPH coefficient solver.timestep.FSI_SPH_CFL
        and the 0.25 h skin: the fluid force held over the DEM sub-steps loses accuracy on
        a deformable structure before the step is unstable (docs/design.md, Time-step
        coefficients); a structure whose discs are all kinematic
        (a gate lifted at a set speed) never reads that force, so its scene takes the
        fluid-only and grain coefficients."""
        if self.fluid is None or self.solid is None or self.options.get("fsi") is None:
            return False
        so = self.solid
        moved = ~np.asarray(so.fixed, bool)
        if so.structure is not None:
            moved &= np.asarray(so.structure, bool)
        return bool(moved.any())

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
        self.open_sides = open_sides(self.open_sides)
        lo, hi = np.asarray(self.domain_lo, float), np.asarray(self.domain_hi, float)
        if not np.all(hi > lo):
            raise ParameterError(f"domain_hi {_point(hi)} must exceed domain_lo {_point(lo)}")
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
                    raise ParameterError(f"{phase}.{k} has shape {a.shape} and {phase}.x "
                                         f"{np.shape(blk.x)}: allowed {want}, one row per "
                                         "particle")
                if not np.all(np.isfinite(a)):
                    raise ParameterError(f"{phase}.{k} contains non-finite values")
            positive = ("mass", "radius", "inertia") if phase == "solid" else ("mass", "h", "rho")
            for k in positive:
                if np.any(np.asarray(getattr(blk, k)) <= 0):
                    i = int(np.argmax(np.asarray(getattr(blk, k)) <= 0))
                    raise ParameterError(f"{phase}.{k}[{i}] = {fmt(getattr(blk, k)[i])} out "
                                         "of range; allowed (0, inf)")
            out = np.any((blk.x < lo) | (blk.x >= hi), axis=1)
            if out.any():
                i = int(np.argmax(out))
                raise ParameterError(
                    f"{phase} particle {i} at {_point(blk.x[i])} lies outside the domain "
                    f"[{_point(lo)}, {_point(hi)})")
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
            if not np.all(np.isin(self.walls.sides(), (-1.0, 0.0, 1.0))):
                raise ParameterError("walls.side out of range; allowed -1, 0, 1")
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
            "open_sides": [str(s) for s in self.open_sides],
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


def _point(p) -> str:
    """(x, y) as a user writes it, without numpy's np.float64(...)."""
    return "(" + ", ".join(fmt(float(v)) for v in np.ravel(p)) + ")"


def open_sides(sides) -> tuple:
    """``sides`` (names or :class:`~fpsi_jax.model.options.Side` members) as a sorted tuple
    of members without repeats; ParameterError for anything else."""
    if isinstance(sides, str):
        sides = (sides,)
    try:
        items = list(sides)
    except TypeError:
        raise ParameterError(f"open_sides = {sides!r} must be a list of sides; allowed: "
                             f"{', '.join(m.value for m in Side)}") from None
    chosen = {choose(Side, "open_sides", s) for s in items}
    return tuple(m for m in Side if m in chosen)


def _jsonable(d):
    return json.loads(json.dumps(d, default=lambda o: np.asarray(o).tolist()))
