"""DEM-only validation scenes: two-disc collision, rolling disc, dry dam break."""
from __future__ import annotations

import math

import numpy as np

from ..build import box_walls, check_positive, disc_block, hex_packing
from ..model.errors import ParameterError, require
from ..model.params import DemParams, Params
from ..model.scene import Scene, WallBlock


def collision(*, radius=0.005, rho=2700.0, speed=0.5, kn=1.0e5, beta=0.1, gap=None,
              t_end=None) -> Scene:
    """Two equal discs moving head-on at ±``speed`` (no gravity, no friction needed).

    Analytic (linear spring–dashpot, contact ending at zero overlap): restitution
    e = exp(−πβ/√(1−β²)), contact time π/√(k/m* (1−β²)), m* = m/2 (dem.py)."""
    check_positive(radius=radius, rho=rho, speed=speed, kn=kn)
    require("beta", beta, 0.0, 1.0, hi_open=True)
    gap = 0.2 * radius if gap is None else gap
    blk = disc_block(np.array([[0.05 - radius - gap / 2, 0.05], [0.05 + radius + gap / 2, 0.05]]),
                     radius, rho, v=np.array([[speed, 0.0], [-speed, 0.0]]))
    m_red = 0.5 * blk.mass[0]
    tc = math.pi / math.sqrt(kn / m_red * (1 - beta ** 2))
    t_end = gap / (2 * speed) + 3 * tc if t_end is None else t_end
    return Scene(
        name="collision", params=Params(gravity=(0.0, 0.0),
                                        dem=DemParams(kn=kn, ks=0.0, mu=0.0, beta_n=beta)),
        domain_lo=(0.0, 0.0), domain_hi=(0.1, 0.1), v_max=speed, solid=blk, t_end=t_end,
        options={"x64": True},
        builder_kwargs=dict(radius=radius, rho=rho, speed=speed, kn=kn, beta=beta, gap=gap,
                            t_end=t_end))


def rolling(*, radius=0.01, rho=2700.0, speed=1.0, mu=0.3, kn=1.0e5, ks=5.0e4, beta_n=0.3,
            beta_s=0.3, t_end=0.3) -> Scene:
    """A disc launched along a floor at ``speed`` without spin; Coulomb friction makes it roll.
    Rigid-body answer: rolling starts at t = v0/(3μg) with v = (2/3) v0 (J = ½mR²)."""
    check_positive(radius=radius, rho=rho, speed=speed, mu=mu, kn=kn, ks=ks, t_end=t_end)
    blk = disc_block(np.array([[0.05, radius]]), radius, rho, v=np.array([[speed, 0.0]]))
    overlap = blk.mass[0] * 9.81 / kn                 # start at rest in the normal direction
    blk.x[0, 1] = radius - overlap
    length = 0.1 + speed * t_end
    walls = WallBlock(a=np.array([[0.0, 0.0]]), b=np.array([[length, 0.0]]))
    return Scene(
        name="rolling", params=Params(dem=DemParams(kn=kn, ks=ks, mu=mu, beta_n=beta_n,
                                                    beta_s=beta_s)),
        domain_lo=(-0.01, -0.01), domain_hi=(length + 0.01, 0.1), v_max=speed, solid=blk,
        walls=walls, t_end=t_end, options={"x64": True},
        builder_kwargs=dict(radius=radius, rho=rho, speed=speed, mu=mu, kn=kn, ks=ks,
                            beta_n=beta_n, beta_s=beta_s, t_end=t_end))


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
        builder_kwargs=dict(diameter=diameter, rho=rho, E=E, nu=nu, mu=mu, rows=rows,
                            per_row=per_row, tank_width=tank_width, tank_height=tank_height,
                            beta_n=beta_n, beta_s=beta_s, kn=kn, t_end=t_end))


def wall_impact(*, radius=0.005, rho=2700.0, speed=10.0, kn=1.0e8, beta=0.1, angle=0.0,
                t_end=None) -> Scene:
    """A grain fired at a floor wall at ``speed`` (stress test, issue 7): no gravity, no
    friction, ``angle`` from the normal in degrees. The linear spring–dashpot answers:
    restitution e = exp(−πβ/√(1−β²)) for the normal velocity, largest overlap
    δ_max ≈ v √(m/k_n) (undamped), which must stay well under R (no tunnelling). The default
    k_n = 1e8 N/m per metre of thickness (a stiff grain, ~E·1.5e-3 of aluminium's) keeps
    δ_max ≈ 0.46 mm < 10 % of R at 10 m/s; k_n = 1e6 would overlap 90 % of R."""
    check_positive(radius=radius, rho=rho, speed=speed, kn=kn)
    require("beta", beta, 0.0, 1.0, hi_open=True)
    require("angle", angle, 0.0, 89.0)
    gap = 2.0 * radius
    a = math.radians(angle)
    v = speed * np.array([[math.sin(a), -math.cos(a)]])
    blk = disc_block(np.array([[0.05, radius + gap]]), radius, rho, v=v)
    tc = math.pi / math.sqrt(kn / blk.mass[0] * (1 - beta ** 2))
    t_end = gap / (speed * math.cos(a)) + 3 * tc if t_end is None else t_end   # normal approach
    walls = WallBlock(a=np.array([[0.0, 0.0]]), b=np.array([[0.1 + speed * t_end, 0.0]]))
    return Scene(
        name="wall_impact", params=Params(gravity=(0.0, 0.0),
                                          dem=DemParams(kn=kn, ks=0.0, mu=0.0, beta_n=beta)),
        domain_lo=(-0.01, -0.01), domain_hi=(0.11 + speed * t_end, 0.05 + speed * t_end),
        v_max=speed, solid=blk, walls=walls, t_end=t_end, options={"x64": True},
        builder_kwargs=dict(radius=radius, rho=rho, speed=speed, kn=kn, beta=beta,
                            angle=angle, t_end=t_end))
