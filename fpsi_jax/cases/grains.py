"""Grains in a fluid, shared by the sedimentation and the two-phase scenes.

Grains are free DEM discs coupled to the fluid through voidage, drag, buoyancy and
lubrication (physics/fpi.py); fluid particles among grains get the mass ε ρ0 Δx² of the
fluid their lattice cell holds (:func:`fluid_among_grains`), so the start is at rest.
"""
from __future__ import annotations

from ..build.fluid import fit_spacing, fluid_among_grains  # noqa: F401  (re-exported)
from ..model.errors import ParameterError
from ..model.options import Voidage


def check_voidage(voidage):
    allowed = tuple(v.value for v in Voidage)
    if voidage not in allowed:
        raise ParameterError(f"voidage must be one of {allowed}, got {voidage!r}")
