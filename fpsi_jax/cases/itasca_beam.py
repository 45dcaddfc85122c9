"""Itasca's parallel-bond beam (K6.1): the scene and its validation against the
Euler–Bernoulli tip deflection."""
from __future__ import annotations

import math

import numpy as np

from ..build import check_positive, disc_block
from ..model.errors import ParameterError, require
from ..model.params import BondParams, DemParams, Params
from ..model.scene import BondBlock, Scene
from . import overrides as ov
from .measure import displacement_run
from .registry import Record, scene, validation

INCH = 0.0254                 # m
KIP = 4448.2216152605         # N


@scene
def itasca_beam(*, n_balls=11, radius=10 * INCH, bond_radius=8 * INCH,
                kn_bar=500 * KIP / INCH ** 3, ks_bar=188 * KIP / INCH ** 3, load=1 * KIP,
                rho=7850.0, alpha=0.7, t_end=3.0) -> Scene:
    """K6.1 / Itasca's parallel-bond beam: ``n_balls`` balls of radius R in a row joined by
    circular bonds of radius R̄ = 8 in (λ = 0.8), k̄_n = 500 kip/in³, k̄_s = 188 kip/in³,
    μ = 0, ball 0 clamped, ``load`` downwards on the last ball, no gravity, local damping 0.7
    to reach the static state. Spherical balls (K: "particles considered spherical").
    SI units (1 in = 0.0254 m, 1 kip = 4448.22 N).

    Euler–Bernoulli: δ = PL³/(3EI), E = k̄_n·2R, I = πR̄⁴/4, L = 2R(n − 1): 0.082893 in."""
    check_positive(radius=radius, bond_radius=bond_radius, kn_bar=kn_bar, ks_bar=ks_bar,
                   load=load, rho=rho, t_end=t_end)
    if n_balls < 2:
        raise ParameterError(f"n_balls = {n_balls} out of range; allowed [2, inf)")
    lam = bond_radius / radius
    require("bond_radius / radius", lam, 0.0, 1.0, lo_open=True)
    x = np.stack([2 * radius * np.arange(n_balls), np.zeros(n_balls)], axis=1)
    fixed = np.zeros(n_balls, bool)
    fixed[0] = True
    f_ext = np.zeros((n_balls, 2))
    f_ext[-1, 1] = -load
    blk = disc_block(x, radius, rho, mass_model="sphere", fixed=fixed, f_ext=f_ext)
    bonds = BondBlock(i=np.arange(n_balls - 1, dtype=np.int32),
                      j=np.arange(1, n_balls, dtype=np.int32))
    area = math.pi * bond_radius ** 2
    L = 2 * radius * (n_balls - 1)
    return Scene(
        name="itasca_beam",
        params=Params(gravity=(0.0, 0.0),
                      dem=DemParams(kn=kn_bar * area, ks=0.0, mu=0.0, alpha=alpha),
                      bond=BondParams(kn=kn_bar, ks=ks_bar, lam=lam)),
        domain_lo=(-2 * radius, -L / 2), domain_hi=(L + 2 * radius, L / 2), v_max=1.0,
        solid=blk, bonds=bonds, t_end=t_end,
        options={"bond_section": "circular", "x64": True})


@validation("itasca_beam", "K6.1 / Itasca 11-ball parallel-bond beam, tip deflection (0.2 %)")
def itasca_beam_case(quick: bool = False, overrides: dict | None = None):
    scene, phys = ov.build("itasca_beam", overrides or {})
    y, res, wall = displacement_run(scene, phys, np.abs(scene.solid.f_ext[:, 1]) > 0)
    kw = scene.builder_kwargs
    E = kw["kn_bar"] * 2 * kw["radius"]
    I = math.pi * kw["bond_radius"] ** 4 / 4
    L = 2 * kw["radius"] * (kw["n_balls"] - 1)
    ref = kw["load"] * L ** 3 / (3 * E * I)
    val = -float(y[-1])
    err = abs(val - ref) / ref
    settle = abs(float(y[-1] - y[int(0.9 * len(y))])) / ref
    info = {**kw, "steps": res.n_steps, "dt": float(res.params.dt),
            "value_in": val / 0.0254, "reference_in": ref / 0.0254, "last_10pct_change": settle}
    return [Record("itasca_beam", "tip deflection [m]", val, ref, err, 0.002, err < 0.002,
                   wall, info)]
