"""Hydrostatic tank: smoothing length against the residual velocity.

    python experiments/hydrostatic_tank_h.py                 # dx 5 mm, h/dx 1.25 and 1.5
    python experiments/hydrostatic_tank_h.py --dx 0.01 --h 1.25 1.5 1.7

For each h/dx: max |v| / √(gH) throughout the 2 s and at the end, where it peaked, and the
pressure L1 error against ρ0 g (H − y) below the top three layers (the `fpsi validate
hydrostatic_tank` figures). Writes experiments/results/hydrostatic_tank_h.json and
hydrostatic_tank_h.png (max |v|(t) per h).
"""
from __future__ import annotations

import argparse
import json
import math
import os
import time

import jax.numpy as jnp
import numpy as np

from fpsi_jax import cases
from fpsi_jax.physics import eos
from fpsi_jax.run.driver import simulate

OUT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "results")


def observer(s):
    speed = jnp.linalg.norm(s.fluid.v, axis=1)
    i = jnp.argmax(speed)
    return jnp.stack([speed[i], s.fluid.x[i, 0], s.fluid.x[i, 1]])


def run(dx, h_factor, t_end=2.0):
    sc = cases.build("hydrostatic_tank", dx=dx, h_factor=h_factor, t_end=t_end)
    H = sc.builder_kwargs["depth"]
    g = 9.81
    vref = math.sqrt(g * H)
    t0 = time.perf_counter()
    res = simulate(sc, progress=False, observe=observer, every=t_end / 10)
    wall = time.perf_counter() - t0
    o = np.asarray(res.observations, float)
    t = (np.arange(len(o)) + 1) * float(res.params.dt)
    v = o[:, 0] / vref
    k = int(np.argmax(v))
    f, sp = res.state.fluid, res.params.sph
    y = np.asarray(f.x[:, 1])
    p = np.asarray(eos.pressure(f.rho, sp.rho0, sp.c0, sp.gamma))
    below = y < H - 3 * dx
    p_ref = float(sp.rho0) * g * (H - y[below])
    return {"dx": dx, "h_over_dx": h_factor, "n_fluid": sc.fluid.n, "steps": res.n_steps,
            "wall_s": wall, "max_v_over_sqrt_gH_throughout": float(v.max()),
            "t_of_max_s": float(t[k]), "x_y_of_max": [float(o[k, 1]), float(o[k, 2])],
            "max_v_over_sqrt_gH_at_end": float(v[-1]),
            "pressure_L1_error": float(np.abs(p[below] - p_ref).sum() / p_ref.sum()),
            "series_t": t[::max(1, len(t) // 400)].tolist(),
            "series_v": v[::max(1, len(t) // 400)].tolist()}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--dx", type=float, default=0.005)
    ap.add_argument("--h", type=float, nargs="*", default=[1.25, 1.5])
    a = ap.parse_args()
    rows = []
    for hf in a.h:
        r = run(a.dx, hf)
        rows.append(r)
        print(f"dx {a.dx * 1e3:g} mm  h/dx {hf}: max|v|/√(gH) throughout "
              f"{r['max_v_over_sqrt_gH_throughout']:.4f} (t = {r['t_of_max_s']:.2f} s), end "
              f"{r['max_v_over_sqrt_gH_at_end']:.4f}; pressure L1 {r['pressure_L1_error']:.4f}"
              f"; {r['wall_s']:.0f} s", flush=True)
    os.makedirs(OUT, exist_ok=True)
    with open(os.path.join(OUT, "hydrostatic_tank_h.json"), "w") as fh:
        json.dump(rows, fh, indent=1)
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6, 3.5))
    for r in rows:
        ax.semilogy(r["series_t"], r["series_v"], label=f"h = {r['h_over_dx']} Δx")
    ax.axhline(0.01, color="r", ls="--", lw=0.8, label="1 % of √(gH)")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("max |v| / √(gH)")
    ax.set_title(f"hydrostatic tank, Δx = {a.dx * 1e3:g} mm")
    ax.legend()
    fig.tight_layout()
    fig.savefig(os.path.join(OUT, "hydrostatic_tank_h.png"), dpi=120)


if __name__ == "__main__":
    main()
