"""Bonded strips in water, shared by the hydrostatic plate and the elastic gate.

Both structures are bonded square packings of discs of diameter d: the 5 mm plate and gate
are 4 rows of d = 1.25 mm, and a bond of section 2R̄t between discs 2R apart is then an
exact bar, so K42 gives the continuum bending stiffness (see ``cantilever``). Both are thin
plates spanning the tank's width, so by default the bonds use the plane-strain modulus
E/(1−ν²) (``plane_strain=True``): the strip then has the plate stiffness D = Ee³/(12(1−ν²))
that the analytic plate solution (K44–K45) assumes. Disc masses are the packing's cell
area × ρ.
"""
from __future__ import annotations

from ..build import check_positive, k42_mapping
from ..model.errors import ParameterError
from ..model.options import FsiMethod, choose
from ..model.params import BondParams


def check_coupling(coupling):
    choose(FsiMethod, "coupling", coupling)


def bond_params(E, nu, d, plane_strain, sigma_c=1.0e30, tau_c=1.0e30, shear_factor=1.0,
                touching=True):
    """K42–K43 stiffnesses with W's 1 % contact split (the cantilever's default mapping);
    the shear springs (k̄_s, k_s) scaled by ``shear_factor``; ``touching=False`` for a
    stretched strip (k42_mapping). Returns (the mapping's dict, BondParams)."""
    check_positive(shear_factor=shear_factor)
    k = k42_mapping(E, nu, d / 2, contact_fraction=0.01, plane_strain=plane_strain,
                    touching=touching)
    k = {**k, "bond_ks": k["bond_ks"] * shear_factor, "ks": k["ks"] * shear_factor}
    return k, BondParams(kn=k["bond_kn"], ks=k["bond_ks"], sigma_c=sigma_c, tau_c=tau_c)


def rows(length, d, name):
    """round(length/d): the discs (or lattice rows) of spacing d in ``length``; at least one."""
    n = int(round(length / d))
    if n < 1:
        raise ParameterError(f"{name} = {length} holds no disc of diameter d = {d}")
    return n
