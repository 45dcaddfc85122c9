"""Two discs colliding head-on: the scene and its validation against the linear
spring–dashpot's restitution and contact time."""
from __future__ import annotations

import math
import time

import numpy as np

from ..build import check_positive, disc_block
from ..model.errors import require
from ..model.params import DemParams, Params
from ..model.scene import Scene
from ..run.driver import simulate
from ..solver import timestep
from . import overrides as ov
from .measure import crossings
from .registry import Record, scene, validation


@scene
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
    # the step resolves the contact with STEPS_PER_CONTACT steps, as the validation does:
    # the derived step (the stability bound 0.55 √(m/k)) gives it ≈ 4, and e 10 % low
    return Scene(dt=tc / STEPS_PER_CONTACT,
        name="collision", params=Params(gravity=(0.0, 0.0),
                                        dem=DemParams(kn=kn, ks=0.0, mu=0.0, beta_n=beta)),
        domain_lo=(0.0, 0.0), domain_hi=(0.1, 0.1), v_max=speed, solid=blk, t_end=t_end,
        options={"x64": True}, builder_kwargs=dict(gap=gap, t_end=t_end))


#: steps over the analytic contact time (an accuracy setting, not a stability one)
STEPS_PER_CONTACT = 300


def collision_run(beta, overrides=None, steps_per_contact=STEPS_PER_CONTACT):
    """Run the two-disc collision at ``steps_per_contact`` steps over the analytic contact
    time (an accuracy setting, independent of the stability bound: the derived step resolves
    a contact with only ≈ 4 steps); returns (e, contact time, e_ref, tc_ref, scene, result)."""
    scene, phys = ov.build("collision", overrides or {}, {"beta": beta})
    beta, kn = float(scene.params.dem.beta_n), float(scene.params.dem.kn)
    m = 0.5 * float(scene.solid.mass[0])                  # reduced mass of the pair
    e_ref = math.exp(-math.pi * beta / math.sqrt(1 - beta ** 2))
    tc_ref = math.pi / math.sqrt(kn / m * (1 - beta ** 2))
    dt = min(tc_ref / steps_per_contact, timestep.stable_dt(scene))
    res = simulate(scene, progress=False, dt=dt, **phys,
                   observe=lambda s: (s.solid.x[1, 0] - s.solid.x[0, 0],
                                      s.solid.v[1, 0] - s.solid.v[0, 0]))
    gap, vrel = (np.asarray(a) for a in res.observations)
    kw = scene.builder_kwargs
    R = float(scene.solid.radius[0])
    t = dt * np.arange(1, len(gap) + 1)
    overlap = np.concatenate([[2 * R - (scene.solid.x[1, 0] - scene.solid.x[0, 0])],
                              2 * R - gap])
    t = np.concatenate([[0.0], t])
    t_in = crossings(t, -overlap, rising=False)[0]      # overlap becomes > 0
    t_out = crossings(t, overlap, rising=False)[0]      # overlap returns to 0
    e = abs(float(vrel[-1])) / (2 * kw["speed"])
    return e, t_out - t_in, e_ref, tc_ref, scene, res


@validation("collision", "two discs head-on, β = 0, 0.1, 0.3: restitution (1 %), duration (2 %)")
def collision_case(quick: bool = False, overrides: dict | None = None):
    out = []
    for beta in (0.0, 0.1, 0.3):
        t0 = time.perf_counter()
        e, tc, e_ref, tc_ref, scene, res = collision_run(beta, overrides)
        wall = time.perf_counter() - t0
        info = {**scene.builder_kwargs, "dt": float(res.params.dt), "steps": res.n_steps}
        re, rt = abs(e - e_ref) / e_ref, abs(tc - tc_ref) / tc_ref
        out += [Record("collision", f"restitution, beta = {beta}", e, e_ref, re, 0.01,
                       re < 0.01, wall, info),
                Record("collision", f"contact time [s], beta = {beta}", tc, tc_ref, rt, 0.02,
                       rt < 0.02, wall, info)]
    return out
