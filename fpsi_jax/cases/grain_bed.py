"""A packed bed of grains under still water in a closed tank: the scene and its validation
against rest, hydrostatic pore pressure and the bed's buoyant weight on the floor.

The test of the fluid–particle coupling in a dense bed at the bed's own voidage: pore fluid
at rest among touching grains. At the area voidage of a hexagonal bed (ε ≈ 0.1) the pore
fluid is ten times lighter than free water, and every force error on it is ten times
larger in acceleration (docs/physics.md, Packed beds).
"""
from __future__ import annotations

import math
import time

import jax.numpy as jnp
import numpy as np

from ..build import (check_positive, dam_speed, disc_block, domain, fit_spacing, fluid_among_grains,
                     hex_packing, hydrostatic_fluid, lattice, sound_speed, sph_params, tank)
from ..model.errors import ParameterError, SimulationError
from ..model.options import Drag, FpiPressure, choose
from ..model.params import DemParams, FpiParams, Params
from ..model.scene import Scene, SolidBlock, WallBlock
from ..physics import eos
from ..run.driver import simulate
from . import overrides as ov
from .grains import check_voidage
from .registry import Record, scene, validation

PACKINGS = ("hex", "random")


def hex_bed(width, d, layers):
    """Hexagonal rows of touching discs from the floor, ``layers`` rows (long rows of
    ⌊width/d⌋ discs against the left wall, short rows shifted by d/2)."""
    s = math.sqrt(3.0) / 2.0 * d
    return hex_packing(0.0, 0.0, width, d + (layers - 1) * s + 1e-9 * d, d)


def random_bed(width, d, n, seed=0, t_settle=0.4, v_rest=1e-3, t_max=4.0):
    """``n`` discs dropped at random from above the floor and settled dry under gravity by a
    DEM run (soft contacts kn = 1e5 N/m, friction 0.3, local damping 0.7): a random packing
    at rest on the floor between two walls ``width`` apart. The run goes on in spans of
    ``t_settle`` s until no disc moved faster than ``v_rest`` m/s during a whole span: no
    fixed time settles every packing (after 0.4 s discs still moved at 50–110 mm/s, and
    such a bed did not come to rest under water). A packing not at rest after ``t_max`` s
    is refused. The starting positions are a random sequential addition (no overlaps) in a
    box ``width`` wide and 3 n d²/width high, from ``seed``."""
    rng = np.random.default_rng(seed)
    height = 3.0 * n * d * d / width + d
    pts = []
    while len(pts) < n:
        p = np.array([rng.uniform(d / 2, width - d / 2), rng.uniform(d / 2, height)])
        if all(np.hypot(*(p - q)) >= d * 1.001 for q in pts):
            pts.append(p)
    x = np.array(sorted(pts, key=lambda q: q[1]))
    blk = disc_block(x, d / 2, 2500.0)
    a = np.array([[0.0, 0.0], [width, 0.0], [width, 2 * height]])
    b = np.array([[width, 0.0], [width, 2 * height], [0.0, 2 * height]])
    walls = WallBlock(a=np.concatenate([a, [[0.0, 2 * height]]]),
                      b=np.concatenate([b, [[0.0, 0.0]]]), side=np.zeros(4))
    dry = Scene(name="random_bed", params=Params(dem=DemParams(kn=1e5, ks=5e4, mu=0.3,
                                                               alpha=0.7)),
                domain_lo=(-d, -d), domain_hi=(width + d, 2 * height + d), v_max=1.0,
                solid=blk, walls=walls, t_end=t_settle, options={"x64": True})
    state, t, fastest = None, 0.0, np.inf
    while fastest > v_rest:
        if t >= t_max - 1e-12:
            raise ParameterError(
                f"seed = {seed}: the random bed is not at rest after {t_max} s of settling "
                f"(fastest disc {fastest:.3g} m/s, allowed below v_rest = {v_rest} m/s)")
        t = min(t + t_settle, t_max)
        res = simulate(dry, t_end=t, state=state, progress=False, observe=_fastest_disc)
        state, speeds = res.state, np.asarray(res.observations)
        fastest = float(speeds.max())
    return separate(np.asarray(state.solid.x, float), d, width)


def _fastest_disc(state):
    return jnp.max(jnp.sqrt(jnp.sum(state.solid.v * state.solid.v, -1)))


def separate(x, d, width, tol=1e-9, max_sweeps=1000):
    """Push apart the discs of a packing settled with soft contacts until no two overlap
    by more than ``tol`` d and all lie inside [0, width] above the floor. The settle's
    overlaps (δ ≈ weight above / kn, 0.2 % of d at kn = 1e5 N/m) would hold ½ kn δ² of
    elastic energy each under the scene's contacts (kn = 1e9 N/m): about 10 mJ, which
    shot grains off at 1.8 m/s in the first step. Each sweep moves both discs of every
    overlapping pair apart by half their overlap (Jacobi), then clamps to the walls."""
    x = np.array(x, float)
    r = d / 2
    iu = np.triu_indices(len(x), 1)
    for _ in range(max_sweeps):
        sep = x[:, None, :] - x[None, :, :]
        dist = np.linalg.norm(sep, axis=-1)
        over = np.where(dist < d, d - dist, 0.0)
        np.fill_diagonal(over, 0.0)
        if over[iu].max(initial=0.0) <= tol * d:
            break
        unit = sep / np.where(dist > 0, dist, 1.0)[..., None]
        x += 0.5 * np.sum((over * (1 + 1e-6))[..., None] * unit, axis=1)
        x[:, 0] = np.clip(x[:, 0], r, width - r)
        x[:, 1] = np.maximum(x[:, 1], r)
    return x


@scene
def grain_bed(*, width=0.0504, water_height=0.1008, d=0.0024, layers=4, packing="hex", seed=0,
              rho_grain=2500.0, dx=0.0024, dx_boundary=0.0015, h0=None, mu=1.0e-3,
              c0=None, kn=1.021e9, ks=1.024e7, friction=0.3, beta_n=0.3,
              voidage="area", eps_floor=0.0, fpi_pressure="shared", drag="sphere",
              alpha_av=0.02, delta=0.1, wall_images=True, t_end=2.0) -> Scene:
    """A bed of grains (d 2.4 mm, ρ 2500: the two-phase dam break's) on the floor of a
    closed tank ``width`` wide (21 d: the long hexagonal rows touch both walls, so the bed
    cannot slide) under ``water_height`` of still water (42 rows of 2.4 mm), started
    hydrostatic.

    packing  'hex'    ``layers`` hexagonal rows of touching discs (area voidage 0.093)
             'random' as many discs, dropped at random and settled dry (:func:`random_bed`,
                      ``seed``)
    The fluid sees the bed's voidage (``voidage`` 'area' by default: the physical one of a
    2D bed), floored at ``eps_floor`` (0: none); fluid particles among grains get the mass
    ε ρ0 Δx² of their cell, so the start is hydrostatic. The grains' pressure force is
    their part of the cells' pressure forces with the mixture's continuity
    (``fpi_pressure`` 'shared', fpi.py: energy-conserving); with ``wall_images`` the grains'
    images in the walls count in the voidage (fpi.wall_images). W6.2.2's fluid and
    boundary spacings (2.4 mm fitted to the width, 1.5 mm) and W6.3's contacts; the kernel
    ``h0`` = 2 dx (W6.2.2 took 3 mm, 1.25 dx). At 1.25 dx the water over the bed never came
    to rest (bursts to 4.9 % / 5.9 % of √(gH), hex / random) and, in a flume, waves lost
    15–20 % of their height and a standing wave 78 % of its amplitude in four periods: two
    and a half spacings of support are too few at a free surface (docs/physics.md,
    *Waves*, *Packed beds*)."""
    h0 = 2.0 * dx if h0 is None else h0
    check_positive(width=width, water_height=water_height, d=d, layers=layers,
                   rho_grain=rho_grain, dx=dx, dx_boundary=dx_boundary, h0=h0, kn=kn)
    check_voidage(voidage)
    choose(FpiPressure, "fpi_pressure", fpi_pressure)
    choose(Drag, "drag", drag)
    if packing not in PACKINGS:
        raise ParameterError(f"packing must be one of {PACKINGS}, got {packing!r}")
    if isinstance(layers, bool) or int(layers) != layers or not 1 <= layers <= 100:
        raise ParameterError(f"layers = {layers} out of range; allowed whole numbers [1, 100]")
    xg = hex_bed(width, d, int(layers))
    if packing == "random":
        xg = random_bed(width, d, xg.shape[0], seed)
    if xg[:, 1].max() + d / 2 > water_height:
        raise ParameterError(f"layers = {layers}: the bed is higher than the water")
    grains: SolidBlock = disc_block(xg, d / 2, rho_grain)
    grains.grain = np.ones(grains.n, bool)
    dx = fit_spacing(width, dx)
    surface = round(water_height / dx) * dx              # the water the lattice holds
    surface = water_height if abs(surface - water_height) < 1e-9 * water_height else surface
    v_max = dam_speed(surface)
    c0 = sound_speed(v_max) if c0 is None else c0
    sp = sph_params(1000.0, c0, mu, dx, 0.01, 0.5, delta, alpha=alpha_av)
    fluid = hydrostatic_fluid(lattice(0.0, 0.0, width, water_height, dx), 1000.0, c0,
                              sp.gamma, surface, dx=dx, h=h0)
    box = tank(width, 1.5 * water_height, dx_boundary, h0, 1000.0, dem_walls=True, lid=True)
    fluid = fluid_among_grains(fluid, grains.x, grains.radius, voidage, eps_floor,
                               box.walls if wall_images else None)
    lo, hi = domain((0.0, 0.0), (box.width, box.height), box.pad)
    return Scene(
        name="grain_bed",
        params=Params(sph=sp, dem=DemParams(kn=kn, ks=ks, mu=friction, beta_n=beta_n,
                                            beta_s=beta_n), fpi=FpiParams()),
        domain_lo=lo, domain_hi=hi, v_max=v_max, fluid=fluid, boundary=box.boundary,
        solid=grains, walls=box.walls, t_end=t_end,
        options={"fpi": True, "voidage": voidage, "eps_floor": eps_floor,
                 "fpi_pressure": fpi_pressure, "drag": drag,
                 "boundary_pressure": "extrapolated", "artificial_viscosity": True,
                 "delta_sph": True, "wall_images": bool(wall_images)},
        builder_kwargs=dict(c0=c0, dx=dx, surface=surface, n_grain=grains.n))


def bed_observer(state):
    """(max |v| of the fluid, max |v| of the grains, Σ of the fluid's force on the grains)."""
    f, s = state.fluid, state.solid
    return (jnp.max(jnp.sqrt(jnp.sum(f.v * f.v, -1))), jnp.max(jnp.sqrt(jnp.sum(s.v * s.v, -1))),
            jnp.sum(state.fpi.force, axis=0))


def bed_metrics(scene, res):
    """Pore pressure L1 error against ρ0 g (H − y) below the top three layers, the largest
    fluid and grain speeds over the last quarter of the run relative to √(gH), and the bed's
    load on the walls (its weight minus the fluid's force on it, averaged over the last
    quarter: at rest, the floor's) relative to its buoyant weight Σ(ρ_p − ρ_f) V_p g."""
    kw = scene.builder_kwargs
    sp, g = res.params.sph, float(-np.asarray(res.params.gravity)[1])
    f = res.state.fluid
    y = np.asarray(f.x[:, 1])
    p = np.asarray(eos.pressure(f.rho, sp.rho0, sp.c0, sp.gamma))
    below = y < kw["surface"] - 3 * kw["dx"]
    p_ref = float(sp.rho0) * g * (kw["surface"] - y[below])
    err_p = float(np.abs(p[below] - p_ref).sum() / p_ref.sum())
    vf, vs, ff = (np.asarray(o, float) for o in res.observations)
    late = slice(int(0.75 * len(vf)), None)
    scale = math.sqrt(g * kw["water_height"])
    vol = np.pi * np.asarray(scene.solid.radius) ** 2
    weight = float(np.sum(scene.solid.mass)) * g
    buoyant = float(np.sum((kw["rho_grain"] - float(sp.rho0)) * vol)) * g
    load = weight - float(np.mean(ff[late, 1]))
    return err_p, float(vf[late].max()) / scale, float(vs[late].max()) / scale, \
        (load - buoyant) / buoyant


@validation("grain_bed_at_rest", "packed grain bed under still water at its own voidage: "
            "pore pressure, rest, buoyant weight on the floor (hex and random packings)",
            scene="grain_bed")
def grain_bed_at_rest_case(quick: bool = False, overrides: dict | None = None):
    out = []
    for packing in ("hex", "random"):
        base = {"packing": packing, **({"t_end": 0.2} if quick else {})}
        scene, phys = ov.build("grain_bed", overrides or {}, base)
        kw = scene.builder_kwargs
        info = {**kw, "quick": quick, "n_particles": scene.n_particles}
        name = "grain_bed_at_rest"
        t0 = time.perf_counter()
        try:
            res = simulate(scene, progress=False, observe=bed_observer, **phys)
        except SimulationError as e:
            wall = time.perf_counter() - t0
            info.update(failed_at_s=e.time, particle=e.particle, quantity=e.quantity)
            out.append(Record(name, f"{packing}: time the bed stays at rest [s]", float(e.time),
                              float(scene.t_end), 1.0 - float(e.time) / scene.t_end, 0.0,
                              False, wall, info))
            continue
        wall = time.perf_counter() - t0
        err_p, vf, vs, load = bed_metrics(scene, res)
        info.update(steps=res.n_steps, grain_speed=vs)
        out += [Record(name, f"{packing}: pore pressure L1 error", err_p, 0.0, err_p, 0.02,
                       err_p < 0.02, wall, info),
                Record(name, f"{packing}: max |v| / sqrt(gH), last quarter", max(vf, vs), 0.0,
                       max(vf, vs), 0.01, max(vf, vs) < 0.01, wall, info),
                Record(name, f"{packing}: load on the floor vs buoyant weight", load, 0.0,
                       abs(load), 0.02, abs(load) < 0.02, wall, info)]
    return out
