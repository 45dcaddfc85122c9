"""A disc sliding along a floor until friction makes it roll: the scene and its validation
against the rigid-body answer v = 2/3 v0."""
from __future__ import annotations

import time

import numpy as np

from ..build import check_positive, disc_block
from ..model.params import DemParams, Params
from ..model.scene import Scene, WallBlock
from ..run.driver import simulate
from . import overrides as ov
from .registry import Record, scene, validation


@scene
def rolling(*, radius=0.01, rho=2700.0, speed=1.0, mu=0.3, kn=1.0e5, ks=5.0e4, beta_n=0.3,
            beta_s=0.3, t_end=0.3) -> Scene:
    """A disc launched along a floor at ``speed`` without spin; Coulomb friction makes it roll.
    Rigid-body answer: rolling starts at t = v0/(3μg) with v = (2/3) v0 (J = ½mR²). The
    floor is as long as the disc rolls in ``t_end``; its far end is an open side."""
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
        open_sides=("right",))          # the lane ends: a disc rolling past it leaves


@validation("rolling", "disc sliding without spin (μ = 0.3) ends rolling at 2/3 v0 (1 %)")
def rolling_case(quick: bool = False, overrides: dict | None = None):
    scene, phys = ov.build("rolling", overrides or {})
    t0 = time.perf_counter()
    res = simulate(scene, progress=False, **phys,
                   observe=lambda s: (s.solid.v[0, 0], s.solid.omega[0]))
    wall = time.perf_counter() - t0
    v, w = (np.asarray(a) for a in res.observations)
    v0 = scene.builder_kwargs["speed"]
    tail = v[int(0.8 * len(v)):]
    ratio = float(tail.mean()) / v0
    ref = 2.0 / 3.0
    err = abs(ratio - ref) / ref
    info = {**scene.builder_kwargs, "steps": res.n_steps, "dt": float(res.params.dt),
            "omega_R_over_v0": float(-w[-1] * scene.solid.radius[0] / v0)}
    return [Record("rolling", "final speed / v0 (mean of last 20 %)", ratio, ref, err, 0.01,
                   err < 0.01, wall, info)]
