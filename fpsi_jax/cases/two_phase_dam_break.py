"""The two-phase dam break of Sun, Sakai & Yamada (2013) (W6.2.2): a water
column with a bed of grains at its foot released by a lifting gate. Its water, bed and
tank (:func:`two_phase_parts`) are also those of ``fpsi_failure``."""
from __future__ import annotations

import math

import numpy as np

from dataclasses import dataclass

from ..build import (Tank, check_positive, dam_speed, disc_block, hex_packing, hydrostatic_fluid,
                     lattice, merge, move, sound_speed, sph_params, square_packing, tank)
from ..model.errors import ParameterError
from ..model.options import FpiPressure, choose
from ..model.params import DemParams, FpiParams, Params, SphParams
from ..model.scene import FluidBlock, Scene, SolidBlock
from .grains import check_voidage, fit_spacing, fluid_among_grains
from .registry import scene


def grain_bed(a, d, n, floor=0.0):
    """``n`` grain centres hexagonally packed from the floor in a bed ``a`` wide (rows of
    round-down(a/d) discs; W6.2.2 packs them against the left wall, the floor and the gate)."""
    rows = hex_packing(0.0, floor, a, 10.0 * n * d / max(1, int(a / d)) + d, d)
    if rows.shape[0] < n:
        raise ParameterError(f"grain bed: {n} grains do not fit")
    return rows[:n]


@dataclass
class TwoPhaseParts:
    """The water column, its grain bed, the tank (with DEM walls) and the contact law of the
    two-phase dam break."""

    sph: SphParams
    fluid: FluidBlock
    grains: SolidBlock
    tank: Tank
    dem: DemParams
    v_max: float
    c0: float
    n_grain: int


def two_phase_parts(a, water_height, tank_length, tank_height, d, rho_grain, grain_mass,
                    depth, dx, dx_boundary, h0, mu, c0, kn, ks, friction, beta_n,
                    voidage, r_clump, eps_xsph, alpha_av, delta, eps_floor,
                    wall_images=True) -> TwoPhaseParts:
    """The parts the two-phase dam break and ``fpsi_failure`` share (:class:`TwoPhaseParts`)."""
    check_positive(a=a, water_height=water_height, tank_length=tank_length,
                   tank_height=tank_height, d=d, rho_grain=rho_grain, grain_mass=grain_mass,
                   depth=depth, dx=dx, dx_boundary=dx_boundary, h0=h0, kn=kn)
    check_voidage(voidage)
    if tank_length < 2 * a:
        raise ParameterError(f"tank_length = {tank_length} out of range; allowed [{2 * a}, inf)")
    n_grain = int(round(grain_mass / (rho_grain * depth * math.pi * d * d / 4)))
    xg = grain_bed(a, d, n_grain)
    if xg[:, 1].max() + d / 2 > water_height:
        raise ParameterError(f"grain_mass = {grain_mass}: the bed is higher than the water")
    grains = disc_block(xg, d / 2, rho_grain)
    grains.grain = np.ones(grains.n, bool)
    v_max = dam_speed(water_height)
    c0 = sound_speed(v_max) if c0 is None else c0
    dx = fit_spacing(a, dx)
    sp = sph_params(1000.0, c0, mu, dx, r_clump, eps_xsph, delta, alpha=alpha_av)
    surface = round(water_height / dx) * dx
    fluid = hydrostatic_fluid(lattice(0.0, 0.0, a, water_height, dx), 1000.0, c0, sp.gamma,
                              surface, dx=dx, h=h0)
    box = tank(tank_length, tank_height, dx_boundary, h0, 1000.0, dem_walls=True)
    fluid = fluid_among_grains(fluid, grains.x, grains.radius, voidage, eps_floor,
                               box.walls if wall_images else None)
    dem = DemParams(kn=kn, ks=ks, mu=friction, beta_n=beta_n, beta_s=beta_n)
    return TwoPhaseParts(sph=sp, fluid=fluid, grains=grains, tank=box, dem=dem, v_max=v_max,
                         c0=c0, n_grain=n_grain)


@scene
def two_phase_dam_break(*, a=0.05, water_height=0.1, tank_length=0.2, tank_height=0.15,
                        d=0.0024, rho_grain=2500.0, grain_mass=0.2, depth=0.1, dx=0.0024,
                        dx_boundary=0.0015, h0=0.003, gate_speed=0.68, gate_columns=4,
                        mu=1.0e-3, c0=None, kn=1.021e9, ks=1.024e7, friction=0.3,
                        beta_n=0.3, voidage="area", fpi_pressure="shared", r_clump=0.01,
                        eps_xsph=0.5, alpha_av=0.02, delta=0.1, eps_floor=0.0,
                        wall_images=True, t_end=0.2) -> Scene:
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

    The packed bed: the fluid sees the bed's own area voidage (``voidage`` 'area', about 0.1
    in the bed; ``eps_floor`` 0: no floor) and the grains their part of the cells' pressure
    forces with the mixture's continuity (``fpi_pressure`` 'shared', fpi.py), which keeps
    the light pore fluid stable (docs/physics.md, Packed beds)."""
    check_positive(gate_speed=gate_speed, gate_columns=gate_columns)
    choose(FpiPressure, "fpi_pressure", fpi_pressure)
    parts = two_phase_parts(
        a, water_height, tank_length, tank_height, d, rho_grain, grain_mass, depth, dx,
        dx_boundary, h0, mu, c0, kn, ks, friction, beta_n, voidage, r_clump, eps_xsph,
        alpha_av, delta, eps_floor, wall_images)
    dg = dx_boundary
    xgate = square_packing(a, 0.0, gate_columns * dg, water_height + 4 * dg, dg)
    gate = disc_block(xgate, dg / 2, 1000.0, mass_model="lattice", packing="square")
    move(gate, lambda x: np.ones(len(x), bool), (0.0, gate_speed))   # lifted at gate_speed
    gate.structure = np.ones(gate.n, bool)
    gate.sph_volume = np.full(gate.n, dg * dg)
    solid, _ = merge(parts.grains, gate)
    pad = parts.tank.pad
    top = water_height + 4 * dg + gate_speed * t_end + 2 * h0
    return Scene(
        name="two_phase_dam_break",
        params=Params(sph=parts.sph, dem=parts.dem, fpi=FpiParams()),
        domain_lo=(-pad, -pad), domain_hi=(tank_length + pad, max(1.2 * tank_height, top)),
        v_max=parts.v_max, fluid=parts.fluid, boundary=parts.tank.boundary, solid=solid,
        walls=parts.tank.walls, t_end=t_end, open_sides=("top",),
        options={"fpi": True, "fsi": "extrapolated", "voidage": voidage,
                 "boundary_pressure": "extrapolated", "artificial_viscosity": True,
                 "delta_sph": True, "eps_floor": eps_floor, "fpi_pressure": fpi_pressure,
                 "wall_images": bool(wall_images)},
        builder_kwargs=dict(c0=parts.c0, n_grain=parts.n_grain))
