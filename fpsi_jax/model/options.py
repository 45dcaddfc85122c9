"""Typed choices of the static configuration (:class:`~fpsi_jax.model.config.Physics`).

Each choice is a ``str`` enum: a scene, a ``--set key=value`` or a scene file may give the
plain string, :func:`choose` turns it into the member (or raises ParameterError listing the
allowed values), and the compiled code compares members, never strings. Being ``str``
subclasses they are written to JSON and HDF5 attributes as their values.
"""
from __future__ import annotations

import enum

from .errors import ParameterError


class Choice(str, enum.Enum):
    """Base of the option enums: the value is the name users write."""

    def __str__(self) -> str:
        return self.value


class KernelKind(Choice):
    """SPH smoothing kernel (physics/kernels.py)."""
    WENDLAND = "wendland"    # Wendland C2 (K28, W41)
    CUBIC = "cubic"          # cubic spline (Monaghan & Lattanzio 1985)


class BoundaryPressure(Choice):
    """Pressure of the fixed SPH boundary particles."""
    FIXED = "fixed"                  # W5/K5 method 1: ρ, P never change
    EXTRAPOLATED = "extrapolated"    # Adami, Hu & Adams (2012): P_b from the fluid


class DensityDiffusion(Choice):
    """Which density differences δ-SPH diffuses (physics/sph.py, ``delta_pairs``)."""
    MOLTENI = "molteni"        # Molteni & Colagrossi (2009): ρ_j − ρ_i
    FOURTAKAS = "fourtakas"    # Fourtakas et al. (2019): less the hydrostatic part


class FsiMethod(Choice):
    """Fluid–structure coupling (physics/fsi.py; K §5)."""
    STATIONARY = "stationary"                          # K method 1
    PRESSURE_GRADIENT = "pressure_gradient"            # K40
    PRESSURE_APPROXIMATION = "pressure_approximation"  # K41
    EXTRAPOLATED = "extrapolated"                      # Adami wall pressure on the structure


class BondSection(Choice):
    """Cross-section of a parallel bond (physics/bonds.py)."""
    SLAB = "slab"            # 2D: A = 2R̄t, I = (2/3)tR̄³
    CIRCULAR = "circular"    # A = πR̄², I = πR̄⁴/4 (K6.1's Itasca beam)


class Voidage(Choice):
    """What the fluid equations see of the grains' volume (physics/fpi.py)."""
    AREA = "area"            # ε = 1 − Σ V_p W (2D area fraction)
    MAPPED = "mapped"        # the equivalent 3D packing's voidage


class Drag(Choice):
    """The grains' drag closure (physics/fpi.py)."""
    SPHERE = "sphere"        # W19–W23: Ergun / Wen–Yu with Schiller–Naumann (a sphere's)
    CYLINDER = "cylinder"    # a disc as a cylinder per unit length (Sucker & Brauer 1975)


class FpiPressure(Choice):
    """The grains' buoyancy (physics/fpi.py)."""
    ARCHIMEDES = "archimedes"    # ρ_f V_p |g|
    GRADIENT = "gradient"        # −V_p ∇P of the SPH pressure
    SHARED = "shared"            # a cell's pressure force: ε to its fluid, 1 − ε to its grains


class Side(Choice):
    """A side of the domain rectangle; an open one lets particles out (Scene.open_sides)."""
    LEFT = "left"        # x < domain_lo[0]
    RIGHT = "right"      # x >= domain_hi[0]
    BOTTOM = "bottom"    # y < domain_lo[1]
    TOP = "top"          # y >= domain_hi[1]


def choose(kind: type[Choice], key: str, value) -> Choice:
    """``value`` (member or string) as a member of ``kind``; ParameterError naming ``key`` and
    the allowed values otherwise."""
    if isinstance(value, kind):
        return value
    try:
        return kind(value)
    except ValueError:
        allowed = ", ".join(m.value for m in kind)
        raise ParameterError(f"{key} = {value!r} is not a choice; allowed: {allowed}") from None
