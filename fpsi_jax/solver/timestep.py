"""Time-step bounds (host side, numpy): the largest stable step of a scene's phases and the
DEM sub-steps of a coupled scene (physics.md §Time integration, docs/design.md for the
coefficients)."""
from __future__ import annotations

import math

import numpy as np

from ..model.config import Physics
from ..model.errors import ParameterError
from ..model.options import Voidage
from ..model.params import Params
from ..model.scene import Scene
from ..physics import bonds as bonds_law
from ..physics import fpi, kernels


def _physics(scene: Scene, phys: Physics | None) -> Physics:
    return Physics.for_scene(scene) if phys is None else phys


def _grains(scene: Scene, phys: Physics):
    """Indices of the grains coupled to the fluid (empty without option fpi)."""
    if not phys.has_fpi:
        return np.zeros(0, int)
    return scene.solid.grain_indices()


# Step coefficients. physics.md quotes 0.25 h/(c0+|v|) and 0.2 √(m/k); the sweeps of
# experiments/stability.py found those 5–6.5× below the step where the runs blow up, so the
# fluid-only and DEM-only coefficients below keep a measured margin of 1.7–1.9 instead. A
# structure the fluid moves (option fsi, Scene.fsi_coupled) takes the DEM coefficient and
# an SPH one of 0.375: the step is sized for the accuracy of the force-holding coupling
# (the sloshing baffle's tip within 1.3 % of its converged record, where 0.5 left it 16 %
# off; the elastic gate's peak within 0.5 %), not for stability (docs/design.md,
# "Time-step coefficients", has the figures).
SPH_CFL = 0.875
FSI_SPH_CFL = 0.375
DEM_DT_FACTOR = 0.55
FSI_DEM_DT_FACTOR = DEM_DT_FACTOR      # the DEM bound needs no coupled margin of its own


def sph_dt(scene: Scene, params: Params, a_max: float | None = None,
           phys: Physics | None = None) -> float:
    """SPH bound (physics.md §Time integration, with the acoustic coefficient SPH_CFL, or
    FSI_SPH_CFL for a structure the fluid moves (Scene.fsi_coupled), instead of 0.25):
    Δt ≤ min(CFL h/(c0 + |v|max), 0.125 h²/ν, 0.25 √(h/|a|max), r0/(c0 √β) with the wall
    backstop), h the smallest smoothing length, |v|max the scene's velocity scale and
    |a|max = max(|g|, a_max).

    With grains in the fluid (fpi) the sound speed in ερ is c0/√ε, so c0/√ε_lo replaces c0,
    ε_lo = max(EPS_MIN, 1 − n_grain V_p,max W(0)) the least voidage the grains can make (3D
    mapped for Physics.voidage 'mapped'; Physics.eps_floor does not relax it: with the bed's
    fluid floored at 0.5 the step for c0/√0.5 went unstable at 0.022 s, the step for the
    unfloored 0.26 ran); and
    the drag, held over a step, must not relax the slip faster than the step: Δt ≤ 0.5 τ,
    τ = ρ_p/(β/(1−ε)) with Ergun's β at the densest sphere packing (ε 0.26) and slip
    |v|max."""
    sp = params.sph
    h = float(np.min(scene.fluid.h))
    nu = float(sp.mu) / float(sp.rho0)
    g = float(np.linalg.norm(np.asarray(params.gravity, float)))
    acc = max(g, a_max or 0.0, 1e-12)
    c = float(sp.c0)
    phys = _physics(scene, phys)
    grains = _grains(scene, phys)
    bounds = []
    if grains.size:
        r = np.asarray(scene.solid.radius, float)[grains]
        w0 = float(kernels.get(phys.kernel).w(0.0, h))
        e_lo = max(fpi.EPS_MIN, 1.0 - grains.size * np.pi * r.max() ** 2 * w0)
        if phys.voidage is Voidage.MAPPED:
            e_lo = float(fpi.voidage_3d(e_lo))
        c = c / math.sqrt(e_lo)
        e = float(fpi.voidage_3d(fpi.EPS_MIN))
        d = 2.0 * r
        rho_p = (np.asarray(scene.solid.mass, float)[grains]
                 / (np.pi * np.asarray(scene.solid.radius, float)[grains] ** 2))
        rate = (150.0 * (1 - e) * float(sp.mu) / (e * d * d)
                + 1.75 * float(sp.rho0) * scene.v_max / d) / rho_p
        bounds.append(0.5 / float(np.max(rate)))
    cfl = FSI_SPH_CFL if scene.fsi_coupled else SPH_CFL
    bounds += [cfl * h / (c + scene.v_max), 0.25 * np.sqrt(h / acc)]
    beta, r0 = float(sp.wall_beta), scene.wall_range()
    if r0 > 0 and phys.wall_repulsion and beta > 0:
        # the wall backstop's stiffness is at most β c0²/r0² (sph.wall_repulsion_scalar);
        # leapfrog needs Δt < 2 r0/(c0 √β), kept with a factor 2 of margin
        bounds.append(r0 / (c * math.sqrt(beta)))
    if nu > 0:
        bounds.append(0.125 * h * h / nu)
    return float(min(bounds))


def dem_dt(scene: Scene, params: Params, phys: Physics | None = None) -> float:
    """DEM bound (physics.md §Time integration, with DEM_DT_FACTOR = 0.55, and
    FSI_DEM_DT_FACTOR, the same, for a structure the fluid moves (Scene.fsi_coupled); the
    seeds took 0.2):
    Δt ≤ factor √(m_min/k_max), and the same for rotation, factor √(J_min/k_rot). k_max adds the contact spring and the stiffest bond
    (k̄ A); k_rot = k̄_n I + (k̄_s A + k_s) R_max² for the stiffest bond."""
    so, dp, bp = scene.solid, params.dem, params.bond
    section = _physics(scene, phys).bond_section
    free = ~np.asarray(so.fixed, bool)
    if not free.any():
        if scene.fluid is not None:     # fixed and kinematic discs only: no DEM force is
            return math.inf             # ever integrated, the SPH step alone bounds Δt
        free = np.ones(so.n, bool)
    m = float(np.min(so.mass[free]))
    J = float(np.min(so.inertia[free]))
    r = float(np.max(so.radius))
    kn, ks = float(dp.kn), float(dp.ks)
    k_rot = ks * r * r
    if scene.bonds is not None and bp is not None:
        A, I = map(float, bonds_law.section(section, float(bp.lam) * r, float(bp.thickness)))
        kn += float(bp.kn) * A
        ks += float(bp.ks) * A
        k_rot = float(bp.kn) * I + ks * r * r
    k = max(kn, ks)
    bound = np.sqrt(m / k)
    if k_rot > 0:
        bound = min(bound, np.sqrt(J / k_rot))
    bound = (FSI_DEM_DT_FACTOR if scene.fsi_coupled else DEM_DT_FACTOR) * bound
    c = float(getattr(dp, "damping", 0.0))
    if c > 0:                      # the lagged viscous term is stable for c·Δt < 2; keep ≤ 0.5
        bound = min(bound, 0.5 / c)
    return float(bound)


def stable_dt(scene: Scene, params: Params | None = None, a_max: float | None = None,
              substeps: int = 1, phys: Physics | None = None) -> float:
    """Largest time step allowed by the explicit bounds of the phases the scene has; with
    ``substeps`` DEM sub-steps per step the DEM bound counts ``substeps`` times."""
    p = params or scene.params
    phys = _physics(scene, phys)
    bounds = []
    if scene.fluid is not None:
        bounds.append(sph_dt(scene, p, a_max, phys))
    if scene.solid is not None:
        bounds.append(substeps * dem_dt(scene, p, phys))
    return float(min(bounds))


def substeps_for(scene: Scene, dt: float, params: Params | None = None,
                 phys: Physics | None = None) -> int:
    """Fewest DEM sub-steps that keep dt/n under the DEM bound (1 without both phases)."""
    if scene.fluid is None or scene.solid is None:
        return 1
    p = params or scene.params
    bound = dem_dt(scene, p, phys)
    return max(1, int(math.ceil(dt / bound * (1.0 - 1e-12))))


def check_dt(scene: Scene, dt: float, params: Params | None = None, substeps: int = 1,
             auto_substeps: bool = False, phys: Physics | None = None) -> None:
    """Refuse a step outside (0, bound]. With ``auto_substeps`` (fluid and discs, the
    sub-step count chosen from dt) the DEM bound never limits dt, so a step that is not
    positive is told the SPH bound, the largest step it may ask for."""
    if not dt > 0 and auto_substeps and scene.fluid is not None and scene.solid is not None:
        raise ParameterError(f"dt = {dt} out of range; allowed "
                             f"(0, {sph_dt(scene, params or scene.params, phys=phys):.4g}] s (the DEM "
                             "sub-steps are chosen from dt)")
    bound = stable_dt(scene, params, substeps=substeps, phys=phys)
    if not dt > 0:
        raise ParameterError(f"dt = {dt} out of range; allowed (0, {bound:.4g}] s")
    if dt > bound * (1 + 1e-9):
        sub = f" with dem_substeps = {substeps}" if substeps > 1 and not auto_substeps else ""
        raise ParameterError(
            f"dt = {dt:.4g} s exceeds the stability bound {bound:.4g} s{sub} "
            f"(SPH: {SPH_CFL:g} h/(c0+|v|max), {FSI_SPH_CFL:g} with a structure the fluid "
            "moves, 0.125 h²/ν, 0.25 √(h/|a|max), r0/(c0 √β) for the wall backstop; "
            f"DEM: {DEM_DT_FACTOR:g} √(m/k), {FSI_DEM_DT_FACTOR:g} √(m/k) with such a "
            "structure, per "
            f"sub-step); allowed (0, {bound:.4g}] s")
