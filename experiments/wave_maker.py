"""Regular waves from a piston wave maker against linear wave-maker theory.

A piston (a `[[kinematic]]` body with `oscillate`) of stroke S = 2 cm at period T = 0.8 s
in water h = 0.1 m deep (kh = 0.886, L = 0.709 m) makes waves of height H = 0.876 S
(Biesel & Suquet 1951; Dean & Dalrymple 1991, eq. 6.22: H/S = 2(cosh 2kh − 1)/(sinh 2kh +
2kh)), travelling at the group velocity c_g = 0.72 m/s. Gauges 0.4, 0.8 and 1.2 m from
the piston read the free surface (kernel h = 2 dx, no artificial viscosity; docs/physics.md,
*Waves*); each gauge's wave height is the mean zero-up-crossing
height over the waves that reach it at full stroke (after the stroke's 2-period ramp) and
before the wave reflected at the flume's end comes back. The run repeats at three fluid
spacings; what the SPH fluid loses in height with distance is its numerical damping.

    python experiments/wave_maker.py [--dx 0.01 0.005 0.0025] [--h-factor 2] [--alpha 0]

(``--h-factor 1.25 --alpha 0.02 --tag h1.25dx_alpha0.02``: the default kernel and the dam
breaks' viscosity, which lose 15-20 % of the height by 0.4 m.)

Writes experiments/results/wave_maker.csv (spacing, gauge, the mean zero-up-crossing H
and the height H1 of the wave-frequency component, each against H_theory, waves counted,
wall time) and wave_maker.png (the gauges' records against ± H_theory/2).
"""
from __future__ import annotations

import argparse
import csv
import math
import pathlib
import sys
import tempfile
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
OUT = ROOT / "experiments" / "results"
sys.path.insert(0, str(ROOT))

DEPTH, PERIOD, STROKE, RAMP, LENGTH = 0.1, 0.8, 0.02, 1.6, 3.0
PADDLE = 0.02                      # the piston's face at rest
GAUGES = (0.4, 0.8, 1.2)           # from the piston's face [m]

SCENE = """
[scene]
t_end = {t_end}
headroom = 1.0
[fluid]
density = 1000.0
viscosity = 1.0e-3
dx = {dx}
h = {h}
alpha = {alpha}
[[fluid.region]]
box = [{x0}, 0.0, {length}, {depth}]
[tank]
width = {length}
height = {height}
[[kinematic]]
name = "piston"
box = [0.0, 0.0, {paddle}, {height_paddle}]
d = {d}
rho = 1000.0
oscillate = {{ amplitude = [{amp}, 0.0], period = {period}, ramp = {ramp} }}
"""


def theory(h=DEPTH, T=PERIOD, g=9.81):
    """k (dispersion ω² = g k tanh kh by fixed point), H/S (piston, linear theory), c_g."""
    w = 2 * math.pi / T
    k = w * w / g
    for _ in range(200):
        k = w * w / (g * math.tanh(k * h))
    ratio = 2 * (math.cosh(2 * k * h) - 1) / (math.sinh(2 * k * h) + 2 * k * h)
    cg = 0.5 * w / k * (1 + 2 * k * h / math.sinh(2 * k * h))
    return k, ratio, cg


def wave_heights(t, eta):
    """Zero-up-crossing heights of ``eta`` (its mean taken out): one per complete wave."""
    e = eta - eta.mean()
    up = np.flatnonzero((e[:-1] < 0) & (e[1:] >= 0))
    return np.array([np.ptp(e[a:b + 1]) for a, b in zip(up[:-1], up[1:])])


def first_harmonic(t, eta, period=PERIOD):
    """Height 2|a| of the wave-frequency component a e^{iωt} of ``eta`` over ``t``, by least
    squares (the linear wave; what a piston also sheds as free second harmonics, which make
    the crest-to-trough height vary along the flume, is left out)."""
    w = 2 * math.pi / period
    A = np.stack([np.cos(w * t), np.sin(w * t), np.ones_like(t)], axis=1)
    c = np.linalg.lstsq(A, eta, rcond=None)[0]
    return 2 * math.hypot(c[0], c[1])


def run(dx, t_end, extra=(), dt_factor=1.0, h_factor=2.0, alpha=0.0):
    from fpsi_jax import scenefile
    from fpsi_jax.run.driver import simulate
    text = SCENE.format(t_end=t_end, dx=dx, h=h_factor * dx, alpha=alpha, x0=PADDLE + dx, length=LENGTH, depth=DEPTH,
                        height=2 * DEPTH, paddle=PADDLE, height_paddle=1.8 * DEPTH,
                        d=min(dx, 0.005), amp=STROKE / 2, period=PERIOD, ramp=RAMP)
    for item in extra:                    # table.key=value into its table
        table, kv = item.split(".", 1)
        key = kv.split("=")[0].strip()
        lines = text.splitlines()
        hit = [j for j, ln in enumerate(lines) if ln.split("=")[0].strip() == key]
        if hit:                           # a key the scene has: replace its line
            lines[hit[0]] = kv
            text = "\n".join(lines) + "\n"
        elif f"[{table}]" in text:
            text = text.replace(f"[{table}]\n", f"[{table}]\n{kv}\n", 1)
        else:
            text += f"[{table}]\n{kv}\n"
    text += "".join(f'[[probe]]\nname = "g{i}"\nkind = "water_level"\nx = {PADDLE + x}\n'
                    for i, x in enumerate(GAUGES))
    with tempfile.TemporaryDirectory() as tmp:
        path = pathlib.Path(tmp) / "flume.toml"
        path.write_text(text)
        sf = scenefile.load(str(path))
        t0 = time.perf_counter()
        dt = None
        if dt_factor != 1.0:              # a step shorter than the derived one
            from fpsi_jax.run import setup
            dt = dt_factor * float(setup(sf.scene)[1].dt)
        res = simulate(sf.scene, probes=sf.probes, progress=False, every=0.02, dt=dt)
        wall = time.perf_counter() - t0
    t = np.asarray(res.times)
    return t, {k: np.asarray(v).ravel() for k, v in res.probes.items()}, wall, sf.scene.n_particles


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dx", type=float, nargs="+", default=[0.01, 0.005, 0.0025])
    ap.add_argument("--t-end", type=float, default=6.0)
    ap.add_argument("--set", nargs="*", default=[], help="table.key=value, e.g. fluid.alpha=0.01 "
                    "physics.xsph=false")
    ap.add_argument("--tag", default="", help="suffix of the result files (a variant)")
    ap.add_argument("--keep", action="store_true", help="also write the gauges' records (.npz)")
    ap.add_argument("--dt-factor", type=float, default=1.0, help="the step, × the derived one")
    ap.add_argument("--h-factor", type=float, default=2.0, help="h / dx (the default 1.25 "
                    "damps waves: docs/physics.md, Waves)")
    ap.add_argument("--alpha", type=float, default=0.0, help="artificial viscosity α")
    a = ap.parse_args()
    name = "wave_maker" + (f"_{a.tag}" if a.tag else "")
    k, ratio, cg = theory()
    h_th = ratio * STROKE
    print(f"k = {k:.3f} 1/m, L = {2 * math.pi / k:.3f} m, kh = {k * DEPTH:.3f}, "
          f"H/S = {ratio:.4f}, H = {h_th * 1e3:.2f} mm, c_g = {cg:.3f} m/s")
    rows, records = [], {}
    for dx in a.dx:
        t, probes, wall, n = run(dx, a.t_end, a.set, a.dt_factor, a.h_factor, a.alpha)
        records[dx] = (t, probes)
        np.savez(OUT / f"{name}_dx{dx:g}.npz", t=t, **probes) if a.keep else None
        for i, x in enumerate(GAUGES):
            start = RAMP + x / cg + 0.5 * PERIOD          # full stroke has arrived
            stop = min(a.t_end, (2 * LENGTH - x - PADDLE) / cg)   # before the reflection
            m = (t >= start) & (t <= stop)
            hs = wave_heights(t[m], probes[f"g{i}"][m]) if m.sum() > 10 else np.array([])
            h = float(hs.mean()) if hs.size else float("nan")
            n_per = int((stop - start) / PERIOD)          # whole periods in the window
            mm = m & (t <= start + n_per * PERIOD)
            h1 = first_harmonic(t[mm], probes[f"g{i}"][mm]) if n_per else float("nan")
            rows.append(dict(dx=dx, h_over_dx=a.h_factor, alpha=a.alpha,
                             settings=" ".join(a.set + ([f"dt x{a.dt_factor:g}"]
                                                        if a.dt_factor != 1 else [])) or "-",
                             particles=n, gauge_m=x, window_s=f"{start:.2f}-{stop:.2f}",
                             waves=int(hs.size), H_mm=round(h * 1e3, 3),
                             H1_mm=round(h1 * 1e3, 3), rel_error_H1=round(h1 / h_th - 1, 4),
                             H_theory_mm=round(h_th * 1e3, 3),
                             rel_error=round(h / h_th - 1, 4), wall_s=round(wall, 1)))
            print(rows[-1], flush=True)
    OUT.mkdir(parents=True, exist_ok=True)
    with open(OUT / f"{name}.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(len(GAUGES), 1, figsize=(8, 2.2 * len(GAUGES)), sharex=True)
    for i, (x, ax) in enumerate(zip(GAUGES, axes)):
        for dx, (t, probes) in records.items():
            ax.plot(t, (probes[f"g{i}"] - DEPTH) * 1e3, lw=0.8, label=f"dx = {dx * 1e3:g} mm")
        for s in (1, -1):
            ax.axhline(s * h_th / 2 * 1e3, color="k", ls="--", lw=0.8)
        ax.set_ylabel(f"η at {x} m [mm]")
    axes[0].legend(fontsize=7, ncol=3)
    axes[0].set_title(f"piston wave maker, S = {STROKE * 100:g} cm, T = {PERIOD} s, h = "
                      f"{DEPTH} m: dashed ± H/2 of linear theory ({h_th * 1e3:.1f} mm)")
    axes[-1].set_xlabel("t [s]")
    fig.tight_layout()
    fig.savefig(OUT / f"{name}.png", dpi=110)


if __name__ == "__main__":
    main()
