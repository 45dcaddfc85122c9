"""Material mappings: DEM contact and parallel-bond constants from engineering ones
(Young's modulus E, Poisson's ratio ν, strength), physics.md §Parallel bonds.

``k42_mapping`` is the seed's (K42–K43), ``lattice_mapping`` the hexagonal-lattice one of
Griffiths & Mustoe (2001) that W cites, ``hexagonal_strength`` the bond strengths of a
hexagonal packing (W31–W34).
"""
from __future__ import annotations

import math

from ..model.errors import ParameterError, require


def _check_elastic(E, nu, nu_max=0.5):
    require("E", E, 0.0, None, lo_open=True)
    require("nu", nu, -1.0, nu_max, lo_open=True, hi_open=nu_max == 0.5)


def shear_modulus(E, nu):
    _check_elastic(E, nu)
    return E / (2.0 * (1.0 + nu))


def k42_mapping(E, nu, radius, lam=1.0, plate=False, contact_fraction=None, plane_strain=False,
                touching=True):
    """Bond and contact stiffnesses of K42–K43 for equal discs of radius R (R_A + R_B = 2R):
    k̄_n = E/(2R), k̄_s = G/(2R), k_n = E·2R̄/(2R) = λE, k_s = λG.

    ``plate=True`` is K's plate variant: E ← E(1−ν)/((1+ν)(1−2ν)) and k_s = ½k_n,
    k̄_s = ½k̄_n (K §6.3.3, "after the calibration procedure").

    ``contact_fraction=None`` keeps K's contact springs (k_n = λE: as stiff as the bond, so a
    bonded pair is twice as stiff in compression as in tension). A number c splits the same
    total stiffness as W26–W30 do instead: A k̄ + k = K42's A k̄ with k = c A k̄ (W: c = 0.01),
    so tension and compression differ by the fraction c only. ``touching=False`` is a
    stretched lattice (bonded discs a small gap apart, ``square_packing(column_spacing=…)``):
    there a bonded pair's contact spring never acts while the bond holds, so the bond keeps
    K42's whole stiffness and the contact springs the share c/(1 + c) (they act once the
    gap closes or the bond has broken).

    ``plane_strain=True`` maps a 2D slice of a wide plate (cylindrical bending): the normal
    stiffnesses use E' = E/(1−ν²), so the bonded strip has the plate's D = Ee³/(12(1−ν²))
    per unit width; the shear modulus stays G = E/(2(1+ν)).

    Returns bond_kn, bond_ks [Pa/m] and kn, ks [N/m per unit thickness]."""
    _check_elastic(E, nu)
    G = E / (2 * (1 + nu))
    if plane_strain:
        if plate:
            raise ParameterError("k42_mapping: plate and plane_strain are alternatives; "
                                 "choose one")
        E = E / (1 - nu * nu)
    require("radius", radius, 0.0, None, lo_open=True)
    require("lam", lam, 0.0, 1.0, lo_open=True)
    if plate:
        E = E * (1 - nu) / ((1 + nu) * (1 - 2 * nu))
        bkn, bks, kn, ks = E / (2 * radius), 0.25 * E / radius, lam * E, 0.5 * lam * E
    else:
        bkn, bks, kn, ks = E / (2 * radius), G / (2 * radius), lam * E, lam * G
    if contact_fraction is None:
        return dict(bond_kn=bkn, bond_ks=bks, kn=kn, ks=ks)
    require("contact_fraction", contact_fraction, 0.0, None)
    f = 1.0 + contact_fraction
    fb = f if touching else 1.0
    return dict(bond_kn=bkn / fb, bond_ks=bks / fb, kn=contact_fraction * kn / f,
                ks=contact_fraction * ks / f)


def lattice_mapping(E, nu, radius, thickness=1.0, lam=1.0, contact_fraction=0.01):
    """Hexagonal-lattice spring stiffnesses, plane stress (Griffiths & Mustoe 2001, W ref.
    [40]): K_n = E t/(√3 (1−ν)), K_s = K_n (1−3ν)/(1+ν); needs ν ≤ 1/3 (K_s ≥ 0).

    The total K_ij is split as in W26–W30: K = A k̄ + k with k = ``contact_fraction``·A k̄
    (W uses 0.01), A = 2R̄t the slab section of the bond. Returns bond_kn, bond_ks [Pa/m],
    kn, ks [N/m]."""
    _check_elastic(E, nu, nu_max=1.0 / 3.0)
    if nu > 1.0 / 3.0:
        raise ParameterError(f"nu = {nu} is out of range for the hexagonal-lattice mapping; "
                             "allowed (-1, 1/3] (k_s = k_n(1-3nu)/(1+nu) must be >= 0)")
    require("radius", radius, 0.0, None, lo_open=True)
    require("thickness", thickness, 0.0, None, lo_open=True)
    require("contact_fraction", contact_fraction, 0.0, None)
    Kn = E * thickness / (math.sqrt(3.0) * (1 - nu))
    Ks = Kn * (1 - 3 * nu) / (1 + nu)
    A = 2 * lam * radius * thickness
    f = 1.0 + contact_fraction
    return dict(bond_kn=Kn / (f * A), bond_ks=Ks / (f * A),
                kn=contact_fraction * Kn / f, ks=contact_fraction * Ks / f)


def hexagonal_strength(sigma_ult, nu, radius, thickness=1.0, lam=1.0):
    """Critical bond forces and stresses of a hexagonal packing (W31–W34, Tavarez & Plesha
    2007): f_n = R̄tσ(√3 − ν/√3)/(2(1−ν)), f_s = R̄tσ(1−3ν)/(2(1−ν)), σ = f/(2R̄t).
    Returns sigma_c, tau_c [Pa] and fn_crit, fs_crit [N]."""
    require("sigma_ult", sigma_ult, 0.0, None, lo_open=True)
    _check_elastic(1.0, nu)
    Rb = lam * radius
    fn = Rb * thickness * sigma_ult * (math.sqrt(3.0) - nu / math.sqrt(3.0)) / (2 * (1 - nu))
    fs = Rb * thickness * sigma_ult * (1 - 3 * nu) / (2 * (1 - nu))
    if fs <= 0:
        raise ParameterError(f"nu = {nu} gives a non-positive shear strength; allowed nu < 1/3")
    return dict(sigma_c=fn / (2 * Rb * thickness), tau_c=fs / (2 * Rb * thickness),
                fn_crit=fn, fs_crit=fs)
