"""Every key a scene file may hold: its type, SI unit, default and meaning.

This table is the single source of what a file can say: :mod:`.reader` checks a file
against it (unknown keys, types, ranges) and ``docs/scene-file.md`` is generated from it
(``python -c "from fpsi_jax.scenefile.schema import markdown; print(markdown())" >
docs/scene-file.md``).

Types: ``float`` (a number in the key's SI unit, or a string with a unit, ``"3.5 mm"``,
``"10 MPa"``), ``int``, ``bool``, ``str``, ``point`` [x, y], ``box`` [x0, y0, x1, y1]
(corners), ``polygon`` [[x, y], …] (≥ 3 vertices), ``polyline`` [[x, y], …] (≥ 2),
``points`` [[x, y], …] (≥ 1), ``region`` (a box, a polygon, or a list of boxes/polygons),
``range`` [a, b] with a < b, ``list`` (of strings), ``load`` (a table
``{region = …, force = [Fx, Fy]}``), ``move`` (a table ``{region = …, velocity = [vx,
vy]}``), ``vectors`` (a point, or one point per disc).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from ..model.config import NeighborConfig

REQUIRED = object()   # a key without a default must be given


@dataclass(frozen=True)
class Key:
    name: str
    type: str
    unit: str
    default: Any
    doc: str
    lo: float | None = None         # allowed range (numbers)
    hi: float | None = None
    lo_open: bool = False
    hi_open: bool = False
    choices: tuple | None = None

    @property
    def required(self) -> bool:
        return self.default is REQUIRED

    def range_text(self) -> str:
        if self.choices:
            return "one of " + ", ".join(repr(c) for c in self.choices)
        if self.lo is None and self.hi is None:
            return ""
        left = "(" if self.lo_open or self.lo is None else "["
        right = ")" if self.hi_open or self.hi is None else "]"
        return (f"{left}{'-inf' if self.lo is None else self.lo}, "
                f"{'inf' if self.hi is None else self.hi}{right}")


def _pos(name, unit, default, doc, **kw):
    return Key(name, "float", unit, default, doc, lo=0.0, lo_open=True, **kw)


PACKING = ("square", "hex")
MASS = ("disc", "lattice", "sphere")
SHAPE = "one of ``box``, ``polygon``, ``points``"

# Tables: name -> (is an array of tables, keys, doc). A '.' in a name is a sub-table.
TABLES: dict[str, tuple[bool, tuple[Key, ...], str]] = {}


def table(name, array, doc, *keys):
    TABLES[name] = (array, tuple(keys), doc)


table("scene", False, "What is run, for how long, and where.",
      Key("name", "str", "", None, "scene name (default: the file's stem)"),
      _pos("t_end", "s", REQUIRED, "physical time to simulate"),
      _pos("dt", "s", None, "time step (default: the stability bound; a larger one is "
           "refused). The bound resolves a free collision of discs with ≈ 4 steps, and the "
           "restitution of β then comes out ~10 % low: for collisional granular flows give "
           "≤ tc/50, tc = π/√(kn/m*(1 − β²)) (docs/physics.md, DEM contacts)"),
      Key("gravity", "point", "m/s²", (0.0, -9.81), "gravitational acceleration (y is up: "
          "a positive y component is refused; a tilted flume may tilt it)"),
      _pos("v_max", "m/s", None, "the flow's velocity scale (sets c0 = 10 v_max); default "
           "√(2 g H) with H the fluid's height, else the fastest initial disc speed, else 1"),
      Key("domain", "box", "m", None, "rectangle every particle must stay inside (default: "
          "the tank with `headroom` above it, grown to hold every body)"),
      Key("headroom", "float", "", 0.5, "room above the tank walls, × tank height",
          lo=0.0),
      Key("open_sides", "list", "", ["top"], "sides of the domain particles may leave "
          "through (left, right, bottom, top; \"none\": every side closed): a particle that "
          "crosses one is taken out of the computation and counted, one that crosses a closed "
          "side stops the run; with an open top, one that goes over the walls (beside the "
          "boundary particles, above the highest) is out too", choices=("left", "right", "bottom", "top", "none")))

table("fluid", False, "The (single) SPH fluid: material, resolution and numerics.",
      _pos("density", "kg/m³", 1000.0, "reference density ρ0"),
      Key("viscosity", "float", "Pa s", 1.0e-3, "dynamic viscosity μ", lo=0.0),
      _pos("dx", "m", REQUIRED, "initial particle spacing Δp"),
      _pos("h", "m", None, "smoothing length (default 1.25 dx). For waves give 2 dx and "
           "no `alpha`: at 1.25 dx a standing wave kept 0.22 of its height after four "
           "periods and a piston's waves came out 15–20 % low; at 2 dx without α all of "
           "it and −0.3 % (physics.md, *Waves*). For a grain bed under water give 2 dx as "
           "well: at 1.25 dx the water over a bed at rest kept moving at 5–6 % of √(gH), "
           "at 2 dx below 1 % (physics.md, *Packed beds*)"),
      _pos("sound_speed", "m/s", None, "numerical sound speed c0 (default: "
           "`sound_speed_factor` × v_max)"),
      _pos("sound_speed_factor", "", 10.0, "c0 = factor × v_max when sound_speed is not "
           "given (10: density varies by about 1 %)"),
      Key("gamma", "float", "", 7.0, "Tait exponent γ", lo=1.0),
      _pos("fit_width", "m", None, "stretch dx to the nearest spacing that fills this width "
           "with whole columns (a block that stops short of a wall sloshes)"),
      Key("delta", "float", "", 0.1, "δ-SPH coefficient (physics option delta_sph)",
          lo=0.0, hi=1.0),
      Key("alpha", "float", "", 0.0, "Monaghan artificial viscosity α (physics option "
          "artificial_viscosity)", lo=0.0, hi=1.0),
      Key("r_clump", "float", "", 0.01, "anti-clump strength", lo=0.0, hi=1.0),
      Key("eps_xsph", "float", "", 0.5, "XSPH coefficient ε", lo=0.0, hi=1.0))

table("fluid.region", True, "A body of still water (hydrostatic density, at rest unless "
      "`velocity`), filled on the fluid's dx lattice. Give `box` or `polygon`.",
      Key("box", "box", "m", None, "rectangle [x0, y0, x1, y1]"),
      Key("polygon", "polygon", "m", None, "polygon vertices"),
      Key("surface", "float", "m", None, "height of the free surface the hydrostatic "
          "pressure is measured from (default: the region's top)"),
      Key("velocity", "point", "m/s", (0.0, 0.0), "initial velocity"))

table("tank", False, "An open-top tank [0, width] × [0, height] of fixed SPH boundary "
      "particles (and DEM line walls for the discs).",
      _pos("width", "m", REQUIRED, "inner width"),
      _pos("height", "m", REQUIRED, "wall height"),
      _pos("dx_boundary", "m", None, "boundary particle spacing (default: the fluid's dx)"),
      _pos("h", "m", None, "boundary particles' smoothing length (default: the fluid's h)"),
      Key("layers", "int", "", None, "boundary layers (default: enough to cover 2h, ≥ 2)",
          lo=2),
      Key("dem_walls", "bool", "", None, "DEM line walls on the floor and sides (default: "
          "when the scene has discs)"),
      Key("lid", "bool", "", False, "close the top (DEM wall only)"))

table("obstacle", True, "A fixed body: SPH boundary particles filling it (on the tank's "
      "dx_boundary lattice) and DEM walls along its outline. Give `box`, `polygon` or "
      "`polyline`. In 2D it spans the channel's whole width: a pier or block standing on "
      "the floor is a weir the water must overtop. Its force probe sums the water on its "
      "particles and the discs on its walls, sampled every step (impacts show as spikes "
      "of a few steps: filter over a few ms before comparing with a load cell); where it "
      "stands on the floor, the water at its foot pushes both, and its vertical force "
      "there is the floor's and its split of that corner, not a lift.",
      Key("name", "str", "", None, "label; a force probe's `body` can name it"),
      Key("box", "box", "m", None, "rectangle [x0, y0, x1, y1], filled"),
      Key("polygon", "polygon", "m", None, "polygon, filled"),
      Key("polyline", "polyline", "m", None, "an open line, `layers` particle rows thick on "
          "its right-hand side (walking from the first vertex)"),
      _pos("dx", "m", None, "particle spacing (default: the tank's dx_boundary, else the "
           "fluid's dx)"),
      Key("layers", "int", "", None, "rows of a polyline (default: enough to cover 2h)",
          lo=1),
      Key("dem_walls", "bool", "", None, "DEM walls along the outline (default: when the "
          "scene has discs)"))

_DISC_COMMON = (
    Key("name", "str", "", REQUIRED, "label that probes and fits refer to"),
    Key("box", "box", "m", None, "fill [x0, y0, x1, y1] with a packing of discs `d`"),
    Key("polygon", "polygon", "m", None, "fill a polygon with a packing of discs `d`"),
    Key("points", "points", "m", None, "explicit disc centres"),
    _pos("d", "m", None, "disc diameter (with box/polygon; with points: 2 × radius)"),
    Key("radius", "radii", "m", None, "disc radius (with points): one number, or one per "
        "point (a polydisperse set; a structure takes one)"),
    Key("packing", "str", "", None, "packing of box/polygon (default: 'hex' for grains, "
        "'square' otherwise)", choices=PACKING),
    Key("rho", "float", "kg/m³", REQUIRED, "density (at least 10 kg/m³: a density in g/cm³ "
        "is written with its unit, \"2.65 g/cm3\"; 2.65 would be read as kg/m³ and set a "
        "DEM step ~30× too short)", lo=10.0),
    _pos("thickness", "m", 1.0, "out-of-plane thickness t of the discs' mass"),
    Key("velocity", "vectors", "m/s", (0.0, 0.0), "initial velocity (one vector, or one per "
        "disc); of a [[kinematic]] body, the constant velocity it moves at"),
    Key("clamp", "region", "m", None, "discs in this region are held fixed (a structure "
        "standing on the floor is fixed to it only by a clamp; without one it rests on "
        "the floor's DEM wall by contact and friction)"),
    Key("load", "load", "N", None, "external force {region = …, force = [Fx, Fy]} shared "
        "equally by the discs in the region (ramped by contacts.load_ramp)"),
    Key("move", "move", "m/s", None, "prescribed motion {region = …, velocity = [vx, vy]}: "
        "the discs in the region move at this constant velocity whatever the forces, "
        "without rotating; a structure's other discs follow through their bonds (a "
        "specimen compressed by its own end rows; a force probe with that `region` reads "
        "the load they carry)"),
)

table("structure", True, "A bonded body: discs glued by parallel bonds between touching "
      "neighbours, bond and contact stiffness from E and ν (K42–K43, W's 1 % contact "
      "split), mass per area ρ. Give `box`, `polygon` or `points`.",
      *_DISC_COMMON,
      _pos("E", "Pa", None, "Young's modulus of the bonds (K42; required unless [bonds] "
           "gives kn and ks): a square lattice loaded along its rows has E, a hexagonal one "
           "is stiffer (√3(1 − ν')E = 1.42 E for ν = 0.3 in an infinite lattice, "
           "Griffiths & Mustoe 2001; 1.33 E in examples/compression.toml)"),
      Key("nu", "float", "", 0.3, "Poisson's ratio", lo=-1.0, hi=0.5, lo_open=True,
          hi_open=True),
      Key("plane_strain", "bool", "", False, "map E/(1−ν²): a slice of a plate spanning "
          "the tank's width"),
      Key("stretch", "bool", "", False, "with a square-packed `box`: a strip of exactly the "
          "box's length, its end columns centred on x0 and x1, ⌊w/d⌋ gaps of w/⌊w/d⌋ ≥ d "
          "(bonds across the gaps are beam elements of their length; the end columns carry "
          "half a cell of mass; the bonds then keep all of K42's stiffness)"),
      Key("contact_fraction", "float", "", 0.01, "share of the stiffness in the contact "
          "springs (W26–W30). Where bonds can break, the pieces meet the walls and each "
          "other through these soft springs: a piece thrown against a wall can pass "
          "through it (the run stops, exit 3); give `[contacts] kn` of the walls' and "
          "pieces' contact (a 5 MPa wall of 5 mm discs broken by a bore needed 5·10⁶ N/m)", lo=0.0),
      _pos("shear_factor", "", 1.0, "multiplies the shear springs"),
      _pos("sigma_c", "Pa", 1.0e30, "bond tensile strength σ̄_c (K21)"),
      _pos("tau_c", "Pa", 1.0e30, "bond shear strength τ̄_c (K22)"),
      Key("mass_model", "str", "", "lattice", "disc mass: the packing's cell × ρ "
          "('lattice'), ρπR² ('disc') or ρ 4/3 πR³ ('sphere')", choices=MASS),
      Key("coupled", "bool", "", True, "takes part in the fluid sums (physics.coupling)"))

table("grains", True, "Free grains (discs of density ρ, mass ρπR²t): a packed bed that "
      "feels the fluid through voidage, buoyancy and drag. Give `box`, `polygon` or "
      "`points`. Beds run at their own voidage: under still water, flushed from under a "
      "gate, and with water running onto them dry (the water that enters the pores "
      "takes a wider kernel, `[physics] pore_neighbours`; physics.md, *Packed beds*). "
      "`[physics] voidage = \"mapped\"` with `eps_floor = 0.8` gives the seeds' floored "
      "set-up, whose pores hold about three times the water they should and whose grains "
      "take 0.82 of their buoyancy (physics.md, *Which voidage a 2D bed has*).",
      *_DISC_COMMON,
      Key("n", "int", "", None, "keep only the first n discs of the packing (rows from the "
          "bottom)", lo=1),
      Key("mass_model", "str", "", "disc", "disc mass model", choices=MASS))

table("discs", True, "Discs that are neither a bonded structure nor grains in the fluid "
      "(dry DEM: collisions, stacks, bars). Give `box`, `polygon` or `points`.",
      *_DISC_COMMON,
      Key("bonds", "str", "", "none", "'touching': bond every touching pair (constants from "
          "[bonds])", choices=("none", "touching")),
      Key("mass_model", "str", "", "disc", "disc mass model", choices=MASS),
      Key("grain", "bool", "", False, "couple to the fluid as grains (physics.fpi)"))

table("kinematic", True, "Discs moving as prescribed whatever the forces: at a constant "
      "velocity (a gate lifted at a given speed), in a sinusoidal stroke (`oscillate`: a "
      "wave maker) or along a displacement time series (`track`); they push the fluid and "
      "the grains. Give `box`, "
      "`polygon` or `points`. A force probe on them reads all that pushes them: the "
      "fluid's force and the free discs' contacts (a platen's load, the blows of "
      "grains or debris on a gate), what the drive must overcome.",
      *[k for k in _DISC_COMMON if k.name not in ("clamp", "load", "move")],
      Key("mass_model", "str", "", "lattice", "disc mass model", choices=MASS),
      Key("coupled", "bool", "", True, "takes part in the fluid sums (physics.coupling)"),
      Key("start", "float", "s", 0.0, "the body stands until this time, then moves at its "
          "`velocity` (one vector) (a dam-break gate lifted after the water settles)",
          lo=0.0),
      _pos("stop", "s", None, "the body stands again from this time (after `start`; "
           "default: never)"),
      Key("oscillate", "oscillate", "m", None, "a sinusoidal stroke instead of a constant "
          "velocity (a piston wave maker; the body translates, it does not turn): {amplitude = [ax, ay], period = T} and "
          "optionally phase = φ [rad] (default 0) and ramp = T_r [s] (default 0); the "
          "displacement from where the body is built is r(τ) A (sin(2πτ/T + φ) − sin φ), "
          "τ the time since `start`, r a half-cosine ramp from 0 to 1 over the first T_r; "
          "until `stop`"),
      Key("track", "str", "", None, "a CSV file (path from the scene file's folder) of "
          "the body's displacement: rows of time [s], x [m], y [m] (a header line is "
          "skipped), followed piecewise linearly from where the body is built; it stands "
          "before the first time and after the last (a piston stroke from a wave-maker "
          "transfer function, a measured gate opening)"))

table("contacts", False, "DEM contact law (W10–W17, K25). kn and ks default to the bonded "
      "structures' material; without a structure kn is required, unless every disc is "
      "clamped or kinematic (a rigid pier as a [[kinematic]] body at rest: no contact "
      "force is read, and the step takes no DEM sub-steps). The material's contact springs "
      "are 1 % of its bonds' (the structure's `contact_fraction`): a structure loaded "
      "through contacts, by a platen of kinematic discs or an obstacle's walls, is loaded "
      "through that soft interface (a 4 × 8 cm specimen of E 50 MPa compressed by a "
      "platen came out at 5 MPa), and a stiffer `kn` here stiffens the bonded pairs in "
      "compression too; such a load is better given as a `load`, or by moving the "
      "structure's own end rows (`move`; a force probe on them reads the load: a "
      "square lattice of E 10 MPa squeezed so read 10.0 MPa).",
      _pos("kn", "N/m", None, "normal contact stiffness: the force per metre of overlap "
           "on a disc of unit thickness, as PFC2D's kn (a 3D code's sphere stiffness in "
           "N/m is not it: divide by the depth the disc stands for)"),
      Key("ks", "float", "N/m", None, "shear contact stiffness (default ½ kn, or the "
          "material's)", lo=0.0),
      Key("friction", "float", "", 0.3, "Coulomb friction coefficient μ", lo=0.0),
      Key("beta_n", "float", "", 0.0, "normal dashpot ratio", lo=0.0, hi=1.0, hi_open=True),
      Key("beta_s", "float", "", 0.0, "shear dashpot ratio", lo=0.0, hi=1.0, hi_open=True),
      Key("alpha", "float", "", 0.0, "local damping α (K25); it switches with each "
          "velocity's sign, so gradients through it are not the loss's derivative: fit "
          "with `damping`", lo=0.0, hi=1.0, hi_open=True),
      Key("damping", "float", "1/s", 0.0, "mass-proportional viscous damping c", lo=0.0),
      Key("load_ramp", "float", "s", 0.0, "external loads grow linearly over this time",
          lo=0.0),
      Key("rolling_friction", "float", "", None, "rolling resistance μ_r (not in the seeds; "
          "default none): a couple μ_r R* F_n against each contact's relative rolling, "
          "R* = R_A R_B/(R_A + R_B) (Ai et al. 2011, model A; LIGGGHTS' cdt). Round discs "
          "without it roll on: a dry column collapse runs out too far and a heap slumps. "
          "Its sign(ω) has no useful derivative (as alpha)", lo=0.0))

table("bonds", False, "Parallel-bond constants (K17–K22); each key overrides what the "
      "structures' material gives.",
      _pos("kn", "Pa/m", None, "normal stiffness per area k̄_n"),
      Key("ks", "float", "Pa/m", None, "shear stiffness per area k̄_s", lo=0.0),
      _pos("sigma_c", "Pa", None, "tensile strength σ̄_c"),
      _pos("tau_c", "Pa", None, "shear strength τ̄_c"),
      Key("beta_bar", "float", "", 1.0, "moment factor β̄ in the tensile criterion", lo=0.0,
          hi=1.0),
      Key("lam", "float", "", 1.0, "bond radius multiplier λ", lo=0.0, hi=1.0, lo_open=True),
      _pos("thickness", "m", 1.0, "out-of-plane thickness of the slab section"))

table("fpi", False, "Fluid–grain coupling constants (W24 lubrication, added mass).",
      Key("lub_gap_min", "float", "", 0.02, "gap regularisation × d̄", lo=0.0, hi=1.0,
          lo_open=True),
      Key("lub_cutoff", "float", "", 0.1, "lubrication acts for gaps ≤ this × d̄", lo=0.0,
          hi=1.0),
      Key("added_mass", "float", "", 1.0, "added-mass coefficient C_a (1: a circular "
          "cylinder in potential flow); used with [physics] added_mass = true", lo=0.0,
          hi=10.0))

table("physics", False, "Which mechanisms are compiled (Physics options; docs/physics.md).",
      Key("coupling", "str", "", None, "fluid–structure coupling (default 'extrapolated' when "
          "fluid and coupled discs meet; 'none' turns it off)",
          choices=("extrapolated", "stationary", "pressure_gradient",
                   "pressure_approximation", "none")),
      Key("boundary_pressure", "str", "", "extrapolated", "pressure of the fixed boundary "
          "particles", choices=("fixed", "extrapolated")),
      Key("delta_sph", "bool", "", None, "δ-SPH density diffusion (default: fluid.delta > 0)"),
      Key("density_diffusion", "str", "", "fourtakas", "what δ-SPH diffuses: all density "
          "differences (Molteni & Colagrossi 2009) or the same less their hydrostatic part "
          "(Fourtakas et al. 2019)", choices=("molteni", "fourtakas")),
      Key("artificial_viscosity", "bool", "", None, "Monaghan viscosity (default: "
          "fluid.alpha > 0)"),
      Key("x64", "bool", "", False, "run in float64. float32 keeps a bonded structure's "
          "stresses (the bonds read the discs' displacements, not their coordinates: a "
          "standing wall's bond noise 4 kPa against 0.4 in float64), but a quasi-static "
          "deflection under local damping converges slowly in it (the cantilever at "
          "d = 1.25 mm 24 % short after six periods, 1.3 % at d = 2.5 mm): set it for "
          "static loads on slender strips"),
      Key("fpi", "bool", "", None, "grains feel the fluid (default: grains and fluid both "
          "present)"),
      Key("voidage", "str", "", "area", "voidage model", choices=("area", "mapped")),
      Key("drag", "str", "", "sphere", "grain drag closure: the seed's sphere law (W19–W23) "
          "or a disc as a cylinder per unit length", choices=("sphere", "cylinder")),
      Key("eps_floor", "float", "", 0.0, "lower bound of the fluid voidage (0: the physical "
          "voidage; with voidage 'mapped', 0.8 is the seeds' set-up, whose pore fluid is "
          "heavier than its pores hold: docs/physics.md, Packed beds)", lo=0.0,
          hi=1.0, hi_open=True),
      Key("wall_images", "bool", "", True, "the grains' mirror images in the DEM walls count "
          "in the voidage (the part of a grain's kernel inside a wall goes back to the "
          "fluid's side: a bed at rest loads the floor right), in the tank's walls and on the "
          "outer side of an obstacle's box or polygon (a polyline, with water on both sides, "
          "has none); false leaves the pores by the "
          "floor less tight and a bed on the floor buoyed about 7 % short"),
      Key("pore_neighbours", "float", "", 0.5, "the least share of the clear water's "
          "neighbours a fluid particle among grains keeps: water that runs into a bed's "
          "pores is spread over Δx²/ε, and its h grows to keep this share (shared "
          "pressure; 0: h follows the density alone and such water goes unstable: "
          "docs/physics.md, Packed beds)", lo=0.0, hi=1.0),
      Key("bond_section", "str", "", "slab", "bond cross-section",
          choices=("slab", "circular")),
      Key("kernel", "str", "", "wendland", "SPH kernel", choices=("wendland", "cubic")),
      Key("dem_substeps", "int", "", None, "DEM sub-steps per SPH step (default: the fewest "
          "the DEM bound needs)", lo=1),
      Key("dem_list_substeps", "bool", "", False, "the DEM contact list's skin test at "
          "every sub-step (false: once per SPH step, with the step's reach; a disc that "
          "outran it makes the run redo its chunk with the test at every sub-step)"),
      Key("structure_acceleration", "bool", "", False, "the structure discs' own "
          "acceleration in their extrapolated pressure, Adami's (g − a); false: g alone (a "
          "bonded disc's acceleration is its lattice's sub-step vibration)"),
      Key("xsph", "bool", "", True, "XSPH velocity smoothing"),
      Key("transport_continuity", "bool", "", True, "continuity with the velocity the "
          "particles move with, v + δv_XSPH (false: with v, as the seeds' K32)"),
      Key("shifting", "float", "", 0.0, "particle shifting coefficient A: each step "
          "δr = −A h² ∇C moves particles from crowded to sparse places, off at a free "
          "surface (0: off)", lo=0.0, hi=0.5),
      Key("variable_h", "bool", "", True, "variable smoothing length"),
      Key("lubrication", "bool", "", True, "lubrication between grains in fluid (W24)"),
      Key("added_mass", "bool", "", False, "the grains' added mass C_a ρ_f V_p (Du/Dt − "
          "dv/dt), C_a from [fpi] (off: the seeds have none)"),
      Key("fpi_pressure", "str", "", None,
          "pressure force on grains: 'shared' (each fluid cell's pressure force shared by "
          "fluid and grains; energy-conserving, stable in packed beds) or 'archimedes' "
          "(ρ_f V_p g, exact for an isolated grain, unstable in a bed at its own voidage); "
          "default: 'shared' when grains touch each other at the start, else 'archimedes'",
          choices=("archimedes", "gradient", "shared")),
      Key("capacity_multiplier", "float", "", NeighborConfig.capacity_multiplier, "room in the neighbour lists over "
          "what the start needs. A scene that splashes, or whose structure breaks into "
          "pieces, outgrows the start's lists: each time, the run grows them, recompiles "
          "the step and redoes the chunk (tens of seconds each; the run's summary says "
          "how long). A larger value starts them with more room, at the price of every "
          "step (each fluid row pays for its slots); a smoothing length that grows past "
          "the lists' reach (water running into a bed's pores: docs/physics.md, Packed "
          "beds) regrows them whatever this value", lo=1.0, hi=10.0),
      Key("rho_tolerance", "float", "", 0.3, "stop when |ρ/ρ0 − 1| exceeds this", lo=0.0,
          lo_open=True))

table("output", False, "What `fpsi run` writes.",
      Key("file", "str", "", None, "HDF5 path, relative to the scene file (default "
          "results/<name>.h5 in the working folder); an .xdmf and a _probes.csv go beside"),
      _pos("every", "s", None, "time between frames (default t_end/100)"),
      Key("plot", "bool", "", False, "draw the probes against their references and a "
          "snapshot"))

table("probe", True, "A measurement recorded after every step (fpsi_jax.run.probes).",
      Key("name", "str", "", REQUIRED, "label (HDF5 /probes/<name>, CSV columns "
          "<name>.<component>)"),
      Key("kind", "str", "", REQUIRED, "what is measured", choices=(
          "displacement", "force", "pressure", "water_level", "front", "bed_profile",
          "broken_bonds")),
      Key("body", "str", "", None, "name of a structure, grains, discs or kinematic group "
          "(displacement, force, bed_profile, broken_bonds, front), or of an obstacle (force: "
          "the water's force on its boundary particles and the discs' on its DEM walls), or "
          "`tank.floor`, `tank.left`, `tank.right` (force: the discs' contact load on that "
          "wall of the tank, a bed's effective weight on the floor; the water's is not in "
          "it, a pressure probe reads that). "
          "force on discs that move: the fluid's force (on grains: buoyancy and drag, at "
          "their centres; their contacts are not in it); on discs that are all held (a "
          "kinematic group, or a `region` inside a structure's clamp): the fluid's force "
          "plus the free discs' contacts and the bonds to them, the support's load. A "
          "force is the one on the body, per metre of thickness: water pushing it toward "
          "−x reads Fx < 0, and M is its moment about `about`, counter-clockwise "
          "positive"),
      Key("region", "region", "m", None, "only the body's discs in this region "
          "(displacement: e.g. the tip)"),
      Key("point", "point", "m", None, "pressure: where (weakly compressible: it carries "
          "sound waves at c0, so a released water column's floor pressure first dips and "
          "rings for a few H/c0 before it follows the flow); displacement: the body's disc "
          "nearest to it"),
      Key("about", "point", "m", None, "force: moment reference point (default: the "
          "discs' start centroid, or the obstacle's particles' centroid, or its walls' "
          "ends' without fluid)"),
      Key("x", "float", "m", None, "water_level: where (the highest particle within one "
          "spacing of x)"),
      Key("direction", "str", "", "+x", "front: which way; it reads the x of the farthest "
          "fluid particle that way (with a `body`, the farthest disc edge of it: how far "
          "grains were carried), so with water already downstream (a tailwater) it reads "
          "that water's end unless `above` is given", choices=("+x", "-x")),
      Key("above", "float", "m", None, "front: only water (or discs) higher than this y count: a "
           "bore over still tailwater is the farthest water above the tailwater's level"),
      Key("x_range", "range", "m", None, "bed_profile: from x0 to x1"),
      Key("bins", "int", "", 10, "bed_profile: columns of equal width between x0 and x1 "
          "(components z0, z1, …: column k centred at x0 + (k + ½)(x1 − x0)/bins); each reads "
          "the top of the highest grain in it, grains in suspension included", lo=1),
      Key("floor", "float", "m", 0.0, "water_level/bed_profile: value when dry or empty"),
      Key("reference", "str", "", None, "CSV to plot against (relative to the scene file; "
          "columns as `fpsi calibrate --data`)"))

table("calibration", False, "Defaults for `fpsi calibrate <file>` (each has a command-line "
      "flag that wins).",
      Key("data", "str", "", None, "measured CSV (relative to the scene file)"),
      Key("fit", "list", "", None, "what to fit: Params leaves (dem.damping) or material "
          "constants of a structure (gate.E), each optionally name:lo:hi"),
      Key("probe", "str", "", None, "the probe the data measures (default: the only one)"),
      Key("window", "range", "s", None, "fitted time window (default: the data's span)"),
      Key("holdout", "range", "s", None, "held-out window, reported but not fitted"),
      Key("target", "str", "", "trajectory", "'trajectory' (every sample), 'static' (the "
          "mean over the window) or 'vibration' (frequency and damping ratio)",
          choices=("trajectory", "static", "vibration")),
      Key("start", "list", "", None, "start values, name=value (default: the file's)"),
      Key("steps", "int", "", 30, "optimiser steps (max)", lo=1),
      Key("optimizer", "str", "", "lm", "optimiser", choices=("lm", "adam", "sgd")),
      Key("jacobian", "str", "", None, "'ad' (forward mode) or 'fd' (secant, for chaotic "
          "long coupled runs); default 'ad', or 'fd' where [contacts] alpha > 0 (local "
          "damping's sign(v) has no useful derivative)", choices=("ad", "fd")))


INTRO = """# Scene files

Describe your own case in a TOML file and run it:

    fpsi run my_case.toml --plot              # HDF5 + XDMF (ParaView), probes CSV, plots
    fpsi calibrate my_case.toml --data measured.csv --fit E,damping

Every value is in SI units: a plain number is in the unit the tables below give, and a
string with a unit is converted (`dx = "3.5 mm"`, `E = "10 MPa"`, `rho = "1.1 g/cm3"`); a
unit that measures something else is refused. A bad file is refused before anything is
built or compiled, with one line naming the file, the table and the key, and exit code 2:

    error: flume.toml: [[structure]] 'gate': key 'E' = -1.0 is out of range; allowed (0.0, inf) Pa

So are water or discs beside the tank's side walls or under its floor, an obstacle wholly
outside the tank (one reaching into a wall or under the floor is accepted: its particles
there only thicken the wall), a
probe's point or x outside the domain, a probe key its kind does not use (`body` on a
pressure probe), and a probe's `reference` curve that is not a CSV or has no column
measuring that probe.

Shipped files: `examples/<scene>.toml` for every registered scene (each builds exactly the
initial state of `fpsi run <scene>`), and examples of cases of your own
(`examples/*.toml`, `examples/calibrate/*.toml`). This page is generated from
`fpsi_jax/scenefile/schema.py` (`python -c "from fpsi_jax.scenefile.schema import
markdown; print(markdown())" > docs/scene-file.md`).

## How the parts fit together

* `[scene]` sets the time, gravity and the domain; `[fluid]` the single fluid's material
  and resolution, with one or more `[[fluid.region]]` bodies of still water (hydrostatic
  density, so nothing moves at t = 0).
* `[tank]` is an open box of fixed SPH boundary particles, with DEM line walls for the
  discs; `[[obstacle]]` adds fixed bodies (filled boxes and polygons, or layered
  polylines).
* Discs come in four kinds, numbered in this order: `[[discs]]` (dry DEM), `[[grains]]`
  (a bed that feels the fluid), `[[structure]]` (bonded bodies from E, ν, ρ) and
  `[[kinematic]]` (moving at a prescribed velocity). Every body has a `name` that probes and
  fits refer to. Bodies may touch but not overlap; water may fill a grain bed's pores but
  not a structure.
* The model holds one set of contact constants (`[contacts]`) and one bond material: every
  structure with E must share it.
* `[[probe]]` measurements are recorded after every step inside the compiled run
  (`/probes/<name>` in the HDF5 file, `<output>_probes.csv`) and plotted by `--plot` against
  the CSV named by `reference`.

Types: `float` (a number, or a string with a unit), `int`, `bool`, `str`, `point` [x, y],
`box` [x0, y0, x1, y1] (corners), `polygon` [[x, y], …] (≥ 3 vertices), `polyline`
(≥ 2), `points` (≥ 1), `region` (a box, a polygon, or a list of them), `range` [a, b] with
a < b, `list` (strings, or one comma-separated string), `load`
`{region = …, force = [Fx, Fy]}`, `move` `{region = …, velocity = [vx, vy]}`, `vectors`
(one [vx, vy] or one per disc), `radii` (one number or one per point). A component of a point, box, polygon or vector may carry
its unit too: `["20 cm", 0.0, "210 mm", 0.08]`.
"""

DATA = """## Data files (references and `fpsi calibrate --data`)

CSV with a header row naming each column with its unit in brackets; lines starting with
`#` are comments. The first column is the time; the others are probe components, written
`<probe>.<component>` (or just `<component>`):

    # tip of the gate, from the video
    t [s], tip.ux [mm], tip.uy [mm]
    0.04, 12.7, 0.84

Units are converted to SI and must measure what the probe measures (mm for a displacement
is fine, N is refused: forces are per metre of thickness, N/m). A column named for the
probe must name one of its components (`tip.uz` is refused, not skipped). Probe components: displacement `ux, uy` [m]; force `Fx, Fy` [N/m],
`M` [N m/m] (per metre of thickness); pressure `p` [Pa]; water_level `level` [m]; front
`x` [m]; bed_profile `z0, z1, …` [m]; broken_bonds `n` [-].

## What `fpsi calibrate --fit` accepts

A comma list (or a `fit` list in `[calibration]`), each `name` or `name:lo:hi` (bounds in
SI units; a positive quantity is fitted in log space):

- `<structure>.E` — Young's modulus [Pa]: a common scale on every spring it sets (bond and
  contact, normal and shear, unless `[bonds]` or `[contacts]` give them); plain `E` with
  one structure. Default bounds ×0.2 – ×5.
- `<structure>.sigma_c`, `<structure>.tau_c` — bond strengths [Pa].
- `stiffness` — a factor on every spring.
- any scalar `Params` leaf by its dotted name or a short name naming one leaf:
  `damping` (`dem.damping`, viscous damping c [1/s], default bounds ×0.01 – ×100 of its
  start), `dem.mu`, `bond.beta_bar`, …; an unknown name (`--fit Q`) is refused with the
  list of them.

`--start name=value` sets a start value (default: the file's); `--window a,b` the fitted
time span (default: the data's, which must then end by `[scene] t_end`), `--holdout a,b`
a span reported but not fitted. The run writes `<out>/<file>.json` (the command as typed,
start, fitted values, Gauss–Newton standard errors, loss history, RMS per component on
both windows, wall times) and `<out>/<file>.png` (measured against simulated at the start
and fitted values, and the loss); `--out` defaults to `results/calibrate`.

The loss is the mean of squared residuals: for 'trajectory' (u_sim − u_data)/max|u_data|
at every sample in the window, each component scaled by its largest measured value, so a
loss of 10⁻⁴ is an RMS misfit of 1 % of the signal; for 'static' (ū_sim − ū_data)/|ū_data|
of the window means; for 'vibration' log(f/f_data) and log(ζ/ζ_data). The RMS lines are
in SI units (m for a displacement measured in mm).

The fit steps at one Δt for every trial, the stability bound of the stiffest values its
bounds allow (the JSON's `run.dt_s`), usually shorter than the step `fpsi run` takes at the
file's values. A recording of your own model made with `fpsi run` (a synthetic test) then
differs from the fit's model by the step's error: on noise-free data the fitted values come
within that error of the truth, but the standard errors, which measure the misfit left,
need not cover it. Make such a recording with `fpsi run FILE --dt <run.dt_s>`.

What a fit can and cannot find. A bond strength (`sigma_c`, `tau_c`) is a threshold: the
record does not change with it until a bond reaches it, then jumps. Fit it against a
window in which bonds break, with the secant Jacobian (`--jacobian fd`), from a start
between the stress the bonds reach and the truth; where no bond reaches the strength the
residuals do not move with it, and the fit says so (an infinite standard error and a
note) instead of a value. A record of an impact with splash is chaotic: its loss has
several minima in a stiffness (a post under a bore: loss 0.022 / 0.043 / 0.020
at E = 2.5 / 3.0 / 3.5 MPa for a truth of 2), so fit a short window around the first
impact, from several starts (`--start`), and keep the lowest loss; a fit that stops
without improving prints that its standard errors are the curvature where it stalled.
'ad' and 'fd' are different compiled programs, so the float32 round-off of a chaotic run,
and with it the loss at the same start, differs between them (by 0.7 % for that post).
"""


def markdown() -> str:
    """docs/scene-file.md: every table and key with type, unit, default and meaning."""
    out = [INTRO]
    for name, (array, keys, doc) in TABLES.items():
        out += [f"## `[{'[' if array else ''}{name}{']' if array else ''}]`", "", doc, "",
                "| key | type | unit | default | allowed | meaning |",
                "|---|---|---|---|---|---|"]
        for k in keys:
            d = "required" if k.required else ("—" if k.default is None else
                                               f"`{_toml(k.default)}`")
            out.append(f"| `{k.name}` | {k.type} | {k.unit or '—'} | {d} | "
                       f"{k.range_text() or '—'} | {k.doc} |")
        out.append("")
    out.append(DATA)
    return "\n".join(out)


def _toml(v):
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (tuple, list)):
        return "[" + ", ".join(_toml(x) for x in v) + "]"
    if isinstance(v, str):
        return f'"{v}"'
    return repr(v)
