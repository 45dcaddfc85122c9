"""Differentiable parameters: everything a gradient may be taken with respect to.

``Params`` is a pytree of floats. It holds one sub-tree per mechanism that the scene has
(``sph`` for the fluid; DEM and bond parameters join in later issues) plus the global
gravity and time step. A mechanism the scene lacks has ``None`` here, so it carries no leaves.

Calibration (``calibrate/``) and the CLI's ``--set`` address leaves by dotted name
(``sph.mu``) or, when unambiguous, by the bare leaf name (``mu``).
"""
from __future__ import annotations

import dataclasses
import math
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from .tree import pytree_dataclass


class ParameterError(ValueError):
    """Bad user input: names the parameter and the allowed range."""


def require(name: str, value, lo=None, hi=None, lo_open=False, hi_open=False):
    """Raise ParameterError unless lo <= value <= hi (open ends where asked)."""
    v = float(value)
    bad = not math.isfinite(v)
    if lo is not None:
        bad |= v <= lo if lo_open else v < lo
    if hi is not None:
        bad |= v >= hi if hi_open else v > hi
    if bad:
        left = "(" if lo_open else "["
        right = ")" if hi_open else "]"
        rng = f"{left}{'-inf' if lo is None else lo}, {'inf' if hi is None else hi}{right}"
        raise ParameterError(f"{name} = {value!r} is out of range; allowed {rng}")


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
    delta     δ-SPH density-diffusion coefficient (Molteni & Colagrossi 2009), used only when
              Physics.delta_sph is on
    alpha     Monaghan artificial-viscosity coefficient α, used only when
              Physics.artificial_viscosity is on (not in the seeds)
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


@pytree_dataclass
class Params:
    """All differentiable parameters of a scene.

    dt is traced (not static) so that sweeps over the time step do not recompile; it is not a
    quantity one would normally differentiate with respect to.
    """

    gravity: Any = (0.0, -9.81)
    dt: Any = 1.0e-4
    sph: SphParams | None = None

    def validate(self):
        require("dt", self.dt, 0.0, None, lo_open=True)
        g = np.asarray(self.gravity, dtype=float)
        if g.shape != (2,) or not np.all(np.isfinite(g)):
            raise ParameterError(f"gravity must be a finite 2-vector, got {self.gravity!r}")
        if self.sph is not None:
            self.sph.validate()
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
