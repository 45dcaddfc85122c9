"""Dry dam break: the collapse of a stack of aluminium cylinders (Zhang et al. 2009)."""
from __future__ import annotations

import math

from ..build import box_walls, check_positive, disc_block, hex_packing
from ..model.errors import ParameterError
from ..model.params import DemParams, Params
from ..model.scene import Scene
from .registry import scene


@scene
def dry_dam_break(*, diameter=0.01, rho=2700.0, E=69.0e9, nu=0.3, mu=0.45, rows=6,
                  per_row=6, tank_width=0.26, tank_height=0.26, beta_n=0.3, beta_s=0.3,
                  kn=None, t_end=0.5) -> Scene:
    """Collapse of a stack of aluminium cylinders (Zhang et al. 2009; W3.1.5).

    33 cylinders d = 1 cm, ρ = 2700, E = 69 GPa, ν = 0.3, μ = 0.45 (also with the walls):
    ``rows`` hexagonal layers alternating ``per_row`` and ``per_row`` − 1 cylinders against
    the left wall of a 26 cm tank; the gate on their right is lifted at t = 0 (it is not
    modelled: the stack is released at once). Contact stiffness per unit length from K43:
    k_n = E (λ = 1), k_s = G = E/(2(1+ν)) unless ``kn`` is given. The damping ratios
    β_n = β_s = 0.3 (restitution ≈ 0.37) are our choice: W does not give them."""
    check_positive(diameter=diameter, rho=rho, E=E, tank_width=tank_width,
                   tank_height=tank_height, t_end=t_end)
    if rows < 1 or per_row < 2:
        raise ParameterError(f"rows = {rows}, per_row = {per_row}: allowed rows >= 1, per_row >= 2")
    s = math.sqrt(3) / 2 * diameter
    x = hex_packing(0.0, 0.0, per_row * diameter, diameter + (rows - 1) * s + 1e-9, diameter)
    blk = disc_block(x, diameter / 2, rho)
    kn = E if kn is None else kn
    ks = kn / (2 * (1 + nu))
    pad = 0.02
    return Scene(
        name="dry_dam_break",
        params=Params(dem=DemParams(kn=kn, ks=ks, mu=mu, beta_n=beta_n, beta_s=beta_s)),
        domain_lo=(-pad, -pad), domain_hi=(tank_width + pad, tank_height + pad),
        v_max=math.sqrt(2 * 9.81 * rows * s), solid=blk,
        walls=box_walls(0.0, 0.0, tank_width, tank_height), t_end=t_end,
        builder_kwargs=dict(kn=kn))
