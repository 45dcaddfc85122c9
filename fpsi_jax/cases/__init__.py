"""The shipped scenes and their validation cases, one module per scene.

Each module holds a scene's builder (registered with :func:`~.registry.scene`: physical
parameters as keyword arguments) and, where it has them, its validation cases
(:func:`~.registry.validation`: reference, observer, metric), the observer ``fpsi run``
records and its plot. ``build(name, **kw)`` builds a registered scene by name; the
builders themselves are attributes of this package (``cases.dam_break(dx=0.01)``).
"""
from __future__ import annotations

# importing a module registers its scene and cases; this order is the order of
# ``fpsi list`` and ``fpsi validate``
from .hydrostatic_tank import hydrostatic_tank
from .dam_break import dam_break
from .collision import collision
from .rolling import rolling
from .dry_dam_break import dry_dam_break
from .wall_impact import wall_impact
from .itasca_beam import itasca_beam
from .cantilever import cantilever
from .bond_tension import bond_tension
from .hydrostatic_plate import hydrostatic_plate
from .elastic_gate import elastic_gate, gate_failure
from .sedimentation import sedimentation
from .grain_bed import grain_bed
from .two_phase_dam_break import two_phase_dam_break
from .fpsi_failure import fpsi_failure
from .registry import (CASES, DESCRIPTIONS, OBSERVERS, PLOTS, SCENE_OF, SCENES, build,
                       builder_keys, get)

__all__ = ["SCENES", "CASES", "DESCRIPTIONS", "SCENE_OF", "OBSERVERS", "PLOTS", "build",
           "builder_keys", "get", "hydrostatic_tank", "dam_break", "collision", "rolling",
           "dry_dam_break", "wall_impact", "itasca_beam", "cantilever", "bond_tension",
           "hydrostatic_plate", "elastic_gate", "gate_failure", "sedimentation",
           "grain_bed", "two_phase_dam_break", "fpsi_failure"]
