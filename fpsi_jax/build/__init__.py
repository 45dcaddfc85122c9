"""Public scene builders: everything a user needs to describe their own case.

Geometry (:mod:`.geometry`: lattices, packings, polygons, regions), SPH fluid blocks and the
sound-speed rule (:mod:`.fluid`), tanks of fixed boundary particles with optional DEM walls
and the domain around them (:mod:`.tank`), DEM discs, grain beds, bonded bodies from E, ν
and ρ, clamps and prescribed motion (:mod:`.solids`), and material mappings
(:mod:`.materials`). Every shipped scene in :mod:`fpsi_jax.cases` is built from these;
a :class:`~fpsi_jax.model.scene.Scene` puts the parts together.
"""
from ..model.errors import check_positive
from .fluid import (G, dam_speed, fit_spacing, fluid_among_grains, fluid_block,
                    fluid_polygon, fluid_rectangle, hydrostatic_fluid, sound_speed, sph_params)
from .geometry import (box_walls, hex_packing, in_region, inside_polygon, lattice,
                       polygon_lattice, span_spacing, square_packing, tank_walls,
                       touching_pairs)
from .materials import hexagonal_strength, k42_mapping, lattice_mapping, shear_modulus
from .solids import (MASS_MODELS, PACKINGS, Structure, bonded_body, bonded_rectangle, clamp,
                     disc_block, grain_bed, merge, move, packing, strip_ends)
from .tank import Tank, boundary_block, boundary_layers, domain, tank

__all__ = ["check_positive", "G", "dam_speed", "fit_spacing", "fluid_among_grains", "fluid_block", "fluid_polygon",
           "fluid_rectangle", "hydrostatic_fluid", "sound_speed", "sph_params", "box_walls",
           "hex_packing", "in_region", "inside_polygon", "lattice", "polygon_lattice",
           "span_spacing", "square_packing", "tank_walls", "touching_pairs", "hexagonal_strength",
           "k42_mapping", "lattice_mapping", "shear_modulus", "MASS_MODELS", "PACKINGS",
           "Structure", "bonded_body", "bonded_rectangle", "clamp", "disc_block", "grain_bed",
           "merge", "move", "packing", "strip_ends", "Tank", "boundary_block", "boundary_layers", "domain",
           "tank"]
