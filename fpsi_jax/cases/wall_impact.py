"""A grain fired at a wall: a stress test of the DEM contact at high speed."""
from __future__ import annotations

import math

import numpy as np

from ..build import check_positive, disc_block
from ..model.errors import require
from ..model.params import DemParams, Params
from ..model.scene import Scene, WallBlock
from .registry import scene


@scene
def wall_impact(*, radius=0.005, rho=2700.0, speed=10.0, kn=1.0e8, beta=0.1, angle=0.0,
                t_end=None) -> Scene:
    """A grain fired at a floor wall at ``speed`` (a stress test): no gravity, no friction,
    ``angle`` from the normal in degrees. The linear spring–dashpot answers: restitution
    e = exp(−πβ/√(1−β²)) for the normal velocity, largest overlap δ_max ≈ v √(m/k_n)
    (undamped), which must stay well under R (no tunnelling). The default k_n = 1e8 N/m per
    metre of thickness (a stiff grain, ~E·1.5e-3 of aluminium's) keeps δ_max ≈ 0.46 mm <
    10 % of R at 10 m/s; k_n = 1e6 would overlap 90 % of R."""
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
        open_sides=("right", "top"),    # a disc that bounces off the end of the floor leaves
        builder_kwargs=dict(t_end=t_end))
