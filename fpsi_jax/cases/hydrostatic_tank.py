"""Water at rest in a tank: the hydrostatic pressure check (issue 2)."""
from __future__ import annotations

import numpy as np

from ..model.params import Params
from ..model.scene import Scene
from ..build import (G, boundary_block, boundary_layers, check_positive, hydrostatic_fluid,
                     lattice, sph_params, tank_walls)


def hydrostatic_tank(*, depth=0.3, width=0.3, dx=0.005, dx_boundary=None, h_factor=1.5,
                     rho0=1000.0, mu=1.0e-3, c0=None, r_clump=0.01, eps_xsph=0.5,
                     delta=0.1, alpha=0.1, t_end=2.0, boundary_pressure="extrapolated",
                     delta_sph=True, artificial_viscosity=True) -> Scene:
    """Still water ``depth`` deep in a tank ``width`` wide, started hydrostatic.

    Reference: P = ρ0 g (H − y) and v = 0. c0 = 10 √(2 g H) (K35) unless given.

    δ-SPH (δ = 0.1) and artificial viscosity α = 0.1 are on by default: a lattice start
    rearranges (max |v| ≈ 0.2 m/s) and the physical μ alone does not damp that within 2 s.

    h = 1.5 Δx by default (the seed's dam break uses 1.25 Δx; DualSPHysics' default
    h = coefh·√2·Δx with coefh 1.0–1.2 gives 1.4–1.7 Δx). With 1.25 Δx the square lattice
    next to the floor goes unstable at t ≈ 0.25 s, bottom particles rearrange and a plume
    rises: at 5 mm max |v| reaches 4.5 % of √(gH) (t = 0.56 s) and is 1.2 % at 2 s. With
    1.5 Δx (≈ 28 instead of 20 neighbours) it stays at rest: 0.73 % throughout and 0.33 %
    at 2 s (experiments/hydrostatic_tank_h.py; not a fit to the reference).
    """
    check_positive(depth=depth, width=width, dx=dx, h_factor=h_factor, rho0=rho0)
    dxb = dx if dx_boundary is None else dx_boundary
    check_positive(dx_boundary=dxb)
    v_max = float(np.sqrt(2 * G * depth))
    c0 = 10.0 * v_max if c0 is None else c0
    h = h_factor * dx
    sp = sph_params(rho0, c0, mu, dx, r_clump, eps_xsph, delta, alpha=alpha)
    fluid = hydrostatic_fluid(lattice(0.0, 0.0, width, depth, dx), rho0, c0, sp.gamma,
                              depth, dx=dx, h=h)
    layers = boundary_layers(h, dxb)
    height = depth * 1.5
    xb = tank_walls(width, height, dxb, layers)
    boundary = boundary_block(xb, rho0, dxb, h_factor * dxb if dx_boundary else h)
    pad = layers * dxb + 2 * h
    return Scene(
        name="hydrostatic_tank", params=Params(sph=sp),
        domain_lo=(-pad, -pad), domain_hi=(width + pad, height + pad), v_max=v_max,
        fluid=fluid, boundary=boundary, t_end=t_end,
        options={"boundary_pressure": boundary_pressure, "delta_sph": delta_sph,
                 "artificial_viscosity": artificial_viscosity},
        builder_kwargs=dict(depth=depth, width=width, dx=dx, dx_boundary=dxb,
                            h_factor=h_factor, rho0=rho0, mu=mu, c0=c0, r_clump=r_clump,
                            eps_xsph=eps_xsph, delta=delta, alpha=alpha, t_end=t_end,
                            boundary_pressure=boundary_pressure, delta_sph=delta_sph,
                            artificial_viscosity=artificial_viscosity))
