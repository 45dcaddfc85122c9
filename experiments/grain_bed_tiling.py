"""How the pore fluid of `grain_bed_at_rest` rearranges over its 2 s, band by band: the
particles per 2.4 mm band, their kernel sum of superficial volumes
Φ_i = Σ_j V_j W(x_i − x_j, h) (fluid V_j = m_j/(ε_j ρ_j), boundary V_b = m_b/ρ_b; about 1.01
on the starting lattice), the band's mean ε0/ε (a particle's mass is ε0 ρ0 Δx², ε0 the
voidage where it started, so this is its superficial volume against the one it started
with) and the band's pressure against ρ0 g (H − y) (Σ(P − P_ref)/Σ P_ref), every 0.1 s;
and, for the 0.1 s up to each frame, the largest fluid speed against √(gH) and the median
height of the particle that had it.

    .venv/bin/python experiments/grain_bed_tiling.py [--packing hex] [--t-end 2] [--set k=v]

writes experiments/results/grain_bed_tiling_<packing>.csv (about 1.5 min on 2 cores).
``--set`` passes Physics options (``xsph=false``, ``anticlump=false``, …).
"""
from __future__ import annotations

import argparse
import json
import os
import tempfile

import h5py
import jax.numpy as jnp
import numpy as np

from _table import write_rows
from fpsi_jax import cases
from fpsi_jax.physics import kernels
from fpsi_jax.run.driver import simulate

BAND = 0.0024
EVERY = 0.1
TOP = 0.024


def frames(path):
    """(fluid x, ρ, ε, P, h) of every frame, and the constant masses and boundary."""
    with h5py.File(path) as f:
        ck = f["checkpoint"]
        const = dict(mf=ck[".fluid.mass"][()], mb=ck[".boundary.mass"][()],
                     xb=ck[".boundary.x"][()], rb=ck[".boundary.rho"][()])
        out = []
        for k in sorted(f["frames"]):
            g = f["frames"][k]
            out.append((g["fluid/x"][()], g["fluid/rho"][()], g["fluid/eps"][()],
                        g["fluid/p"][()], float(np.ravel(g["fluid/h"][()])[0])))
    return const, out


def fastest(state):
    """The largest fluid speed and the height of the particle that has it."""
    v = jnp.sqrt(jnp.sum(state.fluid.v ** 2, axis=1))
    i = jnp.argmax(v)
    return jnp.stack([v[i], state.fluid.x[i, 1]])


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--packing", default="hex")
    ap.add_argument("--t-end", type=float, default=2.0)
    ap.add_argument("--set", nargs="*", default=[], help="Physics options k=v (JSON values)")
    a = ap.parse_args()
    phys = {k: json.loads(v) for k, v in (s.split("=", 1) for s in a.set)}
    scene = cases.build("grain_bed", packing=a.packing, t_end=a.t_end)
    kw = scene.builder_kwargs
    sp = scene.params.sph
    rho0, dx, H = float(sp.rho0), kw["dx"], kw["surface"]
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "bed.h5")
        res = simulate(scene, output=path, every=EVERY, progress=False, observe=fastest,
                       **phys)
        const, frs = frames(path)
    speed = np.asarray(res.observations, float)        # (steps, 2): max |v|, its y
    per = len(speed) // (len(frs) - 1)
    windows = [None] + [speed[k * per:(k + 1) * per] for k in range(len(frs) - 1)]
    edges = np.arange(0.0, TOP + 1e-9, BAND)
    rows = []
    for n_frame, (x, rho, eps, p, h) in enumerate(frs):
        vol = const["mf"] / (eps * rho)
        X = np.concatenate([x, const["xb"]])
        V = np.concatenate([vol, const["mb"] / const["rb"]])
        r = np.linalg.norm(x[:, None] - X[None], axis=-1)
        phi = (np.asarray(kernels.wendland_w(jnp.asarray(r), h)) * V).sum(1)
        ratio = const["mf"] / (rho0 * eps * dx * dx)
        y = x[:, 1]
        ref = rho0 * 9.81 * (H - y)
        w = windows[n_frame]
        for lo, hi in zip(edges[:-1], edges[1:]):
            m = (y >= lo) & (y < hi)
            rows.append(dict(t=round(n_frame * EVERY, 3), band_mm=round(lo * 1e3, 1),
                             particles=int(m.sum()), phi_mean=round(float(phi[m].mean()), 4),
                             eps0_over_eps=round(float(ratio[m].mean()), 4),
                             pressure_err=round(float((p[m] - ref[m]).sum() / ref[m].sum()), 4),
                             fluid_max_v=None if w is None else
                             round(float(w[:, 0].max() / np.sqrt(9.81 * H)), 5),
                             fastest_y_mm=None if w is None else
                             round(float(np.median(w[:, 1]) * 1e3), 1)))
    suffix = "" if not phys else "_" + "_".join(f"{k}-{v}" for k, v in phys.items())
    out = os.path.join(os.path.dirname(__file__), "results",
                       f"grain_bed_tiling_{a.packing}{suffix}.csv")
    write_rows(out, rows)
    print("t    band  n   phi    e0/e   P err")
    for row in rows:
        if row["band_mm"] in (0.0, 2.4, 4.8, 12.0) and round(row["t"] * 10) % 5 == 0:
            print(f"{row['t']:.1f} {row['band_mm']:5.1f} {row['particles']:3d} "
                  f"{row['phi_mean']:.3f} {row['eps0_over_eps']:.3f} {row['pressure_err']*100:+.1f}%")
    print("t    fluid max |v|/sqrt(gH)  median y of the fastest")
    for row in rows:
        if row["band_mm"] == 0.0 and row["fluid_max_v"] is not None:
            print(f"{row['t']:.1f}  {row['fluid_max_v']*100:.2f} %  {row['fastest_y_mm']} mm")
    print("->", out)


if __name__ == "__main__":
    main()
