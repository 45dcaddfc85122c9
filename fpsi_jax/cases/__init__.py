"""Scene builders: one per validation case, physical parameters as keyword arguments."""
from __future__ import annotations

import inspect

from ..model.errors import ParameterError
from .beams import bond_tension, cantilever, itasca_beam
from .dam_break import dam_break
from .dem_cases import collision, dry_dam_break, rolling, wall_impact
from .fpi_cases import fpsi_failure, sedimentation, two_phase_dam_break
from .fsi_cases import elastic_gate, gate_failure, hydrostatic_plate
from .hydrostatic_tank import hydrostatic_tank

SCENES = {
    "hydrostatic_tank": hydrostatic_tank,
    "dam_break": dam_break,
    "collision": collision,
    "rolling": rolling,
    "dry_dam_break": dry_dam_break,
    "wall_impact": wall_impact,
    "itasca_beam": itasca_beam,
    "cantilever": cantilever,
    "bond_tension": bond_tension,
    "hydrostatic_plate": hydrostatic_plate,
    "elastic_gate": elastic_gate,
    "gate_failure": gate_failure,
    "sedimentation": sedimentation,
    "two_phase_dam_break": two_phase_dam_break,
    "fpsi_failure": fpsi_failure,
}


def builder_keys(name: str) -> list[str]:
    return list(inspect.signature(get(name)).parameters)


def get(name: str):
    try:
        return SCENES[name]
    except KeyError:
        raise ParameterError(f"unknown scene {name!r}; available: {', '.join(SCENES)}") from None


def build(name: str, **kwargs):
    fn = get(name)
    keys = builder_keys(name)
    bad = [k for k in kwargs if k not in keys]
    if bad:
        raise ParameterError(f"scene {name!r} has no parameter {bad[0]!r}; allowed: "
                             f"{', '.join(keys)}")
    return fn(**kwargs).validate()
