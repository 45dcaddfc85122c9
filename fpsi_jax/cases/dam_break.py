"""Dam break (Koshizuka & Oka 1996 geometry; K §6.2 parameters): the scene, the
surge front Z(T) against the experiment, and its plot."""
from __future__ import annotations

import time

import numpy as np

from ..build import (check_positive, dam_speed, hydrostatic_fluid, lattice, sound_speed,
                     sph_params, tank)
from ..model.params import Params
from ..model.scene import Scene
from ..run import observers
from ..run.driver import simulate
from . import overrides as ov
from .plotting import draw_snapshot, pyplot
from .registry import Record, load_csv, observer, plot, scene, validation

FRONT_REFERENCE = "koshizuka_oka1996_surge_front.csv"


@scene
def dam_break(*, column_width=0.146, column_height=0.292, tank_width=0.584,
              tank_height=0.584, dx=0.005, dx_boundary=None, h0=None, rho0=1000.0,
              mu=8.9e-4, c0=None, r_clump=0.01, eps_xsph=0.5, delta=0.1, alpha=0.02,
              t_end=0.4, boundary_pressure="extrapolated", delta_sph=True,
              artificial_viscosity=True) -> Scene:
    """Water column ``column_width`` × ``column_height`` at the left of a tank.

    Seed 001 (K6.2): Δx = 5 mm, boundary 2.5 mm, h0 = 6.25 mm (= 1.25 Δx), μ = 8.9e-4 Pa·s.
    h0 defaults to 1.25 dx so a change of resolution keeps the same kernel-to-spacing ratio.
    The column starts hydrostatic; c0 = 10 √(2 g H) (K35).

    Departures from the seed, all keyword arguments:
    * dx_boundary defaults to dx (the seed's dx/2 boundary quadruples the Dense neighbour
      capacity and halves the speed; pass dx_boundary=0.0025 for the seed's setting);
    * δ-SPH (δ = 0.1) and Monaghan artificial viscosity α = 0.02 are on: with the physical
      μ alone the run loses particles through the wall at the impact (t ≈ 0.21 s at 5 mm).
    """
    check_positive(column_width=column_width, column_height=column_height,
                   tank_width=tank_width, tank_height=tank_height, dx=dx, rho0=rho0)
    h = 1.25 * dx if h0 is None else h0
    dxb = dx if dx_boundary is None else dx_boundary
    check_positive(dx_boundary=dxb, h0=h)
    v_max = dam_speed(column_height)
    c0 = sound_speed(v_max) if c0 is None else c0
    sp = sph_params(rho0, c0, mu, dx, r_clump, eps_xsph, delta, alpha=alpha)
    fluid = hydrostatic_fluid(lattice(0.0, 0.0, column_width, column_height, dx), rho0, c0,
                              sp.gamma, column_height, dx=dx, h=h)
    box = tank(tank_width, tank_height, dxb, h, rho0)
    lo, hi = box.domain(headroom=0.5)
    return Scene(
        name="dam_break", params=Params(sph=sp), domain_lo=lo, domain_hi=hi,
        v_max=v_max, fluid=fluid, boundary=box.boundary, t_end=t_end, open_sides=("top",),
        options={"boundary_pressure": boundary_pressure, "delta_sph": delta_sph,
                 "artificial_viscosity": artificial_viscosity},
        builder_kwargs=dict(dx_boundary=dxb, h0=h, c0=c0))


#: Front position: the rightmost fluid particle centre (half a spacing is added later).
front_observer = observers.max_coordinate(0, "fluid")


def dam_break_front(scene, res):
    """(T, Z) of a run observed with :data:`front_observer`: Z = (x_front + dx/2)/a,
    T = t √(2g/a) (K&O nondimensionalisation)."""
    kw = scene.builder_kwargs
    a, dx = kw["column_width"], kw["dx"]
    g = float(-np.asarray(res.params.gravity)[1])
    t = np.arange(1, len(res.observations) + 1) * float(res.params.dt)
    return t * np.sqrt(2 * g / a), (np.asarray(res.observations) + 0.5 * dx) / a


@validation("dam_break", "front position Z(T) vs Koshizuka & Oka (1996), T <= 2.5")
def dam_break_case(quick: bool = False, overrides: dict | None = None):
    base = {"dx": 0.01} if quick else {}
    scene, phys = ov.build("dam_break", overrides or {}, base)
    kw = scene.builder_kwargs
    a = kw["column_width"]
    g = float(-np.asarray(scene.params.gravity)[1])
    t_end = 2.5 / np.sqrt(2 * g / a) * 1.02
    t0 = time.perf_counter()
    res = simulate(scene, t_end=t_end, progress=False, observe=front_observer,
                   every=t_end / 20, **phys)
    wall = time.perf_counter() - t0
    T, Z = dam_break_front(scene, res)
    ref = load_csv(FRONT_REFERENCE)
    ref = ref[(ref[:, 0] <= 2.5) & (ref[:, 0] > 0)]
    z = np.interp(ref[:, 0], T, Z)
    rel = np.abs(z - ref[:, 1]) / ref[:, 1]
    k = int(np.argmax(rel))
    info = {**kw, "quick": quick, "n_particles": scene.n_particles, "steps": res.n_steps,
            "T_worst": float(ref[k, 0])}
    return [Record("dam_break", "front Z at worst T <= 2.5", float(z[k]), float(ref[k, 1]),
                   float(rel[k]), 0.05, bool(rel.max() < 0.05), wall, info)]


@observer("dam_break")
def run_observer(scene):
    return front_observer


@plot("dam_break")
def run_plot(scene, res, png):
    """The final state beside the front Z(T) against Koshizuka & Oka; prints the front at
    the experiment's times."""
    plt = pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    draw_snapshot(fig, axes[0], scene, res)
    T, Z = dam_break_front(scene, res)
    ref = load_csv(FRONT_REFERENCE)
    axes[1].plot(T, Z, label=f"fpsi-jax, dx = {scene.builder_kwargs['dx'] * 1e3:g} mm")
    axes[1].plot(ref[:, 0], ref[:, 1], "ko", label="Koshizuka & Oka (1996)")
    axes[1].set_xlabel("T = t sqrt(2g/a)")
    axes[1].set_ylabel("Z = x_front / a")
    axes[1].set_xlim(0, max(3.5, float(ref[:, 0].max()) + 0.2))
    axes[1].legend()
    axes[1].grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(png, dpi=120)
    plt.close(fig)
    lines = [f"wrote {png}"]
    ref = ref[(ref[:, 0] > 0) & (ref[:, 0] <= T.max())]
    z = np.interp(ref[:, 0], T, Z)
    lines.append("front vs Koshizuka & Oka:  T      Z_exp   Z_sim   rel.err")
    for t_, zr, zs in zip(ref[:, 0], ref[:, 1], z):
        lines.append(f"                          {t_:5.3f}  {zr:6.3f}  {zs:6.3f}  "
                     f"{(zs - zr) / zr:+.1%}")
    return lines
