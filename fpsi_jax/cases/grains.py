"""Grains in a fluid, shared by the sedimentation and the two-phase scenes.

Grains are free DEM discs coupled to the fluid through voidage, drag, buoyancy and
lubrication (physics/fpi.py); fluid particles among grains get the mass ε ρ0 Δx² of the
fluid their lattice cell holds (:func:`fluid_among_grains`), so the start is at rest.
"""
from __future__ import annotations

import numpy as np

from ..model.errors import ParameterError
from ..model.options import Voidage
from ..physics import fpi, kernels


def check_voidage(voidage):
    allowed = tuple(v.value for v in Voidage)
    if voidage not in allowed:
        raise ParameterError(f"voidage must be one of {allowed}, got {voidage!r}")


def fluid_among_grains(fluid, x_grain, r_grain, voidage, eps_floor=0.0):
    """Scale the masses of the fluid particles by the voidage the grains leave them."""
    eps = np.asarray(fpi.voidage_at(kernels.get("wendland"), fluid.x, fluid.h, x_grain,
                                    np.pi * np.asarray(r_grain) ** 2, voidage), float)
    eps = np.maximum(eps, eps_floor)
    fluid.mass = fluid.mass * eps
    return fluid


def fit_spacing(width, dx):
    """The spacing nearest ``dx`` that fills ``width`` with whole columns (a fluid block that
    stops short of a wall by more than dx/2 starts out of balance and sloshes)."""
    return width / max(1, round(width / dx))
