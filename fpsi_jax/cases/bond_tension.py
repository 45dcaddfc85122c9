"""A bonded bar pulled apart: the scene and its validation of the tensile bond strength."""
from __future__ import annotations

import time

import numpy as np

from ..build import check_positive, disc_block
from ..model.errors import ParameterError
from ..model.params import BondParams, DemParams, Params
from ..model.scene import BondBlock, Scene
from ..run.driver import simulate
from . import overrides as ov
from .registry import Record, scene, validation


@scene
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
    # whose far end is open
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
        t_end=t_end, options={"x64": True}, builder_kwargs=dict(t_end=t_end),
        open_sides=("right",))       # the freed end leaves through the far end of the box


@validation("bond_tension", "bonded bar pulled apart: breaks at F/A = σ̄_c (1 %)")
def bond_tension_case(quick: bool = False, overrides: dict | None = None):
    scene, phys = ov.build("bond_tension", overrides or {})
    t0 = time.perf_counter()
    res = simulate(scene, progress=False, **phys)
    wall = time.perf_counter() - t0
    b = res.state.bonds
    tb = np.asarray(b.t_break)
    kw = scene.builder_kwargs
    broke = tb >= 0
    area = kw["d"] * float(res.params.bond.lam) * float(res.params.bond.thickness)
    if not broke.any():
        return [Record("bond_tension", "stress at break [Pa]", float("nan"), kw["sigma_c"],
                       float("inf"), 0.01, False, wall, {**kw, "note": "no bond broke"})]
    t_first = float(tb[broke].min())
    force = float(scene.solid.f_ext[-1, 0]) * min(1.0, t_first / kw["ramp_time"])
    sigma = force / area
    err = abs(sigma - kw["sigma_c"]) / kw["sigma_c"]
    mode = int(np.asarray(b.mode)[broke][np.argmin(tb[broke])])
    info = {**kw, "steps": res.n_steps, "dt": float(res.params.dt), "t_break": t_first,
            "bond": int(np.flatnonzero(broke)[np.argmin(tb[broke])]),
            "mode": {1: "tension", 2: "shear"}[mode], "n_broken": int(broke.sum())}
    return [Record("bond_tension", "applied stress F/A at the first break [Pa]", sigma,
                   float(kw["sigma_c"]), err, 0.01, err < 0.01 and mode == 1, wall, info)]
