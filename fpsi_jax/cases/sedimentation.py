"""One grain in a closed channel of fluid (Glowinski et al. 2001 as set up in W6.2.1): the
scene and its three validations, the terminal velocity against the drag law's own force
balance, a neutrally buoyant grain, and the settling against a published y(t)."""
from __future__ import annotations

import time

import numpy as np

from ..build import (check_positive, dam_speed, disc_block, hydrostatic_fluid, lattice,
                     sound_speed, sph_params, tank)
from ..build.fluid import in_float64
from ..model.errors import ParameterError
from ..model.options import Drag, choose
from ..model.params import DemParams, FpiParams, Params
from ..model.scene import Scene
from ..physics import fpi
from ..run.driver import simulate
from . import overrides as ov
from .grains import check_voidage, fit_spacing, fluid_among_grains
from .registry import Record, load_csv, scene, validation

SEDIMENTATION_REFERENCE = "sedimentation_zhang2019_fpm_pst_y_position.csv"


@scene
def sedimentation(*, width=0.02, height=0.06, d=0.0025, rho_grain=1250.0, rho_fluid=1000.0,
                  mu=0.01, x0=0.01, y0=0.04, dx=0.0015, dx_boundary=0.00125, h0=None,
                  c0=None, kn=1.0e4, friction=0.3, beta_n=0.5,
                  voidage="area", drag="cylinder", added_mass=True, c_added=1.0,
                  r_clump=0.01, eps_xsph=0.5, delta=0.1, x64=False,
                  wall_images=True, t_end=1.0) -> Scene:
    """One grain (disc d = 2.5 mm, ρ 1250) released at rest at (``x0``, ``y0``) = (0.01,
    0.04) m in a ``width`` × ``height`` = 0.02 × 0.06 m box of fluid (ρ 1000, μ 0.01 Pa·s);
    W6.2.1's numerical parameters: fluid spacing 1.5 mm, boundary 1.25 mm; Wendland h
    ``h0`` = max(3 mm, 2d) = 5 mm (W6.2.1 took 3 mm, 1.2 d).

    Why 2d: the grain is not resolved, it acts on the fluid through its kernel-averaged
    voidage and reaction, and the averaged equations need the kernel wider than the grain.
    Robinson, Ramaioli & Luding (2014) found one SPH–DEM grain settling within 1–2 % of
    the analytical solution once the fluid resolution is coarser than twice the grain's
    diameter; at h = 1.2 d the fluid particles next to the grain's path pass up through it
    and its settling speed moves by ±30 % with the fluid spacing (docs/physics.md, *Drag
    of a disc*). ``added_mass`` (with C_a = ``c_added``, 1 for a cylinder) turns on the
    grain's added mass (Physics.added_mass, fpi.added_mass).

    The channel of Glowinski et al. is closed; here its top is a free surface at y =
    ``height`` (the grain never comes near it). The grain meets the box through DEM line
    walls with a soft contact (``kn`` 1e4 N/m, β_n 0.5): only the landing depends on it.
    c0 = 10 √(2 g height). With ``rho_grain`` = ``rho_fluid`` the grain is neutrally
    buoyant; with a small ``d`` (ε → 1) it is the terminal-velocity case. ``dx`` is fitted
    to fill ``width`` with whole columns (``builder_kwargs`` records the fitted value).
    ``drag``: 'cylinder' (default: the disc is a cylinder per unit length, fpi.py) or
    'sphere' (the seed's W19–W23). ``wall_images``: the grain's images in the walls count in
    the voidage (fpi.wall_images)."""
    h0 = max(0.003, 2.0 * d) if h0 is None else h0
    check_positive(width=width, height=height, d=d, rho_grain=rho_grain, rho_fluid=rho_fluid,
                   mu=mu, dx=dx, dx_boundary=dx_boundary, h0=h0, kn=kn, t_end=t_end)
    check_voidage(voidage)
    choose(Drag, "drag", drag)
    if not (d / 2 < x0 < width - d / 2 and d / 2 < y0 < height - d / 2):
        raise ParameterError(f"grain start ({x0}, {y0}) out of range; allowed inside the box "
                             f"[{d / 2}, {width - d / 2}] × [{d / 2}, {height - d / 2}]")
    v_max = dam_speed(height)
    c0 = sound_speed(v_max) if c0 is None else c0
    dx = fit_spacing(width, dx)
    sp = sph_params(rho_fluid, c0, mu, dx, r_clump, eps_xsph, delta)
    surface = round(height / dx) * dx
    fluid = hydrostatic_fluid(lattice(0.0, 0.0, width, height, dx), rho_fluid, c0, sp.gamma,
                              surface, dx=dx, h=h0)
    grain = disc_block(np.array([[x0, y0]]), d / 2, rho_grain)
    grain.grain = np.array([True])
    grain.structure = np.array([False])
    box = tank(width, height, dx_boundary, h0, rho_fluid, dem_walls=True, lid=True)
    fluid = fluid_among_grains(fluid, grain.x, grain.radius, voidage,
                               walls=box.walls if wall_images else None)
    lo, hi = box.domain(headroom=0.5)
    return Scene(
        name="sedimentation",
        params=Params(sph=sp, dem=DemParams(kn=kn, ks=0.5 * kn, mu=friction, beta_n=beta_n,
                                            beta_s=beta_n),
                      fpi=FpiParams(added_mass=c_added)),
        domain_lo=lo, domain_hi=hi, v_max=v_max,
        fluid=fluid, boundary=box.boundary, solid=grain, walls=box.walls, t_end=t_end, open_sides=("top",),
        options={"fpi": True, "voidage": voidage, "drag": drag, "delta_sph": True,
                 "boundary_pressure": "extrapolated", "x64": x64,
                 "wall_images": bool(wall_images), "added_mass": bool(added_mass)},
        builder_kwargs=dict(dx=dx, c0=c0, h0=h0))


def grain_observer(state):
    """(position, velocity, Shepard fluid velocity ū_f, voidage ε_p) of the first grain."""
    k = state.fpi.idx[0]
    return state.solid.x[k], state.solid.v[k], state.fpi.u_f[0], state.fpi.eps_p[0]


def grain_run(scene, **kw):
    """Run a one-grain scene; returns (t, x, v, u_f, ε_p, result) per step."""
    res = simulate(scene, progress=False, observe=grain_observer, **kw)
    x, v, u, e = (np.asarray(a, float) for a in res.observations)
    t = (np.arange(x.shape[0]) + 1) * float(res.params.dt)
    return t, x, v, u, e, res


def terminal_slip(eps, rho_p, rho_f, d, mu, g, law="sphere"):
    """The slip s at which the drag law balances weight minus buoyancy,
    (ρ_p − ρ_f) g = β(ε, s)/(1 − ε) s (W19–W23 per unit grain volume), by bisection."""
    law = choose(Drag, "drag", law)

    def excess(s):
        beta = float(in_float64(fpi.interphase_beta, eps, s, rho_f, d, mu, law))
        return (rho_p - rho_f) * g - beta / (1 - eps) * s
    lo, hi = 0.0, 1.0
    while excess(hi) > 0:
        hi *= 2.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if excess(mid) > 0 else (lo, mid)
    return 0.5 * (lo + hi)


def _info(scene, res, quick, **extra):
    return {**scene.builder_kwargs, "quick": quick, "n_particles": scene.n_particles,
            "steps": res.n_steps, "dt": float(res.params.dt), **extra}


@validation("terminal_velocity", "isolated small grain (ε → 1) settling: mean slip vs the "
            "root of the drag law's force balance", scene="sedimentation")
def terminal_velocity_case(quick: bool = False, overrides: dict | None = None):
    # 0.04 m of fluid: under the cylinder law the grain slips at 0.089 m/s and falls 0.025 m
    # in 0.3 s, still 0.01 m above the floor at the end
    base = dict(width=0.02, height=0.04, d=0.0005, rho_grain=5000.0, y0=0.035, x64=True,
                t_end=0.15 if quick else 0.3)
    scene, phys = ov.build("sedimentation", overrides or {}, base)
    t0 = time.perf_counter()
    t, x, v, u, e, res = grain_run(scene, every=scene.t_end / 5, **phys)
    wall = time.perf_counter() - t0
    kw = scene.builder_kwargs
    late = t > t[-1] / 3
    slip = float(np.mean(u[late, 1] - v[late, 1]))
    eps = float(np.mean(e[late]))
    g = float(-np.asarray(res.params.gravity)[1])
    ref = terminal_slip(eps, kw["rho_grain"], kw["rho_fluid"], kw["d"], kw["mu"], g,
                        scene.options["drag"])
    rel = abs(slip - ref) / ref
    info = _info(scene, res, quick, eps_p=eps, window_s=[float(t[late][0]), float(t[-1])],
                 grain_velocity=float(-np.mean(v[late, 1])),
                 fluid_velocity_at_grain=float(-np.mean(u[late, 1])))
    return [Record("terminal_velocity", "mean slip |u_f - v_p| [m/s]", slip, ref, rel, 0.02,
                   rel < 0.02, wall, info)]


@validation("neutral_buoyancy", "grain of the fluid's density in still water: largest drift "
            "over 0.5 s, in diameters", scene="sedimentation")
def neutral_buoyancy_case(quick: bool = False, overrides: dict | None = None):
    base = dict(rho_grain=1000.0, x64=True, t_end=0.25 if quick else 0.5)
    over = dict(overrides or {})
    scene, phys = ov.build("sedimentation", over, base)
    kw = scene.builder_kwargs
    if kw["rho_grain"] != kw["rho_fluid"]:
        raise ParameterError("neutral_buoyancy needs rho_grain == rho_fluid")
    t0 = time.perf_counter()
    t, x, v, u, e, res = grain_run(scene, every=scene.t_end / 5, **phys)
    wall = time.perf_counter() - t0
    drift = float(np.max(np.linalg.norm(x - np.array([kw["x0"], kw["y0"]]), axis=1)) / kw["d"])
    info = _info(scene, res, quick, final_drift_d=float(
        np.linalg.norm(x[-1] - np.array([kw["x0"], kw["y0"]])) / kw["d"]))
    return [Record("neutral_buoyancy", "max drift / d", drift, 0.0, drift, 0.1, drift < 0.1,
                   wall, info)]


def phys_drag(scene):
    return scene.options.get("drag", "sphere")


def sedimentation_metrics(t, y, ref, y0):
    """RMS of y − y_ref over the reference times (relative to the fall y0 − y_ref,end) and
    the settling velocity (slope of a straight-line fit for 0.2 ≤ t ≤ 0.6 s) of ours and
    of the reference."""
    mask = ref[:, 0] <= t[-1]
    yi = np.interp(ref[mask, 0], t, y)
    rms = float(np.sqrt(np.mean((yi - ref[mask, 1]) ** 2)) / (y0 - ref[-1, 1]))
    win = (ref[:, 0] >= 0.2) & (ref[:, 0] <= 0.6)
    v_ref = -np.polyfit(ref[win, 0], ref[win, 1], 1)[0]
    ours = (t >= 0.2) & (t <= 0.6)
    v_ours = -np.polyfit(t[ours], y[ours], 1)[0] if ours.sum() > 10 else float("nan")
    return rms, float(v_ours), float(v_ref)


@validation("sedimentation", "single grain in the Glowinski channel (W6.2.1): y(t) and "
            "settling velocity vs Zhang 2019 FPM")
def sedimentation_case(quick: bool = False, overrides: dict | None = None):
    base = dict(t_end=0.3) if quick else {}
    scene, phys = ov.build("sedimentation", overrides or {}, base)
    t0 = time.perf_counter()
    t, x, v, u, e, res = grain_run(scene, every=scene.t_end / 10, **phys)
    wall = time.perf_counter() - t0
    ref = load_csv(SEDIMENTATION_REFERENCE)
    ref = ref[np.argsort(ref[:, 0])]
    rms, v_ours, v_ref = sedimentation_metrics(t, x[:, 1], ref, scene.builder_kwargs["y0"])
    mid = (t >= 0.2) & (t <= 0.6)
    info = _info(scene, res, quick, eps_p_mean=float(np.mean(e)), drag=str(phys_drag(scene)),
                 fluid_spacing_over_d=scene.params.sph.dp / scene.builder_kwargs["d"],
                 fluid_velocity_at_grain=float(np.mean(u[mid, 1])) if mid.any() else None)
    out = [Record("sedimentation", "RMS(y - y_ref) / fall height", rms, 0.0, rms, 0.03,
                  rms < 0.03, wall, info)]
    if not quick:
        rel = abs(v_ours - v_ref) / v_ref
        out.append(Record("sedimentation", "settling velocity 0.2-0.6 s [m/s]", v_ours, v_ref,
                          rel, 0.05, rel < 0.05, wall, info))
    return out
