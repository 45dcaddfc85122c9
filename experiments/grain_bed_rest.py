"""Where the fluid over `grain_bed_at_rest`'s bed moves, 0.1 s window by window: the largest
fluid speed against √(gH), where the particle that has it is, the voidage ε0 it started at
(its mass is ε0 ρ0 Δx²) and the voidage ε it sees now; with controls that tell the bed's
share from the fluid's own.

    .venv/bin/python experiments/grain_bed_rest.py [--packing hex] [--t-end 4] \\
        [--variant bed|no-grains|frozen-grains|relaxed-start]

    bed            the validation scene as it is
    no-grains      the same tank, fluid, boundary and numerics with the grains taken out
                   (every fluid particle of mass ρ0 Δx², no voidage)
    frozen-grains  the bed with every grain held fixed (kinematic, at rest)
    relaxed-start  the bed started from the water of a 2 s frozen-grains run (positions and
                   densities kept, velocities zeroed): whether a relaxed start stays at rest

writes experiments/results/grain_bed_rest_<packing>_<variant>.csv (2–4 min on 2 cores for
2 s) and prints the windows.
"""
from __future__ import annotations

import argparse
import dataclasses
import os

import jax.numpy as jnp
import numpy as np

from _table import write_rows
from fpsi_jax import cases
from fpsi_jax.build import hydrostatic_fluid, lattice
from fpsi_jax.cases.grain_bed import bed_metrics, bed_observer
from fpsi_jax.run.driver import simulate

WINDOW = 0.1
VARIANTS = ("bed", "no-grains", "frozen-grains", "relaxed-start")
T_RELAX = 2.0


def variant_scene(packing: str, t_end: float, variant: str):
    scene = cases.build("grain_bed", packing=packing, t_end=t_end)
    if variant in ("frozen-grains", "relaxed-start"):
        solid = dataclasses.replace(scene.solid, fixed=np.ones(scene.solid.n, bool))
        frozen = dataclasses.replace(scene, solid=solid)
        if variant == "frozen-grains":
            return frozen
        f = simulate(frozen, t_end=T_RELAX, progress=False).state.fluid
        x = np.asarray(f.x, float)
        fluid = dataclasses.replace(scene.fluid, x=x, v=np.zeros_like(x),
                                    rho=np.asarray(f.rho, float))
        return dataclasses.replace(scene, fluid=fluid)
    if variant == "no-grains":
        kw, sp = scene.builder_kwargs, scene.params.sph
        h = float(np.ravel(scene.fluid.h)[0])
        width = float(np.max(scene.fluid.x[:, 0])) + kw["dx"] / 2
        fluid = hydrostatic_fluid(lattice(0.0, 0.0, width, kw["surface"], kw["dx"]),
                                  float(sp.rho0), kw["c0"], sp.gamma, kw["surface"],
                                  dx=kw["dx"], h=h)
        keep = ("boundary_pressure", "artificial_viscosity", "delta_sph")
        return dataclasses.replace(scene, fluid=fluid, solid=None, walls=None,
                                   options={k: scene.options[k] for k in keep})
    return scene


def fastest(state):
    """(max |v| of the fluid, its index, x, y, the voidage it sees)."""
    f = state.fluid
    v = jnp.sqrt(jnp.sum(f.v * f.v, axis=1))
    i = jnp.argmax(v)
    eps = state.fpi.eps[i] if state.fpi is not None else jnp.ones((), v.dtype)
    return jnp.stack([v[i], i.astype(v.dtype), f.x[i, 0], f.x[i, 1], eps])


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--packing", default="hex")
    ap.add_argument("--t-end", type=float, default=2.0)
    ap.add_argument("--variant", default="bed", choices=VARIANTS)
    a = ap.parse_args()
    scene = variant_scene(a.packing, a.t_end, a.variant)
    kw = scene.builder_kwargs
    grains = scene.solid is not None
    res = simulate(scene, progress=False,
                   observe=(lambda s: (fastest(s), bed_observer(s))) if grains else fastest)
    obs = np.asarray(res.observations[0] if grains else res.observations, float)
    eps0 = np.asarray(scene.fluid.mass) / (float(scene.params.sph.rho0) * kw["dx"] ** 2)
    scale = np.sqrt(-float(np.asarray(scene.params.gravity)[1]) * kw["water_height"])
    rows = []
    for k, w in enumerate(np.array_split(obs, int(round(a.t_end / WINDOW)))):
        v, i, x, y, eps = w[np.argmax(w[:, 0])]
        rows.append(dict(t0=round(k * WINDOW, 3), t1=round((k + 1) * WINDOW, 3),
                         fluid_max_v=round(v / scale, 5), x_mm=round(x * 1e3, 1),
                         y_mm=round(y * 1e3, 1), eps0=round(float(eps0[int(i)]), 3),
                         eps=round(float(eps), 3)))
    out = os.path.join(os.path.dirname(__file__), "results",
                       f"grain_bed_rest_{a.packing}_{a.variant}.csv")
    write_rows(out, rows)
    print("window       max|v|/sqrt(gH)  at (x, y) mm    eps0   eps")
    for r in rows:
        print(f"{r['t0']:.1f}-{r['t1']:.1f}  {r['fluid_max_v'] * 100:6.2f} %   "
              f"({r['x_mm']:5.1f}, {r['y_mm']:5.1f})  {r['eps0']:.3f}  {r['eps']:.3f}")
    if grains:
        p, vf, vs, load = bed_metrics(scene, dataclasses.replace(
            res, observations=res.observations[1]))
        print(f"validation figures: pore pressure {p:.2%}, fluid {vf:.2%}, grains {vs:.2%} "
              f"of sqrt(gH) in the last quarter, floor load {load:+.2%}")
    print("->", out)


if __name__ == "__main__":
    main()
