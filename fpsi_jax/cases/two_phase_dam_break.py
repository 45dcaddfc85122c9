"""Fluid–particle scenes (issue 5; seed 000 §6.2–6.3): a grain settling in a closed channel
(Glowinski et al. 2001 as set up in W6.2.1), the two-phase dam break of Sun et al. (2013)
(W6.2.2) and the three-phase case with a breaking structure (W6.3).

Grains are free DEM discs coupled to the fluid through voidage, drag, buoyancy and
lubrication (``fpi.py``); fluid particles among grains get the mass ε ρ0 Δx² of the fluid
their lattice cell holds (:func:`_fluid_among_grains`), so the start is at rest.
"""
from __future__ import annotations

import math

import numpy as np

from ..build import (G, boundary_block, boundary_layers, box_walls, check_positive, disc_block,
                     hex_packing, hydrostatic_fluid, lattice, sph_params, square_packing,
                     tank_walls, touching_pairs)
from ..model.errors import ParameterError
from ..model.options import Voidage
from ..model.params import BondParams, DemParams, FpiParams, Params
from ..model.scene import Scene, SolidBlock
from ..physics import fpi, kernels


def _check_choice(name, value, allowed):
    if value not in allowed:
        raise ParameterError(f"{name} must be one of {allowed}, got {value!r}")


def _fluid_among_grains(fluid, x_grain, r_grain, voidage, eps_floor=0.0):
    """Scale the masses of the fluid particles by the voidage the grains leave them."""
    eps = np.asarray(fpi.voidage_at(kernels.get("wendland"), fluid.x, fluid.h, x_grain,
                                    np.pi * np.asarray(r_grain) ** 2, voidage), float)
    eps = np.maximum(eps, eps_floor)
    fluid.mass = fluid.mass * eps
    return fluid


def _fit(width, dx):
    """The spacing nearest ``dx`` that fills ``width`` with whole columns (a fluid block that
    stops short of a wall by more than dx/2 starts out of balance and sloshes)."""
    return width / max(1, round(width / dx))


def _merge(*blocks: SolidBlock) -> SolidBlock:
    """One SolidBlock from several (masks concatenated; None masks become explicit)."""
    cat = lambda k: np.concatenate([np.asarray(getattr(b, k)) for b in blocks])
    mask = lambda k, default: np.concatenate([
        np.full(b.n, default) if getattr(b, k) is None else np.asarray(getattr(b, k), bool)
        for b in blocks])
    vol = np.concatenate([(2 * b.radius) ** 2 if b.sph_volume is None else b.sph_volume
                          for b in blocks])
    return SolidBlock(x=cat("x"), v=cat("v"), omega=cat("omega"), radius=cat("radius"),
                      mass=cat("mass"), inertia=cat("inertia"), fixed=cat("fixed"),
                      f_ext=cat("f_ext"), structure=mask("structure", False),
                      sph_volume=vol, grain=mask("grain", False))


# --- single grain in a closed channel -------------------------------------------------------
def sedimentation(*, width=0.02, height=0.06, d=0.0025, rho_grain=1250.0, rho_fluid=1000.0,
                  mu=0.01, x0=0.01, y0=0.04, dx=0.0015, dx_boundary=0.00125, h0=0.003,
                  c0=None, kn=1.0e4, friction=0.3, beta_n=0.5,
                  voidage="area", r_clump=0.01, eps_xsph=0.5, delta=0.1, x64=False,
                  t_end=1.0) -> Scene:
    """One grain (disc d = 2.5 mm, ρ 1250) released at rest at (``x0``, ``y0``) = (0.01,
    0.04) m in a ``width`` × ``height`` = 0.02 × 0.06 m box of fluid (ρ 1000, μ 0.01 Pa·s);
    W6.2.1's numerical parameters: fluid spacing 1.5 mm, boundary 1.25 mm, Wendland h 3 mm.

    The channel of Glowinski et al. is closed; here its top is a free surface at y =
    ``height`` (the grain never comes near it). The grain meets the box through DEM line
    walls with a soft contact (``kn`` 1e4 N/m, β_n 0.5): only the landing depends on it.
    c0 = 10 √(2 g height). With ``rho_grain`` = ``rho_fluid`` the grain is neutrally
    buoyant; with a small ``d`` (ε → 1) it is the terminal-velocity case."""
    check_positive(width=width, height=height, d=d, rho_grain=rho_grain, rho_fluid=rho_fluid,
                   mu=mu, dx=dx, dx_boundary=dx_boundary, h0=h0, kn=kn, t_end=t_end)
    _check_choice("voidage", voidage, tuple(v.value for v in Voidage))
    if not (d / 2 < x0 < width - d / 2 and d / 2 < y0 < height - d / 2):
        raise ParameterError(f"grain start ({x0}, {y0}) out of range; allowed inside the box "
                             f"[{d / 2}, {width - d / 2}] × [{d / 2}, {height - d / 2}]")
    v_max = float(np.sqrt(2 * G * height))
    c0 = 10.0 * v_max if c0 is None else c0
    dx = _fit(width, dx)
    sp = sph_params(rho_fluid, c0, mu, dx, r_clump, eps_xsph, delta)
    surface = round(height / dx) * dx
    fluid = hydrostatic_fluid(lattice(0.0, 0.0, width, height, dx), rho_fluid, c0, sp.gamma,
                              surface, dx=dx, h=h0)
    grain = disc_block(np.array([[x0, y0]]), d / 2, rho_grain)
    grain.grain = np.array([True])
    grain.structure = np.array([False])
    fluid = _fluid_among_grains(fluid, grain.x, grain.radius, voidage)
    layers = boundary_layers(h0, dx_boundary)
    boundary = boundary_block(tank_walls(width, height, dx_boundary, layers), rho_fluid,
                              dx_boundary, h0)
    pad = layers * dx_boundary + 2 * h0
    return Scene(
        name="sedimentation",
        params=Params(sph=sp, dem=DemParams(kn=kn, ks=0.5 * kn, mu=friction, beta_n=beta_n,
                                            beta_s=beta_n), fpi=FpiParams()),
        domain_lo=(-pad, -pad), domain_hi=(width + pad, 1.5 * height), v_max=v_max,
        fluid=fluid, boundary=boundary, solid=grain,
        walls=box_walls(0.0, 0.0, width, height, top=True), t_end=t_end,
        options={"fpi": True, "voidage": voidage, "delta_sph": True,
                 "boundary_pressure": "extrapolated", "x64": x64},
        builder_kwargs=dict(width=width, height=height, d=d, rho_grain=rho_grain,
                            rho_fluid=rho_fluid, mu=mu, x0=x0, y0=y0, dx=dx,
                            dx_boundary=dx_boundary, h0=h0, c0=c0, kn=kn, friction=friction,
                            beta_n=beta_n, voidage=voidage,
                            r_clump=r_clump, eps_xsph=eps_xsph, delta=delta, x64=x64,
                            t_end=t_end))


# --- two-phase dam break ---------------------------------------------------------------------
def grain_bed(a, d, n, floor=0.0):
    """``n`` grain centres hexagonally packed from the floor in a bed ``a`` wide (rows of
    round-down(a/d) discs; W6.2.2 packs them against the left wall, the floor and the gate)."""
    rows = hex_packing(0.0, floor, a, 10.0 * n * d / max(1, int(a / d)) + d, d)
    if rows.shape[0] < n:
        raise ParameterError(f"grain bed: {n} grains do not fit")
    return rows[:n]


def _two_phase_parts(a, water_height, tank_length, tank_height, d, rho_grain, grain_mass,
                     depth, dx, dx_boundary, h0, mu, c0, kn, ks, friction, beta_n,
                     voidage, r_clump, eps_xsph, alpha_av, delta, eps_floor):
    check_positive(a=a, water_height=water_height, tank_length=tank_length,
                   tank_height=tank_height, d=d, rho_grain=rho_grain, grain_mass=grain_mass,
                   depth=depth, dx=dx, dx_boundary=dx_boundary, h0=h0, kn=kn)
    _check_choice("voidage", voidage, tuple(v.value for v in Voidage))
    if tank_length < 2 * a:
        raise ParameterError(f"tank_length = {tank_length} out of range; allowed [{2 * a}, inf)")
    n_grain = int(round(grain_mass / (rho_grain * depth * math.pi * d * d / 4)))
    xg = grain_bed(a, d, n_grain)
    if xg[:, 1].max() + d / 2 > water_height:
        raise ParameterError(f"grain_mass = {grain_mass}: the bed is higher than the water")
    grains = disc_block(xg, d / 2, rho_grain)
    grains.grain = np.ones(grains.n, bool)
    v_max = float(np.sqrt(2 * G * water_height))
    c0 = 10.0 * v_max if c0 is None else c0
    dx = _fit(a, dx)
    sp = sph_params(1000.0, c0, mu, dx, r_clump, eps_xsph, delta, alpha=alpha_av)
    surface = round(water_height / dx) * dx
    fluid = hydrostatic_fluid(lattice(0.0, 0.0, a, water_height, dx), 1000.0, c0, sp.gamma,
                              surface, dx=dx, h=h0)
    fluid = _fluid_among_grains(fluid, grains.x, grains.radius, voidage, eps_floor)
    layers = boundary_layers(h0, dx_boundary)
    boundary = boundary_block(tank_walls(tank_length, tank_height, dx_boundary, layers),
                              1000.0, dx_boundary, h0)
    dem = DemParams(kn=kn, ks=ks, mu=friction, beta_n=beta_n, beta_s=beta_n)
    return sp, fluid, grains, boundary, dem, v_max, c0, layers, n_grain


def two_phase_dam_break(*, a=0.05, water_height=0.1, tank_length=0.2, tank_height=0.15,
                        d=0.0024, rho_grain=2500.0, grain_mass=0.2, depth=0.1, dx=0.0024,
                        dx_boundary=0.0015, h0=0.003, gate_speed=0.68, gate_columns=4,
                        mu=1.0e-3, c0=None, kn=1.021e9, ks=1.024e7, friction=0.3,
                        beta_n=0.3, voidage="mapped", r_clump=0.01,
                        eps_xsph=0.5, alpha_av=0.02, delta=0.1, eps_floor=0.8,
                        t_end=0.2) -> Scene:
    """W6.2.2 after Sun, Sakai & Yamada (2013): a water column ``a`` = 0.05 m wide with a bed
    of grains (d 2.4 mm, ρ 2500) at its foot, behind a gate lifted at ``gate_speed`` =
    0.68 m/s from t = 0; W's numerical parameters (fluid 2.4 mm, fitted to the column:
    2.381 mm, 21 columns; boundary 1.5 mm, h 3 mm).

    The seed leaves out the tank, the water height and the packing. Choices (keywords):
    water 0.1 m high (the experiment's 2a) in a tank 0.2 m long (4a: the front reaches the
    end wall at z* = 4, the last point W plots); the bed holds the 200 g of the experiment
    for a ``depth`` of 0.1 m, i.e. round(0.2/(ρ depth π d²/4)) = 177 discs per unit
    thickness, hexagonally packed from the floor (W packs randomly and settles the bed
    first; a regular bed starts in equilibrium). W6.3 gives the grains' contact stiffness
    (1.021e9 / 1.024e7 N/m); friction 0.3 and β_n 0.3 are ours.

    The gate is ``gate_columns`` columns of fixed discs (d = dx_boundary) that move up at
    ``gate_speed``: kinematic structure discs, in the SPH sums for the water (the
    'extrapolated' coupling) and in contact with the grains. δ-SPH (on the intrinsic
    density) and α = 0.02 artificial viscosity as in the dam break.

    The packed bed: the fluid sees the 3D-mapped voidage (``voidage`` 'mapped', 0.26-0.3 in
    the bed), floored at ``eps_floor`` = 0.8 in the fluid equations (the drag sees the
    unfloored value). The light pore fluid near the left wall went unstable within 0.02 s
    without the floor, and by 0.035–0.11 s with a floor of 0.5 (unresolved; README). The
    floor makes the bed's pore fluid heavier than the pores hold, so the bed's pressure
    gradient is steeper than hydrostatic."""
    check_positive(gate_speed=gate_speed, gate_columns=gate_columns)
    sp, fluid, grains, boundary, dem, v_max, c0, layers, n_grain = _two_phase_parts(
        a, water_height, tank_length, tank_height, d, rho_grain, grain_mass, depth, dx,
        dx_boundary, h0, mu, c0, kn, ks, friction, beta_n, voidage, r_clump, eps_xsph,
        alpha_av, delta, eps_floor)
    dg = dx_boundary
    xgate = square_packing(a, 0.0, gate_columns * dg, water_height + 4 * dg, dg)
    gate = disc_block(xgate, dg / 2, 1000.0, mass_model="lattice", packing="square",
                      fixed=np.ones(xgate.shape[0], bool),
                      v=np.tile([0.0, gate_speed], (xgate.shape[0], 1)))
    gate.structure = np.ones(gate.n, bool)
    gate.sph_volume = np.full(gate.n, dg * dg)
    solid = _merge(grains, gate)
    pad = layers * dx_boundary + 2 * h0
    top = water_height + 4 * dg + gate_speed * t_end + 2 * h0
    return Scene(
        name="two_phase_dam_break",
        params=Params(sph=sp, dem=dem, fpi=FpiParams()),
        domain_lo=(-pad, -pad), domain_hi=(tank_length + pad, max(1.2 * tank_height, top)),
        v_max=v_max, fluid=fluid, boundary=boundary, solid=solid,
        walls=box_walls(0.0, 0.0, tank_length, tank_height), t_end=t_end,
        options={"fpi": True, "fsi": "extrapolated", "voidage": voidage,
                 "boundary_pressure": "extrapolated", "artificial_viscosity": True,
                 "delta_sph": True, "eps_floor": eps_floor},
        builder_kwargs=dict(a=a, water_height=water_height, tank_length=tank_length,
                            tank_height=tank_height, d=d, rho_grain=rho_grain,
                            grain_mass=grain_mass, depth=depth, dx=dx,
                            dx_boundary=dx_boundary, h0=h0, gate_speed=gate_speed,
                            gate_columns=gate_columns, mu=mu, c0=c0, kn=kn, ks=ks,
                            friction=friction, beta_n=beta_n,
                            voidage=voidage, r_clump=r_clump, eps_xsph=eps_xsph,
                            alpha_av=alpha_av, delta=delta, eps_floor=eps_floor, t_end=t_end,
                            n_grain=n_grain))


# --- three phases with a breaking structure ----------------------------------------------------
FPSI_CASES = {"I": 4.0e4, "II": 2.0e4}


def fpsi_failure(*, case="I", sigma_c=None, tau_c=None, thickness=0.01, d_structure=0.0025,
                 rho_structure=1100.0, a=0.05, water_height=0.1, tank_length=0.2,
                 tank_height=0.15, d=0.0024, rho_grain=2500.0, grain_mass=0.2, depth=0.1,
                 dx=0.0024, dx_boundary=0.0015, h0=0.003, mu=1.0e-3, c0=None, kn=1.021e9,
                 ks=1.024e7, friction=0.3, beta_n=0.3, voidage="mapped",
                 r_clump=0.01, eps_xsph=0.5, alpha_av=0.02, delta=0.1, eps_floor=0.8,
                        t_end=0.2) -> Scene:
    """W6.3: the two-phase dam break with the gate replaced by a bonded structure fixed at
    its foot (ρ 1100), bond tensile strength 4e4 Pa (``case`` 'I') or 2e4 Pa ('II'),
    contact stiffness k_n 1.021e9, k_s 1.024e7 N/m (grains and structure alike).

    The seed leaves out the structure's size, its bond stiffness and shear strength.
    Choices (keywords): a wall ``thickness`` 10 mm × ``water_height`` high, square-packed
    discs of 2.5 mm (4 columns, the bottom row fixed), bond stiffness per area = contact
    stiffness / bond area (k̄ = k/d for the 2R̄·1 m slab), shear strength τ̄_c = σ̄_c. Static
    bending at the foot under the water alone is 6M/e² with M = ρ_w g H³/6: 9.8e4 Pa for
    the defaults, above both strengths, so both walls crack from the foot once the load
    arrives; the weaker one earlier and further. The bed's fluid voidage is floored at
    ``eps_floor`` = 0.8 as in :func:`two_phase_dam_break`."""
    if case not in FPSI_CASES and sigma_c is None:
        raise ParameterError(f"case must be one of {tuple(FPSI_CASES)}, got {case!r}")
    sigma_c = FPSI_CASES[case] if sigma_c is None else sigma_c
    tau_c = sigma_c if tau_c is None else tau_c
    check_positive(sigma_c=sigma_c, tau_c=tau_c, thickness=thickness,
                   d_structure=d_structure, rho_structure=rho_structure, ks=ks)
    sp, fluid, grains, boundary, dem, v_max, c0, layers, n_grain = _two_phase_parts(
        a, water_height, tank_length, tank_height, d, rho_grain, grain_mass, depth, dx,
        dx_boundary, h0, mu, c0, kn, ks, friction, beta_n, voidage, r_clump, eps_xsph,
        alpha_av, delta, eps_floor)
    ds = d_structure
    xs = square_packing(a, 0.0, thickness, water_height, ds)
    wall = disc_block(xs, ds / 2, rho_structure, mass_model="lattice", packing="square",
                      fixed=xs[:, 1] < ds)
    wall.structure = np.ones(wall.n, bool)
    wall.sph_volume = np.full(wall.n, ds * ds)
    bonds = touching_pairs(xs, ds / 2)
    bonds.i, bonds.j = bonds.i + grains.n, bonds.j + grains.n
    solid = _merge(grains, wall)
    bp = BondParams(kn=kn / ds, ks=ks / ds, sigma_c=sigma_c, tau_c=tau_c)
    pad = layers * dx_boundary + 2 * h0
    return Scene(
        name="fpsi_failure",
        params=Params(sph=sp, dem=dem, bond=bp, fpi=FpiParams()),
        domain_lo=(-pad, -pad), domain_hi=(tank_length + pad, 1.5 * tank_height),
        v_max=v_max, fluid=fluid, boundary=boundary, solid=solid, bonds=bonds,
        walls=box_walls(0.0, 0.0, tank_length, tank_height), t_end=t_end,
        options={"fpi": True, "fsi": "extrapolated", "voidage": voidage,
                 "boundary_pressure": "extrapolated", "artificial_viscosity": True,
                 "delta_sph": True, "eps_floor": eps_floor},
        builder_kwargs=dict(case=case, sigma_c=sigma_c, tau_c=tau_c, thickness=thickness,
                            d_structure=d_structure, rho_structure=rho_structure, a=a,
                            water_height=water_height, tank_length=tank_length,
                            tank_height=tank_height, d=d, rho_grain=rho_grain,
                            grain_mass=grain_mass, depth=depth, dx=dx,
                            dx_boundary=dx_boundary, h0=h0, mu=mu, c0=c0, kn=kn, ks=ks,
                            friction=friction, beta_n=beta_n,
                            voidage=voidage, r_clump=r_clump, eps_xsph=eps_xsph,
                            alpha_av=alpha_av, delta=delta, eps_floor=eps_floor, t_end=t_end,
                            n_grain=n_grain))
