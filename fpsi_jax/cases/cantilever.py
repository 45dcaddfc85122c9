"""Bonded-structure validation scenes: Itasca beam (K6.1), cantilever (K6.3.3) and a bar
pulled to failure."""
from __future__ import annotations

import math

import numpy as np

from ..build import (check_positive, disc_block, hex_packing, hexagonal_strength, k42_mapping,
                     lattice_mapping, square_packing, touching_pairs)
from ..model.errors import ParameterError, require
from ..model.params import BondParams, DemParams, Params
from ..model.scene import BondBlock, Scene

INCH = 0.0254                 # m
KIP = 4448.2216152605         # N
MAPPINGS = ("lattice", "k42", "k42_plate", "k42_split")
PACKINGS = ("hex", "square")


def itasca_beam(*, n_balls=11, radius=10 * INCH, bond_radius=8 * INCH,
                kn_bar=500 * KIP / INCH ** 3, ks_bar=188 * KIP / INCH ** 3, load=1 * KIP,
                rho=7850.0, alpha=0.7, t_end=3.0) -> Scene:
    """K6.1 / Itasca's parallel-bond beam: ``n_balls`` balls of radius R in a row joined by
    circular bonds of radius R̄ = 8 in (λ = 0.8), k̄_n = 500 kip/in³, k̄_s = 188 kip/in³,
    μ = 0, ball 0 clamped, ``load`` downwards on the last ball, no gravity, local damping 0.7
    to reach the static state. Spherical balls (K: "particles considered spherical").
    SI units (1 in = 0.0254 m, 1 kip = 4448.22 N).

    Euler–Bernoulli: δ = PL³/(3EI), E = k̄_n·2R, I = πR̄⁴/4, L = 2R(n − 1): 0.082893 in."""
    check_positive(radius=radius, bond_radius=bond_radius, kn_bar=kn_bar, ks_bar=ks_bar,
                   load=load, rho=rho, t_end=t_end)
    if n_balls < 2:
        raise ParameterError(f"n_balls = {n_balls} out of range; allowed [2, inf)")
    lam = bond_radius / radius
    require("bond_radius / radius", lam, 0.0, 1.0, lo_open=True)
    x = np.stack([2 * radius * np.arange(n_balls), np.zeros(n_balls)], axis=1)
    fixed = np.zeros(n_balls, bool)
    fixed[0] = True
    f_ext = np.zeros((n_balls, 2))
    f_ext[-1, 1] = -load
    blk = disc_block(x, radius, rho, mass_model="sphere", fixed=fixed, f_ext=f_ext)
    bonds = BondBlock(i=np.arange(n_balls - 1, dtype=np.int32),
                      j=np.arange(1, n_balls, dtype=np.int32))
    area = math.pi * bond_radius ** 2
    L = 2 * radius * (n_balls - 1)
    return Scene(
        name="itasca_beam",
        params=Params(gravity=(0.0, 0.0),
                      dem=DemParams(kn=kn_bar * area, ks=0.0, mu=0.0, alpha=alpha),
                      bond=BondParams(kn=kn_bar, ks=ks_bar, lam=lam)),
        domain_lo=(-2 * radius, -L / 2), domain_hi=(L + 2 * radius, L / 2), v_max=1.0,
        solid=blk, bonds=bonds, t_end=t_end,
        options={"bond_section": "circular", "x64": True},
        builder_kwargs=dict(n_balls=n_balls, radius=radius, bond_radius=bond_radius,
                            kn_bar=kn_bar, ks_bar=ks_bar, load=load, rho=rho, alpha=alpha,
                            t_end=t_end))


def beam_discs(length, height, d, packing="hex", clamp_columns=3):
    """Disc centres of a beam clamped at x = 0 and free at x = ``length``: rows along x, the
    discs with x ≤ 0 (``clamp_columns`` of them per row) are the clamp. The packing is chosen
    so that some rows have a disc centre exactly at x = length (the loaded tip discs).
    Returns (x, fixed, tip)."""
    if packing not in PACKINGS:
        raise ParameterError(f"packing must be one of {PACKINGS}, got {packing!r}")
    n_half = int(math.ceil(length / d)) + clamp_columns + 1
    width = (n_half + 1) * d
    x = (hex_packing if packing == "hex" else square_packing)(0.0, 0.0, width, height, d)
    # put a tip disc of the top row (hex: of the rows like it) at x = length
    top = x[:, 1] == x[:, 1].max()
    x[:, 0] += length - x[top, 0].max()
    tol = 1e-9 * d
    x = x[x[:, 0] <= length + tol]
    clamp_limit = -(clamp_columns - 1) * d - tol
    x = x[x[:, 0] >= clamp_limit - d / 2]
    fixed = x[:, 0] <= tol
    tip = np.abs(x[:, 0] - length) <= tol
    x[:, 1] -= x[:, 1].mean()
    return x, fixed, tip


def cantilever(*, length=0.079375, height=0.005, d=0.00125, E=10.0e6, nu=0.33, rho=1100.0,
               load=1.0, mapping="k42_split", packing="square", variant="tip", alpha=None,
               damping=0.0, amplitude=0.02, clamp_columns=3, t_end=None) -> Scene:
    """K6.3.3's rubber strip: ``length`` × ``height`` (5 mm × 79.375 mm), E = 10 MPa, discs
    d = 1.25 mm, clamped at x = 0, per unit width (t = 1 m), no gravity.

    variant 'tip'   ``load`` [N] downwards shared by the tip discs (x = length), local
                    damping α = 0.7 to the static state; Euler–Bernoulli δ = PL³/(3EI) with
                    I = height³/12: 1.6 mm
    variant 'free'  no load, no damping; initial velocity in the first Euler–Bernoulli mode
                    shape with ``amplitude`` m/s at the tip; f1 = (1.875²/2π)√(EI/(ρAL⁴))
    mapping         'k42_split' (default: K42–K43 bond stiffness, the total split as in
                    W26–W30 with 1 % in the contact springs), 'k42' (K42–K43 literally: the
                    contact springs as stiff as the bond), 'k42_plate' (K's plate variant,
                    k_s = ½k_n), 'lattice' (hexagonal plane stress, Griffiths & Mustoe;
                    ν ≤ 1/3)
    packing         'square' (default: 4 rows of d = 1.25 mm fill the 5 mm exactly, and a
                    bond of section 2R̄t between discs 2R apart is then an exact bar, so K42
                    gives the continuum EI) or 'hex' (4 rows fit, representing 4.33 mm)
    damping         mass-proportional viscous damping rate c [1/s] (DemParams.damping): the
                    first mode decays with damping ratio ζ1 = c/(4π f1)
    The clamp is the discs with x ≤ 0; with the square packing the last clamped column sits at
    −d/2, so the as-built span from it to the loaded tip column is L + d/2 (80 mm).
    Disc masses: the packing's cell area (mass per area exactly ρ; physics.md allows it).
    """
    check_positive(length=length, height=height, d=d, E=E, rho=rho, load=load)
    if mapping not in MAPPINGS:
        raise ParameterError(f"mapping must be one of {MAPPINGS}, got {mapping!r}")
    if variant not in ("tip", "free"):
        raise ParameterError(f"variant must be 'tip' or 'free', got {variant!r}")
    x, fixed, tip = beam_discs(length, height, d, packing, clamp_columns)
    R = d / 2
    if mapping == "lattice":
        k = lattice_mapping(E, nu, R)
    elif mapping == "k42_split":
        k = k42_mapping(E, nu, R, contact_fraction=0.01)
    else:
        k = k42_mapping(E, nu, R, plate=mapping == "k42_plate")
    f_ext = np.zeros_like(x)
    v = np.zeros_like(x)
    if variant == "tip":
        f_ext[tip, 1] = -load / tip.sum()
        alpha = 0.7 if alpha is None else alpha
    else:
        alpha = 0.0 if alpha is None else alpha
        v[:, 1] = amplitude * mode_shape(np.clip(x[:, 0], 0, None) / length)
    blk = disc_block(x, R, rho, mass_model="lattice", packing=packing, fixed=fixed, f_ext=f_ext,
                     v=v)
    bonds = touching_pairs(x, R)
    if t_end is None:
        f1 = euler_bernoulli_f1(E, rho, height, length)
        # six periods either way: the local damping of the static variant converges per
        # step, not per period (at 4 periods and the issue-7 step, 27 k steps, the tip still
        # moved 0.24 % over the last tenth of the run; at 6, 0.02 %)
        t_end = 6.0 / f1
    pad = 0.3 * length
    return Scene(
        name="cantilever",
        params=Params(gravity=(0.0, 0.0),
                      dem=DemParams(kn=k["kn"], ks=k["ks"], mu=0.0, alpha=alpha,
                                    damping=damping),
                      bond=BondParams(kn=k["bond_kn"], ks=k["bond_ks"])),
        domain_lo=(-clamp_columns * d - pad, -pad), domain_hi=(length + pad, pad), v_max=1.0,
        solid=blk, bonds=bonds, t_end=t_end, options={"x64": True},
        builder_kwargs=dict(length=length, height=height, d=d, E=E, nu=nu, rho=rho, load=load,
                            mapping=mapping, packing=packing, variant=variant, alpha=alpha,
                            damping=damping, amplitude=amplitude, clamp_columns=clamp_columns, t_end=t_end))


def mode_shape(s):
    """First Euler–Bernoulli cantilever mode φ(s), s = x/L, normalised to φ(1) = 1."""
    b = 1.8751040687
    sig = (math.cosh(b) + math.cos(b)) / (math.sinh(b) + math.sin(b))
    phi = lambda z: np.cosh(b * z) - np.cos(b * z) - sig * (np.sinh(b * z) - np.sin(b * z))
    return phi(s) / phi(1.0)


def euler_bernoulli_f1(E, rho, height, length):
    """f1 = (1.875²/2π) √(EI/(ρAL⁴)), I = h³/12, A = h per unit width."""
    return 1.8751040687 ** 2 / (2 * math.pi) * math.sqrt(E * height ** 2 / 12 / (rho * length ** 4))


def tip_deflection(load, length, E, height):
    """Euler–Bernoulli δ = PL³/(3EI), I = h³/12 per unit width."""
    return load * length ** 3 / (3 * E * height ** 3 / 12)


def bond_tension(*, n_discs=5, d=0.01, rho=2700.0, kn_bar=1.0e9, ks_bar=4.0e8,
                 sigma_c=1.0e6, tau_c=1.0e30, beta_bar=1.0, ramp_time=1.0, alpha=0.7,
                 t_end=None) -> Scene:
    """A straight bar of ``n_discs`` bonded discs (slab bonds), the first clamped, the last
    pulled along the bar by a force growing linearly to 2σ̄_c A over ``ramp_time``: the
    bonds should break in tension when F/A = σ̄_c, at t = ramp_time/2."""
    check_positive(d=d, rho=rho, kn_bar=kn_bar, sigma_c=sigma_c, ramp_time=ramp_time)
    if n_discs < 2:
        raise ParameterError(f"n_discs = {n_discs} out of range; allowed [2, inf)")
    x = np.stack([d * np.arange(n_discs), np.zeros(n_discs)], axis=1)
    fixed = np.zeros(n_discs, bool)
    fixed[0] = True
    area = d * 1.0                         # slab: 2R̄t with λ = 1, t = 1 m
    f_ext = np.zeros((n_discs, 2))
    f_ext[-1, 0] = 2 * sigma_c * area
    blk = disc_block(x, d / 2, rho, fixed=fixed, f_ext=f_ext)
    bonds = BondBlock(i=np.arange(n_discs - 1, dtype=np.int32),
                      j=np.arange(1, n_discs, dtype=np.int32))
    # after the break the freed end flies off under the load: stop soon after, in a long box
    t_end = 0.51 * ramp_time if t_end is None else t_end
    L = d * n_discs
    return Scene(
        name="bond_tension",
        params=Params(gravity=(0.0, 0.0),
                      dem=DemParams(kn=kn_bar * area, ks=0.0, mu=0.0, alpha=alpha,
                                    load_ramp=ramp_time),
                      bond=BondParams(kn=kn_bar, ks=ks_bar, sigma_c=sigma_c, tau_c=tau_c,
                                      beta_bar=beta_bar)),
        domain_lo=(-L, -L), domain_hi=(L + 100 * L, L), v_max=1.0, solid=blk, bonds=bonds,
        t_end=t_end, options={"x64": True},
        builder_kwargs=dict(n_discs=n_discs, d=d, rho=rho, kn_bar=kn_bar, ks_bar=ks_bar,
                            sigma_c=sigma_c, tau_c=tau_c, beta_bar=beta_bar,
                            ramp_time=ramp_time, alpha=alpha, t_end=t_end))


__all__ = ["itasca_beam", "cantilever", "bond_tension", "beam_discs", "mode_shape",
           "euler_bernoulli_f1", "tip_deflection", "hexagonal_strength"]
