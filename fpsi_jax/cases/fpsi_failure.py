"""Three phases with a breaking structure (W6.3): the two-phase dam break
with its gate replaced by a bonded wall fixed at its foot."""
from __future__ import annotations

import numpy as np

from ..build import check_positive, clamp, disc_block, merge, square_packing, touching_pairs
from ..model.errors import ParameterError
from ..model.options import FpiPressure, choose
from ..model.params import BondParams, FpiParams, Params
from ..model.scene import Scene
from .registry import scene
from .two_phase_dam_break import two_phase_parts

FPSI_CASES = {"I": 4.0e4, "II": 2.0e4}      # bond tensile strength σ̄_c [Pa] of W6.3's cases


@scene
def fpsi_failure(*, case="I", sigma_c=None, tau_c=None, thickness=0.01, d_structure=0.0025,
                 rho_structure=1100.0, a=0.05, water_height=0.1, tank_length=0.2,
                 tank_height=0.15, d=0.0024, rho_grain=2500.0, grain_mass=0.2, depth=0.1,
                 dx=0.0024, dx_boundary=0.0015, h0=0.003, mu=1.0e-3, c0=None, kn=1.021e9,
                 ks=1.024e7, friction=0.3, beta_n=0.3, voidage="area", fpi_pressure="shared",
                 r_clump=0.01, eps_xsph=0.5, alpha_av=0.02, delta=0.1, eps_floor=0.0,
                 wall_images=True, t_end=0.2) -> Scene:
    """W6.3: the two-phase dam break with the gate replaced by a bonded structure fixed at
    its foot (ρ 1100), bond tensile strength 4e4 Pa (``case`` 'I') or 2e4 Pa ('II'),
    contact stiffness k_n 1.021e9, k_s 1.024e7 N/m (grains and structure alike).

    The seed leaves out the structure's size, its bond stiffness and shear strength.
    Choices (keywords): a wall ``thickness`` 10 mm × ``water_height`` high, square-packed
    discs of 2.5 mm (4 columns, the bottom row fixed), bond stiffness per area = contact
    stiffness / bond area (k̄ = k/d for the 2R̄·1 m slab), shear strength τ̄_c = σ̄_c. Static
    bending at the foot under the water alone is 6M/e² with M = ρ_w g H³/6: 9.8e4 Pa for
    the defaults, above both strengths, so both walls crack from the foot once the load
    arrives; the weaker one earlier and further. The bed is the two-phase dam break's, at its
    own voidage with the shared pressure (``two_phase_dam_break``)."""
    if case not in FPSI_CASES and sigma_c is None:
        raise ParameterError(f"case must be one of {tuple(FPSI_CASES)}, got {case!r}")
    sigma_c = FPSI_CASES[case] if sigma_c is None else sigma_c
    tau_c = sigma_c if tau_c is None else tau_c
    check_positive(sigma_c=sigma_c, tau_c=tau_c, thickness=thickness,
                   d_structure=d_structure, rho_structure=rho_structure, ks=ks)
    choose(FpiPressure, "fpi_pressure", fpi_pressure)
    parts = two_phase_parts(
        a, water_height, tank_length, tank_height, d, rho_grain, grain_mass, depth, dx,
        dx_boundary, h0, mu, c0, kn, ks, friction, beta_n, voidage, r_clump, eps_xsph,
        alpha_av, delta, eps_floor, wall_images)
    ds = d_structure
    xs = square_packing(a, 0.0, thickness, water_height, ds)
    wall = disc_block(xs, ds / 2, rho_structure, mass_model="lattice", packing="square")
    clamp(wall, (-np.inf, -np.inf, np.inf, ds))          # its bottom row is fixed
    wall.structure = np.ones(wall.n, bool)
    wall.sph_volume = np.full(wall.n, ds * ds)
    bonds = touching_pairs(xs, ds / 2)
    bonds.i, bonds.j = bonds.i + parts.grains.n, bonds.j + parts.grains.n
    solid, _ = merge(parts.grains, wall)
    bp = BondParams(kn=kn / ds, ks=ks / ds, sigma_c=sigma_c, tau_c=tau_c)
    lo, hi = parts.tank.domain(headroom=0.5)
    return Scene(
        name="fpsi_failure",
        params=Params(sph=parts.sph, dem=parts.dem, bond=bp, fpi=FpiParams()),
        domain_lo=lo, domain_hi=hi, v_max=parts.v_max, fluid=parts.fluid,
        boundary=parts.tank.boundary, solid=solid, bonds=bonds, walls=parts.tank.walls,
        t_end=t_end, open_sides=("top",),
        options={"fpi": True, "fsi": "extrapolated", "voidage": voidage,
                 "boundary_pressure": "extrapolated", "artificial_viscosity": True,
                 "delta_sph": True, "eps_floor": eps_floor, "fpi_pressure": fpi_pressure,
                 "wall_images": bool(wall_images)},
        builder_kwargs=dict(sigma_c=sigma_c, tau_c=tau_c, c0=parts.c0, n_grain=parts.n_grain))
