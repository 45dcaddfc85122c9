"""Scenes (host-side description) and the static ``Physics`` derived from them.

A :class:`Scene` holds numpy arrays per phase, the default :class:`~fpsi_jax.params.Params`
and a few settings. :meth:`Physics.for_scene` turns it into the static configuration that
decides which mechanisms are compiled: a phase or option the scene lacks is absent from the
compiled program (not multiplied by zero).
"""
from __future__ import annotations

import dataclasses
import json
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
class Scene:
    """Everything needed to start a run. Built by ``fpsi_jax.scenes.<name>(**kwargs)``.

    domain_lo/domain_hi  rectangle every particle must stay inside (the neighbour grid)
    v_max                the scene's velocity scale (c0 = 10 v_max, time-step bound)
    options              Physics overrides chosen by the builder (e.g. delta_sph)
    builder_kwargs       the physical parameters the builder was called with (for output)
    """

    name: str
    params: Params
    domain_lo: tuple[float, float]
    domain_hi: tuple[float, float]
    v_max: float
    fluid: FluidBlock | None = None
    boundary: BoundaryBlock | None = None
    t_end: float = 1.0
    options: dict = field(default_factory=dict)
    builder_kwargs: dict = field(default_factory=dict)

    def validate(self) -> "Scene":
        """Check shapes, finiteness and that every particle lies inside the domain."""
        self.params.validate()
        lo, hi = np.asarray(self.domain_lo, float), np.asarray(self.domain_hi, float)
        if not np.all(hi > lo):
            raise ParameterError(f"domain_hi {tuple(hi)} must exceed domain_lo {tuple(lo)}")
        for phase in ("fluid", "boundary"):
            blk = getattr(self, phase)
            if blk is None:
                continue
            n = blk.n
            for k, a in dataclasses.asdict(blk).items():
                a = np.asarray(a)
                want = (n, 2) if k in ("x", "v") else (n,)
                if a.shape != want:
                    raise ParameterError(f"{phase}.{k} has shape {a.shape}, expected {want}")
                if not np.all(np.isfinite(a)):
                    raise ParameterError(f"{phase}.{k} contains non-finite values")
            if np.any(blk.mass <= 0) or np.any(blk.h <= 0) or np.any(blk.rho <= 0):
                raise ParameterError(f"{phase}: mass, h and rho must be > 0")
            out = np.any((blk.x < lo) | (blk.x >= hi), axis=1)
            if out.any():
                i = int(np.argmax(out))
                raise ParameterError(
                    f"{phase} particle {i} at {tuple(blk.x[i])} lies outside the domain "
                    f"[{tuple(lo)}, {tuple(hi)})")
        if self.fluid is None:
            raise ParameterError("scene has no fluid; DEM-only scenes arrive with the DEM issue")
        if self.fluid is not None and self.params.sph is None:
            raise ParameterError("scene has fluid but params.sph is None")
        return self

    @property
    def n_particles(self) -> int:
        return sum(b.n for b in (self.fluid, self.boundary) if b is not None)

    def to_json(self) -> str:
        return json.dumps({
            "name": self.name, "builder_kwargs": _jsonable(self.builder_kwargs),
            "domain_lo": list(self.domain_lo), "domain_hi": list(self.domain_hi),
            "v_max": self.v_max, "t_end": self.t_end, "options": _jsonable(self.options),
            "n_fluid": self.fluid.n if self.fluid else 0,
            "n_boundary": self.boundary.n if self.boundary else 0,
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


BOUNDARY_PRESSURE = ("fixed", "extrapolated")


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
      boundary_pressure    'fixed' (W5/K5: ρ, P of boundary particles never change) or
                           'extrapolated' (Adami et al. 2012: P_b from the fluid, with the
                           hydrostatic correction)
      h_margin             the neighbour cut-off allows h to grow to h_margin·h0
      rho_tolerance        |ρ/ρ0 − 1| above this marks a run unstable
      x64                  float64 everywhere
    """

    n_fluid: int
    n_boundary: int
    neighbors: NeighborConfig
    kernel: str = "wendland"
    xsph: bool = True
    anticlump: bool = True
    anticlump_boundary: bool = False
    variable_h: bool = True
    delta_sph: bool = False
    artificial_viscosity: bool = False
    boundary_pressure: str = "fixed"
    h_margin: float = 1.05
    rho_tolerance: float = 0.3
    x64: bool = False

    OPTIONS = ("kernel", "xsph", "anticlump", "anticlump_boundary", "variable_h", "delta_sph",
               "artificial_viscosity", "boundary_pressure", "h_margin", "rho_tolerance", "x64", "skin",
               "capacity_multiplier")

    @classmethod
    def for_scene(cls, scene: Scene, **overrides) -> "Physics":
        """Derive the static configuration from a scene (scene.options, then overrides)."""
        opts = {**scene.options, **overrides}
        unknown = set(opts) - set(cls.OPTIONS)
        if unknown:
            raise ParameterError(f"unknown Physics option(s) {sorted(unknown)}; "
                                 f"allowed: {', '.join(cls.OPTIONS)}")
        skin_factor = opts.pop("skin", 0.25)
        cap = opts.pop("capacity_multiplier", 1.25)
        kernels.get(opts.get("kernel", "wendland"))
        bp = opts.get("boundary_pressure", "fixed")
        if bp not in BOUNDARY_PRESSURE:
            raise ParameterError(f"boundary_pressure must be one of {BOUNDARY_PRESSURE}, got {bp!r}")
        h_margin = float(opts.get("h_margin", 1.05))
        if not 1.0 <= h_margin <= 2.0:
            raise ParameterError(f"h_margin = {h_margin} out of range; allowed [1, 2]")
        h_all = [b.h for b in (scene.fluid, scene.boundary) if b is not None]
        h_max = float(max(np.max(h) for h in h_all)) * h_margin
        r_cut = kernels.SUPPORT * h_max
        if not 0.0 <= skin_factor <= 2.0:
            raise ParameterError(f"skin = {skin_factor} out of range; allowed [0, 2] (× h)")
        nb = NeighborConfig(
            r_cut=r_cut, skin=skin_factor * h_max / h_margin,
            origin=tuple(map(float, scene.domain_lo)),
            box=tuple(float(h - l) for h, l in zip(scene.domain_hi, scene.domain_lo)),
            capacity_multiplier=float(cap))
        return cls(n_fluid=scene.fluid.n if scene.fluid else 0,
                   n_boundary=scene.boundary.n if scene.boundary else 0,
                   neighbors=nb, **opts)

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
        return tuple(m)

    def to_json(self) -> str:
        d = dataclasses.asdict(self)
        return json.dumps(d)
