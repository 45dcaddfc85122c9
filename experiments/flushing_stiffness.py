"""The pore fluid's local acoustic stiffness over a sediment flush, with and without the
grains' wall images (docs/physics.md, Packed beds: what grows where the unfloored flush
goes unstable with the images).

    fpsi run unfloored.toml --out flush.h5                  # stops with exit 3 at ~0.48 s
                                       # (the example with [physics] pore_neighbours = 0)
    fpsi run unfloored_noimg.toml --out flush_noimg.h5      # the same, wall_images = false
    python experiments/flushing_stiffness.py unfloored.toml flush.h5 flush_noimg.h5 \
        [flush_dt09.h5 --labels "wall images" "no wall images" "wall images, 0.9 of the step"]

For every frame and fluid particle i it evaluates the volume-sum gradient

    G_i = |Σ_j V_j ∇_i W_ij|,   V_j = m_j/(ε_j ρ_j) (fluid), m_b/ρ_b (boundary),

in units of Σ_j V_j |∇_i W_ij| on the scene's clear-water lattice (Δx, h0). In the
symmetric pressure force −(1/ρ_i) Σ_j V_j (P_i + P_j) ∇_iW_ij and its adjoint continuity
(ρ_i Σ_j V_j u_i·∇_iW_ij) the particle's own pressure and its own velocity meet through
this one vector, so a particle displaced along it oscillates at ω ≥ c0 |Σ_j V_j ∇_iW_ij|
(its neighbours' pressure responses add to it): zero in a uniform lattice (G ≈ 0.003 in
the clear water); it is the gradient of the volume sum Σ_j V_j W_ij, which uneven
superficial volumes or crowded particles make. Writes experiments/results/flushing_stiffness.{csv,png}:
per frame the largest G, which particle, its ε0 (mass / ρ0Δx²) and ε.
"""
from __future__ import annotations

import argparse
import csv
import os

import fpsi_jax  # noqa: F401  (XLA flags before JAX starts)
import h5py
import jax
import jax.numpy as jnp
import numpy as np

from fpsi_jax import scenefile
from fpsi_jax.physics import kernels
from fpsi_jax.run.driver import setup

OUT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "results")


def lattice_sum(kern, dx, h):
    """Σ_j Δx² |∇W(r_ij, h)| over a square lattice of spacing dx about one particle."""
    n = int(np.ceil(2.0 * h / dx)) + 1
    g = np.arange(-n, n + 1) * dx
    r = np.hypot(*np.meshgrid(g, g)).ravel()
    r = r[(r > 0) & (r < 2.0 * h)]
    return float(np.sum(dx * dx * np.abs(np.asarray(kern.dw_dr(jnp.asarray(r), h)))))


def volume_gradient(kern):
    """A jitted (x, h, columns' positions and volumes) -> |Σ_j V_j ∇_iW_ij| for every
    fluid row i over all columns j (brute force, (rows, columns) arrays: scenes of a few
    thousand particles; the kernel the step uses)."""
    @jax.jit
    def g(x, hf, xs, vs):
        r = x[:, None, :] - xs[None, :, :]
        d = jnp.sqrt(jnp.sum(r * r, axis=-1))
        inside = (d > 0) & (d < kernels.SUPPORT * hf[:, None])
        dw = jnp.where(inside, kern.dw_dr(d, hf[:, None]), 0.0)
        e = r / jnp.where(inside, d, 1.0)[..., None]
        return jnp.linalg.norm(jnp.sum((vs[None, :] * dw)[..., None] * e, axis=1), axis=-1)
    return g


def series(path, g_fn, ref, rho0, dx):
    rows = []
    with h5py.File(path, "r") as f:
        ck = f["checkpoint"]
        m = ck[".fluid.mass"][()]
        xb, vb = ck[".boundary.x"][()], ck[".boundary.mass"][()] / ck[".boundary.rho"][()]
        times = f["time"][()]
        for k, name in enumerate(sorted(f["frames"].keys())):
            fr = f["frames"][name]["fluid"]
            x, eps, rho, h = fr["x"][()], fr["eps"][()], fr["rho"][()], fr["h"][()]
            vol = m / (eps * rho)
            g = np.asarray(g_fn(jnp.asarray(x), jnp.asarray(h),
                                jnp.asarray(np.concatenate([x, xb])),
                                jnp.asarray(np.concatenate([vol, vb])))) / ref
            i = int(np.argmax(g))
            rows.append({"t_s": float(times[k]), "max_G": float(g[i]), "particle": i,
                         "eps0": float(m[i] / (rho0 * dx * dx)), "eps": float(eps[i]),
                         "y_m": float(x[i, 1]), "n_G_above_1_5": int(np.sum(g > 1.5))})
    return rows


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("scene")
    ap.add_argument("h5", nargs="+", help="runs of the scene (the first with the images)")
    ap.add_argument("--labels", nargs="+", default=["wall images", "no wall images"])
    a = ap.parse_args()
    sf = scenefile.load(a.scene)
    phys, params = setup(sf.scene)
    kern = kernels.get(phys.kernel)
    dx, h0 = float(params.sph.dp), float(np.min(sf.scene.fluid.h))
    rho0 = float(params.sph.rho0)
    ref = lattice_sum(kern, dx, h0)
    os.makedirs(OUT, exist_ok=True)
    out = []
    for path, label in zip(a.h5, a.labels):
        for r in series(path, volume_gradient(kern), ref, rho0, dx):
            out.append({"run": label, **r})
        last = [r for r in out if r["run"] == label]
        print(label, f"frames {len(last)}, to t = {last[-1]['t_s']:.3f} s,",
              f"largest G {max(r['max_G'] for r in last):.2f}", flush=True)
    with open(os.path.join(OUT, "flushing_stiffness.csv"), "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(out[0]))
        w.writeheader()
        w.writerows(out)
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6, 3.5))
    for label in a.labels[:len(a.h5)]:
        rr = [r for r in out if r["run"] == label]
        ax.plot([r["t_s"] for r in rr], [r["max_G"] for r in rr], label=label)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("max_i |Σ V_j ∇W_ij| / clear water Σ V|∇W|")
    ax.legend()
    fig.tight_layout()
    fig.savefig(os.path.join(OUT, "flushing_stiffness.png"), dpi=120)


if __name__ == "__main__":
    main()
