"""Which parameters a fit moves, and the unconstrained space it moves them in.

A :class:`Fitted` quantity is either one leaf of ``Params`` addressed by its dotted name
(``"bond.kn"``, ``"dem.damping"``) or a common *scale* factor on several leaves (the
``stiffness`` preset scales every spring of the solid, ``bond.kn``, ``bond.ks``,
``dem.kn``, ``dem.ks``, which is the same as scaling Young's modulus E in either
published mapping, since both are linear in E).

The optimiser works on an unconstrained vector z (docs/design.md, *Static,
differentiable, state*): a positive quantity is optimised in log space, a bounded one through a
logistic map onto its bounds (in log space if it is positive),

    v = exp z                                        positive, no bounds
    v = exp(log lo + (log hi − log lo) σ(z))         positive, lo ≤ v ≤ hi
    v = lo + (hi − lo) σ(z)                          bounded, not log
    v = z                                            free

so every step of the optimiser gives a valid parameter set. ``ParamSpace.params(z)`` is
pure jnp and differentiable; everything else runs on the host.
"""
from __future__ import annotations

import dataclasses
import math
from typing import Sequence

import jax
import jax.numpy as jnp
import numpy as np

from fpsi_jax.model.errors import ParameterError
from fpsi_jax.model.params import Params

STIFFNESS_LEAVES = ("bond.kn", "bond.ks", "dem.kn", "dem.ks")


@dataclasses.dataclass(frozen=True)
class Fitted:
    """One calibrated quantity.

    name    label in reports (the dotted leaf for a single leaf)
    leaves  the Params leaves it sets; with ``scale=True`` each is multiplied by v/ref
            (its base value × v/ref), else the single leaf is set to v
    lo, hi  bounds (None: open); log  optimise log v (the default for positive values)
    ref     with ``scale=True``: the physical value at which the leaves keep their base
            values (1 for a pure factor; the scene's E [Pa] for a structure's E, so that
            the value, its bounds and its standard error read in Pa)
    """

    name: str
    leaves: tuple[str, ...]
    scale: bool = False
    lo: float | None = None
    hi: float | None = None
    log: bool = True
    ref: float = 1.0

    def check(self, value: float):
        if self.log and not value > 0:
            raise ParameterError(f"{self.name} = {value!r} must be > 0 to be fitted in log "
                                 "space (give a positive start value, or log=False)")
        lo = -math.inf if self.lo is None else self.lo
        hi = math.inf if self.hi is None else self.hi
        if not lo < value < hi:
            raise ParameterError(f"{self.name} = {value!r} is out of range; allowed "
                                 f"({self.lo}, {self.hi}) (strictly inside the bounds)")

    # v ↔ z ---------------------------------------------------------------------------
    # The transform works on v/ref (bounds lo/ref, hi/ref): a factor on the leaves that
    # does not depend on how large the reported unit is.
    def factor(self, z):
        """v/ref (jnp): what a scale quantity multiplies its leaves by."""
        r = self.ref
        if self.lo is not None and self.hi is not None:
            lo, hi = self.lo / r, self.hi / r
            s = jax.nn.sigmoid(z)
            if self.log:
                a, b = math.log(lo), math.log(hi)
                return jnp.exp(a + (b - a) * s)
            return lo + (hi - lo) * s
        if self.lo is not None or self.hi is not None:
            raise ParameterError(f"{self.name}: give both bounds or neither")
        return jnp.exp(z) if self.log else z

    def to_value(self, z):
        """The physical value v = ref · factor(z)."""
        f = self.factor(z)
        return f if self.ref == 1.0 else self.ref * f

    def to_z(self, v: float) -> float:
        self.check(v)
        r = self.ref
        if self.lo is not None and self.hi is not None:
            lo, hi = self.lo / r, self.hi / r
            if self.log:
                a, b = math.log(lo), math.log(hi)
                s = (math.log(v / r) - a) / (b - a)
            else:
                s = (v / r - lo) / (hi - lo)
            return math.log(s / (1.0 - s))
        return math.log(v / r) if self.log else float(v / r)


def param(name: str, lo=None, hi=None, log=True) -> Fitted:
    """A single Params leaf by dotted name (``"bond.kn"``)."""
    return Fitted(name=name, leaves=(name,), lo=lo, hi=hi, log=log)


def scale(name: str, leaves: Sequence[str], lo=None, hi=None, ref: float = 1.0) -> Fitted:
    """A common factor on several leaves: the value v multiplies each by v/ref (start: ref,
    the leaves' base values)."""
    return Fitted(name=name, leaves=tuple(leaves), scale=True, lo=lo, hi=hi, log=True,
                  ref=float(ref))


def stiffness(lo=0.1, hi=10.0) -> Fitted:
    """Scale of every solid spring (bond and contact, normal and shear): E_fit = v · E."""
    return scale("stiffness", STIFFNESS_LEAVES, lo=lo, hi=hi)


PRESETS = {"stiffness": stiffness}


def parse(spec: str) -> Fitted:
    """CLI form ``name[:lo:hi]`` (``stiffness:0.25:4``, ``dem.damping:0.1:100``)."""
    parts = spec.split(":")
    name = parts[0]
    bounds = [float(p) for p in parts[1:]] if len(parts) > 1 else []
    if len(bounds) not in (0, 2):
        raise ParameterError(f"fit spec {spec!r}: use name or name:lo:hi")
    lo, hi = (bounds + [None, None])[:2]
    if name in PRESETS:
        return PRESETS[name](*(b for b in bounds)) if bounds else PRESETS[name]()
    return param(name, lo, hi)


def _set_leaf(params: Params, dotted: str, value) -> Params:
    parts = dotted.split(".")

    def rec(obj, parts):
        if len(parts) == 1:
            return dataclasses.replace(obj, **{parts[0]: value})
        return dataclasses.replace(obj, **{parts[0]: rec(getattr(obj, parts[0]), parts[1:])})

    return rec(params, parts)


class ParamSpace:
    """The fitted quantities of a base ``Params``: z ↔ Params.

    ``start`` gives start values by name (default: the base's value, 1 for a scale)."""

    def __init__(self, base: Params, fitted: Sequence[Fitted], start: dict | None = None):
        if not fitted:
            raise ParameterError("nothing to fit: give at least one parameter")
        names = [f.name for f in fitted]
        if len(set(names)) != len(names):
            raise ParameterError(f"a parameter is fitted twice: {names}")
        self.base = base
        resolved = []
        for f in fitted:
            leaves = tuple(base.resolve(l) for l in f.leaves)
            resolved.append(dataclasses.replace(
                f, leaves=leaves, name=leaves[0] if (not f.scale and f.name == f.leaves[0])
                else f.name))
        self.fitted = tuple(resolved)
        start = dict(start or {})
        unknown = set(start) - {f.name for f in self.fitted}
        if unknown:
            raise ParameterError(f"start values for parameters not fitted: {sorted(unknown)}; "
                                 f"fitted: {[f.name for f in self.fitted]}")
        self.start = {f.name: float(start.get(f.name, f.ref if f.scale
                                              else np.asarray(base.get(f.leaves[0]))))
                      for f in self.fitted}
        self.z0 = jnp.asarray([f.to_z(self.start[f.name]) for f in self.fitted])

    @property
    def names(self) -> list[str]:
        return [f.name for f in self.fitted]

    def values(self, z):
        """Physical values (jnp array, one per fitted quantity)."""
        return jnp.stack([f.to_value(z[k]) for k, f in enumerate(self.fitted)])

    def params(self, z, base: Params | None = None) -> Params:
        """Params with the fitted leaves set from z (differentiable)."""
        p = self.base if base is None else base
        out = p
        for k, f in enumerate(self.fitted):
            v = f.factor(z[k]) if f.scale else f.to_value(z[k])
            for leaf in f.leaves:
                old = p.get(leaf)
                new = v * old if f.scale else v
                out = _set_leaf(out, leaf, jnp.asarray(new, dtype=jnp.asarray(old).dtype))
        return out

    def z_of(self, values: dict) -> jnp.ndarray:
        """z for physical values given by name (missing: the start value)."""
        return jnp.asarray([f.to_z(float(values.get(f.name, self.start[f.name])))
                            for f in self.fitted])

    def extreme(self, which: str = "hi") -> Params:
        """Host Params with every bounded fitted quantity at its ``which`` bound (others at
        their start): what the time-step bound is derived for."""
        vals = {}
        for f in self.fitted:
            b = f.hi if which == "hi" else f.lo
            vals[f.name] = self.start[f.name] if b is None else b
        p = self.params(self.z_of({k: v * (1 - 1e-9) if which == "hi" else v * (1 + 1e-9)
                                   for k, v in vals.items()}))
        return jax.tree_util.tree_map(lambda a: np.asarray(a).item() if np.ndim(a) == 0
                                      else np.asarray(a), p)

    def report(self, z) -> dict:
        """name → physical value, plus every leaf it sets."""
        v = np.asarray(self.values(z), float)
        out = {f.name: float(v[k]) for k, f in enumerate(self.fitted)}
        p = self.params(z)
        for f in self.fitted:
            for leaf in f.leaves:
                out.setdefault(leaf, float(np.asarray(p.get(leaf))))
        return out
