"""A standing wave in a closed tank: how much of its height the SPH fluid keeps, and its
period against linear theory, for kernel widths and artificial viscosities.

Water h = 0.1 m deep in a tank one wavelength long (L = 0.709 m, kh = 0.886) starts at
rest with its surface at h + a cos(kx), a = 5 mm; linear theory: period T = 2π/√(gk tanh
kh) = 0.800 s, and the height stays (the physical damping of this wave is below 1 % a
period). Gauges at the side wall and at mid-tank (both antinodes) give the amplitude over
each period and the mean period from the wall gauge's up-crossings.

    python experiments/standing_wave.py [--dx 0.005] [--variants 1.25:0.02 2:0.02 2:0]

Writes experiments/results/standing_wave.csv (h/dx, α, amplitude in each of the five
periods at both gauges, period).
"""
from __future__ import annotations

import argparse
import csv
import math
import pathlib
import sys
import tempfile

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
OUT = ROOT / "experiments" / "results"
sys.path.insert(0, str(ROOT))

DEPTH, AMP, T_END = 0.1, 0.005, 4.0
LENGTH = 0.70898                     # one wavelength of T = 0.8 s in 0.1 m of water


def scene_text(dx, h_factor, alpha):
    k = 2 * math.pi / LENGTH
    top = [(LENGTH - i * LENGTH / 60, DEPTH + AMP * math.cos(k * (LENGTH - i * LENGTH / 60)))
           for i in range(61)]
    poly = ", ".join(f"[{x:.5f}, {y:.5f}]" for x, y in [(0.0, 0.0), (LENGTH, 0.0)] + top)
    return f"""
[scene]
t_end = {T_END}
headroom = 1.0
[fluid]
dx = {dx}
h = {h_factor * dx}
alpha = {alpha}
[[fluid.region]]
polygon = [{poly}]
surface = {DEPTH}
[tank]
width = {LENGTH}
height = 0.2
[[probe]]
name = "wall"
kind = "water_level"
x = {dx}
[[probe]]
name = "mid"
kind = "water_level"
x = {LENGTH / 2}
"""


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dx", type=float, default=0.005)
    ap.add_argument("--variants", nargs="+", default=["1.25:0.02", "1.5:0.02", "2:0.02", "2:0"],
                    help="h/dx:alpha pairs")
    a = ap.parse_args()
    from fpsi_jax import scenefile
    from fpsi_jax.run.driver import simulate
    k = 2 * math.pi / LENGTH
    period = 2 * math.pi / math.sqrt(9.81 * k * math.tanh(k * DEPTH))
    rows = []
    for v in a.variants:
        hf, alpha = (float(x) for x in v.split(":"))
        with tempfile.TemporaryDirectory() as tmp:
            path = pathlib.Path(tmp) / "tank.toml"
            path.write_text(scene_text(a.dx, hf, alpha))
            sf = scenefile.load(str(path))
            res = simulate(sf.scene, probes=sf.probes, progress=False, every=0.02)
        t = np.asarray(res.times)
        wall = np.asarray(res.probes["wall"]).ravel() - DEPTH
        mid = np.asarray(res.probes["mid"]).ravel() - DEPTH
        amps = []
        for i in range(int(T_END / period)):
            m = (t >= i * period) & (t < (i + 1) * period)
            amps.append((round(float(np.ptp(wall[m])) / 2 * 1e3, 2),
                         round(float(np.ptp(mid[m])) / 2 * 1e3, 2)))
        up = t[1:][(wall[:-1] < 0) & (wall[1:] >= 0)]
        row = dict(dx=a.dx, h_over_dx=hf, alpha=alpha,
                   amplitude_mm_wall_mid_per_period=" ".join(f"{w}/{m}" for w, m in amps),
                   kept_after_4_periods=round(0.5 * (amps[-1][0] + amps[-1][1])
                                              / (1e3 * AMP), 3),
                   period_s=round(float(np.diff(up).mean()), 4) if len(up) > 1 else None,
                   period_theory_s=round(period, 4))
        rows.append(row)
        print(row, flush=True)
    OUT.mkdir(parents=True, exist_ok=True)
    with open(OUT / "standing_wave.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)


if __name__ == "__main__":
    main()
