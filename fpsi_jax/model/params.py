"""Differentiable parameters: everything a gradient may be taken with respect to.

``Params`` is a pytree of floats. It holds one sub-tree per mechanism that the scene has
(``sph`` for the fluid, ``dem`` for disc contacts, ``bond`` for parallel bonds, ``fpi``
for the grains' coupling to the fluid) plus the global
gravity and time step. A mechanism the scene lacks has ``None`` here, so it carries no leaves.

Calibration (``calibrate/``) and the CLI's ``--set`` address leaves by dotted name
(``sph.mu``) or, when unambiguous, by the bare leaf name (``mu``).
"""
from __future__ import annotations

import dataclasses
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from .errors import ParameterError, _traced, fmt, require
from .tree import pytree_dataclass


@pytree_dataclass
class SphParams:
    """Weakly compressible SPH fluid (physics.md §SPH; W43–W46, K32–K39).

    rho0      reference density ρ0 [kg/m³]
    c0        numerical speed of sound [m/s]; B = c0²ρ0/γ (W46, K35)
    gamma     Tait exponent γ (7 for water)
    mu        dynamic viscosity μ [Pa·s] in the Morris term (K36)
    r_clump   anti-clump coefficient r of R_ij (W45, K38)
    dp        initial particle spacing Δp used by the anti-clump term [m]
    eps_xsph  XSPH coefficient ε (K39), 0 ≤ ε ≤ 1
    delta     δ-SPH density-diffusion coefficient δ (Molteni & Colagrossi 2009; Fourtakas et
              al. 2019: Physics.density_diffusion), used only when Physics.delta_sph is on
    alpha     Monaghan artificial-viscosity coefficient α, used only when
              Physics.artificial_viscosity is on (not in the seeds)
    wall_beta strength β of the wall backstop, (β c0²/r0²)(1 − r²/r0²)² x_ij inside the
              static range r0 = Physics.wall_range (sph.wall_repulsion_scalar), used only
              when Physics.wall_repulsion is on (not in the seeds)
    """

    rho0: Any = 1000.0
    c0: Any = 20.0
    gamma: Any = 7.0
    mu: Any = 1.0e-3
    r_clump: Any = 0.01
    dp: Any = 0.005
    eps_xsph: Any = 0.5
    delta: Any = 0.1
    alpha: Any = 0.0
    wall_beta: Any = 0.05

    def validate(self):
        require("sph.rho0", self.rho0, 0.0, None, lo_open=True)
        require("sph.c0", self.c0, 0.0, None, lo_open=True)
        require("sph.gamma", self.gamma, 1.0, 15.0)
        require("sph.mu", self.mu, 0.0, None)
        require("sph.r_clump", self.r_clump, 0.0, 1.0)
        require("sph.dp", self.dp, 0.0, None, lo_open=True)
        require("sph.eps_xsph", self.eps_xsph, 0.0, 1.0)
        require("sph.delta", self.delta, 0.0, 1.0)
        require("sph.alpha", self.alpha, 0.0, 1.0)
        require("sph.wall_beta", self.wall_beta, 0.0, 1.0)

    def checked(self) -> "SphParams":
        """``self`` after :meth:`validate`."""
        self.validate()
        return self


@pytree_dataclass
class DemParams:
    """Linear DEM contacts between discs and with walls (physics.md §DEM; W10–W17, K5–K16,
    K25). Stiffnesses are per unit thickness (N/m for a 1 m thick 2D model).

    kn, ks      normal and shear contact spring stiffness k_n, k_s (W10, W13)
    mu          Coulomb friction coefficient (W14)
    beta_n      normal dashpot ratio β_n: F = 2β_n √(m k_n) δ̇ (W15–W17), m the reduced mass
    beta_s      shear dashpot ratio β_s (W16 prints β_n there: a typo)
    alpha       local damping α (K25): F_d = −α |F| sign(v) per component, moments too
    damping     mass-proportional viscous damping rate c [1/s]: F_d = −c m v, M_d = −c J ω
                (not in the seeds: the smooth counterpart of α that calibration can
                differentiate; a mode of angular frequency ω decays with damping ratio
                ζ = c/(2ω), so α ≈ πζ of K25 corresponds to c ≈ 2αω/π)
    load_ramp   external loads grow linearly from 0 over this time [s] (0: applied at once)
    mu_roll     rolling resistance μ_r (not in the seeds; None: none, no term compiled): a
                couple M_r = −μ_r R* F_n sign(ω_A − ω_B) on each disc of a contact,
                R* = R_A R_B/(R_A + R_B) (R_A against a wall), the constant directional
                torque of Ai et al. (2011, model A; LIGGGHTS' rolling_friction cdt)
    """

    kn: Any = 1.0e6
    ks: Any = 5.0e5
    mu: Any = 0.3
    beta_n: Any = 0.0
    beta_s: Any = 0.0
    alpha: Any = 0.0
    damping: Any = 0.0
    load_ramp: Any = 0.0
    mu_roll: Any = None

    def validate(self):
        require("dem.kn", self.kn, 0.0, None, lo_open=True)
        if self.mu_roll is not None:
            require("dem.mu_roll", self.mu_roll, 0.0, None)
        require("dem.ks", self.ks, 0.0, None)
        require("dem.mu", self.mu, 0.0, None)
        require("dem.beta_n", self.beta_n, 0.0, 1.0, hi_open=True)
        require("dem.beta_s", self.beta_s, 0.0, 1.0, hi_open=True)
        require("dem.alpha", self.alpha, 0.0, 1.0, hi_open=True)
        require("dem.damping", self.damping, 0.0, None)
        require("dem.load_ramp", self.load_ramp, 0.0, None)


@pytree_dataclass
class BondParams:
    """Parallel bonds (physics.md §Parallel bonds; K17–K22, W26–W38).

    kn, ks      bond normal and shear stiffness per unit area k̄_n, k̄_s [Pa/m]
    sigma_c     tensile strength σ̄_c [Pa] (K21): breaks when F̄_n/A + β̄|M̄|R̄/I ≥ σ̄_c
    tau_c       shear strength τ̄_c [Pa] (K22): breaks when |F̄_s|/A ≥ τ̄_c
    beta_bar    moment-contribution factor β̄ (1 in K21, 0 in W37)
    lam         bond radius multiplier λ: R̄ = λ (R_A + R_B)/2
    thickness   out-of-plane thickness t of the slab section [m]
    """

    kn: Any = 1.0e9
    ks: Any = 4.0e8
    sigma_c: Any = 1.0e30
    tau_c: Any = 1.0e30
    beta_bar: Any = 1.0
    lam: Any = 1.0
    thickness: Any = 1.0

    def validate(self):
        require("bond.kn", self.kn, 0.0, None, lo_open=True)
        require("bond.ks", self.ks, 0.0, None)
        require("bond.sigma_c", self.sigma_c, 0.0, None, lo_open=True)
        require("bond.tau_c", self.tau_c, 0.0, None, lo_open=True)
        require("bond.beta_bar", self.beta_bar, 0.0, 1.0)
        require("bond.lam", self.lam, 0.0, 1.0, lo_open=True)
        require("bond.thickness", self.thickness, 0.0, None, lo_open=True)


@pytree_dataclass
class FpiParams:
    """Fluid–particle coupling (physics.md §Fluid–particle coupling; W19–W25, W47–W48).
    The fluid density and viscosity are the SPH ones (ρ_f = sph.rho0, μ = sph.mu).

    lub_gap_min   lubrication (W24) gap regularisation: s ← max(s, lub_gap_min · d̄)
    lub_cutoff    lubrication acts for gaps s ≤ lub_cutoff · d̄ (zero beyond)
    added_mass    added-mass coefficient C_a (Physics.added_mass): the fluid a grain
                  accelerates carries C_a ρ_f V_p with it; 1 is a circular cylinder's
                  potential-flow value (Lamb 1932, §68), i.e. a disc per unit thickness
    """

    lub_gap_min: Any = 0.02
    lub_cutoff: Any = 0.1
    added_mass: Any = 1.0

    def validate(self):
        require("fpi.lub_gap_min", self.lub_gap_min, 0.0, 1.0, lo_open=True)
        require("fpi.lub_cutoff", self.lub_cutoff, 0.0, 1.0)
        require("fpi.added_mass", self.added_mass, 0.0, 10.0)


@pytree_dataclass
class Params:
    """All differentiable parameters of a scene.

    dt is traced (not static) so that sweeps over the time step do not recompile; it is not a
    quantity one would normally differentiate with respect to.
    """

    gravity: Any = (0.0, -9.81)
    dt: Any = 1.0e-4
    sph: SphParams | None = None
    dem: DemParams | None = None
    bond: BondParams | None = None
    fpi: FpiParams | None = None

    def validate(self):
        require("dt", self.dt, 0.0, None, lo_open=True)
        try:
            g = np.asarray(self.gravity, dtype=float)
            ok = g.shape == (2,) and bool(np.all(np.isfinite(g)))
        except (TypeError, ValueError):
            ok = False
        if not ok and not _traced(self.gravity):
            raise ParameterError(f"gravity = {fmt(self.gravity)} is not a finite vector "
                                 "[gx, gy] (m/s²)")
        for sub in (self.sph, self.dem, self.bond, self.fpi):
            if sub is not None:
                sub.validate()
        return self

    # --- naming ---------------------------------------------------------------------------
    def flat(self) -> dict[str, float]:
        """Dotted-name → value for every scalar leaf (gravity as gravity.x / gravity.y)."""
        out: dict[str, Any] = {}

        def walk(prefix, obj):
            if dataclasses.is_dataclass(obj):
                for f in dataclasses.fields(obj):
                    walk(f"{prefix}{f.name}.", getattr(obj, f.name))
            elif obj is None:
                return
            else:
                out[prefix[:-1]] = obj

        walk("", self)
        return out

    def names(self) -> list[str]:
        return list(self.flat())

    def resolve(self, key: str) -> str:
        """Map a bare or dotted key to the full dotted name; ParameterError if unknown."""
        names = self.names()
        if key in names:
            return key
        hits = [n for n in names if n.split(".")[-1] == key]
        if len(hits) == 1:
            return hits[0]
        if len(hits) > 1:
            raise ParameterError(f"parameter {key!r} is ambiguous: {hits}")
        raise ParameterError(f"unknown parameter {key!r}; known: {', '.join(names)}")

    def get(self, key: str):
        name = self.resolve(key)
        obj = self
        for part in name.split("."):
            obj = getattr(obj, part)
        return obj

    def set(self, key: str, value) -> "Params":
        """Return a copy with the leaf ``key`` replaced (validates the result)."""
        name = self.resolve(key)
        parts = name.split(".")

        def rec(obj, parts):
            if len(parts) == 1:
                return dataclasses.replace(obj, **{parts[0]: value})
            return dataclasses.replace(obj, **{parts[0]: rec(getattr(obj, parts[0]), parts[1:])})

        return rec(self, parts).validate()

    def to_json(self) -> dict:
        return {k: np.asarray(v).tolist() for k, v in self.flat().items()}

    def as_arrays(self, dtype) -> "Params":
        """Convert every leaf to a JAX array of ``dtype`` (what the compiled step receives)."""
        return jax.tree_util.tree_map(lambda v: jnp.asarray(v, dtype=dtype), self)
