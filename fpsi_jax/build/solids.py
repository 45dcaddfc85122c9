"""DEM discs: mass models and solid blocks (numpy).

A disc's mass per unit thickness is ρπR² by default (PFC2D, physics.md §Conventions);
a bonded structure usually wants the packing's cell instead, so its mass per area is
exactly ρ (``mass_model='lattice'``).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..model.errors import ParameterError, check_positive
from ..model.params import BondParams
from ..model.scene import BondBlock, SolidBlock
from .geometry import hex_packing, in_region, square_packing, touching_pairs
from .materials import k42_mapping

MASS_MODELS = ("disc", "lattice", "sphere")


def disc_block(x, radius, rho, mass_model="disc", d_lattice=None, packing="hex",
               thickness=1.0, fixed=None, f_ext=None, v=None, column_spacing=None):
    """SolidBlock for discs at ``x``.

    mass_model  'disc':    m = ρπR²t, J = ½mR² (PFC2D default, physics.md §Conventions)
                'lattice': m = ρ·(cell area)·t with the cell of the packing, (√3/2)d²
                           (hex) or d² (square; d·s with columns ``column_spacing`` s
                           apart): the structure's mass per area is exactly ρ; J = ½mR²
                'sphere':  m = ρ(4/3)πR³, J = (2/5)mR² (K6.1: "particles considered
                           spherical")
    """
    x = np.asarray(x, float)
    n = x.shape[0]
    R = np.broadcast_to(np.asarray(radius, float), (n,)).copy()
    if mass_model not in MASS_MODELS:
        raise ParameterError(f"mass_model must be one of {MASS_MODELS}, got {mass_model!r}")
    if mass_model == "disc":
        m = rho * np.pi * R ** 2 * thickness
        J = 0.5 * m * R ** 2
    elif mass_model == "lattice":
        d = 2 * R if d_lattice is None else np.full(n, d_lattice)
        sx = d if column_spacing is None else column_spacing
        cell = (np.sqrt(3) / 2 if packing == "hex" else 1.0) * d * sx
        m = rho * cell * thickness
        J = 0.5 * m * R ** 2
    else:
        m = rho * 4.0 / 3.0 * np.pi * R ** 3
        J = 0.4 * m * R ** 2
    return SolidBlock(
        x=x, v=np.zeros((n, 2)) if v is None else np.asarray(v, float), omega=np.zeros(n),
        radius=R, mass=m, inertia=J,
        fixed=np.zeros(n, bool) if fixed is None else np.asarray(fixed, bool),
        f_ext=np.zeros((n, 2)) if f_ext is None else np.asarray(f_ext, float))


PACKINGS = ("hex", "square")


def packing(x0, y0, width, height, d, kind="hex", stretch=False):
    """Disc centres of diameter ``d`` filling [x0, x0+width] × [y0, y0+height]: 'hex'
    (:func:`~.geometry.hex_packing`) or 'square' (:func:`~.geometry.square_packing`;
    ``stretch``: a strip whose end columns stand on x0 and x0 + width)."""
    if kind not in PACKINGS:
        raise ParameterError(f"packing = {kind!r} is not a choice; allowed: {', '.join(PACKINGS)}")
    check_positive(width=width, height=height, d=d)
    if kind == "hex":
        if stretch:
            raise ParameterError("stretch applies to the square packing only")
        return hex_packing(x0, y0, width, height, d)
    return square_packing(x0, y0, width, height, d, stretch)


def strip_ends(blk: SolidBlock, x0, x1) -> SolidBlock:
    """Halve the mass and moment of inertia of the discs centred on x = x0 and x = x1: the
    lumped masses of a strip that ends at its end columns' centres (a stretched packing,
    ``packing(stretch=True)``), each end column standing for half a cell, so the strip's
    mass is ρ·height·length and its first frequency that of a strip of that length."""
    tol = 1e-9 * float(blk.radius.max())
    ends = (np.abs(blk.x[:, 0] - x0) <= tol) | (np.abs(blk.x[:, 0] - x1) <= tol)
    blk.mass = np.where(ends, 0.5 * blk.mass, blk.mass)
    blk.inertia = np.where(ends, 0.5 * blk.inertia, blk.inertia)
    return blk


def grain_bed(x0, y0, width, height, d, rho, kind="hex", n=None) -> SolidBlock:
    """Free grains (discs of diameter ``d``, density ``rho``, mass ρπR²) packed in the
    rectangle from its bottom row up; ``n`` keeps the first n (a bed of a given mass). The
    grains feel the fluid when the scene has option ``fpi``."""
    check_positive(rho=rho)
    x = packing(x0, y0, width, height, d, kind)
    if n is not None:
        if not 0 < n <= x.shape[0]:
            raise ParameterError(f"n = {n} grains out of range; allowed [1, {x.shape[0]}] "
                                 "for this bed")
        x = x[:n]
    blk = disc_block(x, d / 2, rho)
    blk.grain = np.ones(blk.n, bool)
    return blk


@dataclass
class Structure:
    """A bonded body: its discs, the bonds between touching discs, and the contact and bond
    constants from its material (:func:`bonded_body`)."""

    solid: SolidBlock
    bonds: BondBlock
    bond: BondParams
    kn: float
    ks: float


def bonded_body(x, d, E, nu, rho, *, kind="square", thickness=1.0, plane_strain=False,
                contact_fraction=0.01, sigma_c=1.0e30, tau_c=1.0e30,
                structure=True) -> Structure:
    """Discs of diameter ``d`` at ``x`` glued by parallel bonds between touching neighbours,
    with constants from Young's modulus E, Poisson's ratio ν and density ρ (K42–K43:
    k̄_n = E/d, k̄_s = G/d, split with the contact springs as W26–W30 do by
    ``contact_fraction``; ``plane_strain`` maps a 2D slice of a wide plate with E/(1−ν²)).
    The mass per area is exactly ρ (the packing's cell, ``mass_model='lattice'``) and the
    SPH volume of each disc its cell, so the body displaces the fluid it should. Strengths
    σ̄_c, τ̄_c [Pa] (unbreakable by default). ``structure`` marks the discs as structure,
    coupled to the fluid under option ``fsi``.

    E is the springs' modulus, not the assembly's: a square lattice loaded along its rows
    has about E (a beam's EI, docs/physics.md), a hexagonal one is stiffer (uniaxial
    compression of a 4 × 8 cm hexagonal specimen gave 1.27 E), and ν sets the shear
    springs, not the assembly's Poisson ratio. For a hexagonal lattice with the plane-stress E and ν, map
    with :func:`~.materials.lattice_mapping`; otherwise calibrate the assembly's constants
    (``fpsi calibrate``), as a PFC user would."""
    check_positive(d=d, rho=rho, thickness=thickness)
    if kind not in PACKINGS:
        raise ParameterError(f"packing = {kind!r} is not a choice; allowed: {', '.join(PACKINGS)}")
    k = k42_mapping(E, nu, d / 2, contact_fraction=contact_fraction, plane_strain=plane_strain)
    blk = disc_block(x, d / 2, rho, mass_model="lattice", packing=kind, thickness=thickness)
    blk.sph_volume = np.full(blk.n, (np.sqrt(3) / 2 if kind == "hex" else 1.0) * d * d)
    blk.structure = np.full(blk.n, bool(structure))
    return Structure(solid=blk, bonds=touching_pairs(blk.x, d / 2),
                     bond=BondParams(kn=k["bond_kn"], ks=k["bond_ks"], sigma_c=sigma_c,
                                     tau_c=tau_c),
                     kn=k["kn"], ks=k["ks"])


def bonded_rectangle(x0, y0, width, height, d, E, nu, rho, *, kind="square", thickness=1.0,
                     plane_strain=False, contact_fraction=0.01, sigma_c=1.0e30,
                     tau_c=1.0e30, structure=True) -> Structure:
    """A bonded plate or beam [x0, x0+width] × [y0, y0+height] of discs ``d``: :func:`packing`
    of ``kind`` ('square' by default here; :func:`packing`'s own default is 'hex') glued by
    :func:`bonded_body`, whose keywords these are.

    What the body then needs is set on the returned ``Structure``: clamped discs with
    :func:`clamp`, prescribed motion with :func:`move`, a load as forces per disc [N per
    metre of thickness] in ``structure.solid.f_ext`` (ramped in over
    ``DemParams.load_ramp`` s when that is set, applied at once otherwise); gravity is the
    scene's, ``Params(gravity=…)``."""
    return bonded_body(packing(x0, y0, width, height, d, kind), d, E, nu, rho, kind=kind,
                       thickness=thickness, plane_strain=plane_strain,
                       contact_fraction=contact_fraction, sigma_c=sigma_c, tau_c=tau_c,
                       structure=structure)


def clamp(solid: SolidBlock, region) -> np.ndarray:
    """Clamp the discs of ``solid`` in ``region`` (a rectangle (x0, y0, x1, y1), a polygon or
    a mask function; :func:`~.geometry.in_region`): they keep v = ω = 0. Returns their
    indices; ParameterError when the region holds no disc."""
    return move(solid, region, (0.0, 0.0))


def move(solid: SolidBlock, region, velocity) -> np.ndarray:
    """Prescribe the motion of the discs in ``region``: they move at the constant
    ``velocity`` (vx, vy) [m/s] whatever the forces (kinematic discs, e.g. a gate lifted at
    a given speed), without rotating. Returns their indices."""
    sel = in_region(solid.x, region)
    if not sel.any():
        raise ParameterError(f"region {region!r} holds no disc")
    v = np.asarray(velocity, float)
    if v.shape != (2,) or not np.all(np.isfinite(v)):
        raise ParameterError(f"velocity = {velocity!r}; allowed a finite (vx, vy)")
    solid.fixed = np.asarray(solid.fixed, bool) | sel
    solid.v = np.where(sel[:, None], v[None, :], np.asarray(solid.v, float))
    solid.omega = np.where(sel, 0.0, np.asarray(solid.omega, float))
    return np.nonzero(sel)[0]


def merge(*parts):
    """One (SolidBlock, BondBlock or None) from several SolidBlocks or Structures, bond
    indices shifted; the masks (structure, grain, sph_volume) made explicit."""
    blocks = [p.solid if isinstance(p, Structure) else p for p in parts]
    cat = lambda k: np.concatenate([np.asarray(getattr(b, k)) for b in blocks])
    mask = lambda k, default: np.concatenate([
        np.full(b.n, default) if getattr(b, k) is None else np.asarray(getattr(b, k), bool)
        for b in blocks])
    solid = SolidBlock(x=cat("x"), v=cat("v"), omega=cat("omega"), radius=cat("radius"),
                       mass=cat("mass"), inertia=cat("inertia"), fixed=cat("fixed"),
                       f_ext=cat("f_ext"), structure=mask("structure", False),
                       sph_volume=np.concatenate([b.volumes() for b in blocks]),
                       grain=mask("grain", False))
    ii, jj, off = [], [], 0
    for p, b in zip(parts, blocks):
        if isinstance(p, Structure):
            ii.append(np.asarray(p.bonds.i) + off)
            jj.append(np.asarray(p.bonds.j) + off)
        off += b.n
    bonds = (BondBlock(i=np.concatenate(ii).astype(np.int32), j=np.concatenate(jj).astype(np.int32))
             if ii else None)
    return solid, bonds
