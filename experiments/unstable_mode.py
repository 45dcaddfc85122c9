"""Which mode makes a coupled run go unstable: the step's dominant eigenvalue at a state
of the run, found by power iteration with Jacobian-vector products of one step.

    fpsi run dry_bed_h_fixed.toml --out dry.h5      # stops with exit 3 at ~0.30 s

(``dry_bed_h_fixed.toml``: experiments/scenes/dry_bed.toml with ``[physics]
pore_neighbours = 0``, h fixed to the density; with the default the run completes.)
    python experiments/unstable_mode.py dry_bed_h_fixed.toml dry.h5 \\
        [--advance 30] [--iterations 40] [--mass-scale 1 4] [--dt-fraction 1 0.5]

From the file's last checkpoint (its last good frame) the script advances ``--advance``
steps, then linearises the step there: v ↦ J v over every floating-point field of the
state (positions, velocities, densities, the held fluid force on the grains, the held
accelerations, ...), each scaled by its spread, from a random start. A growth factor |λ|
above 1 is a mode the step amplifies; λ < 0 alternates sign every step. The mode's largest
parts name the fields and particles it lives in. ``--mass-scale`` multiplies the discs'
masses and inertias (the grains' inertia in the mode), ``--dt-fraction`` the step.
Writes experiments/results/unstable_mode.json.
"""
from __future__ import annotations

import argparse
import json
import os

import fpsi_jax  # noqa: F401  (XLA flags before JAX starts)
import jax
import jax.numpy as jnp
import numpy as np

from fpsi_jax import scenefile
from fpsi_jax.run import io
from fpsi_jax.run.driver import grown_like, setup
from fpsi_jax.solver import forward, init, stages

OUT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "results")


def restart(path, h5, dt_fraction, mass_scale, advance):
    """The run's state ``advance`` steps after the file's last checkpoint, with the step
    and the discs' masses scaled; (phys, params, state)."""
    sf = scenefile.load(path)
    _, params = setup(sf.scene)
    phys, params = setup(sf.scene, dt=float(params.dt) * dt_fraction)
    p = params.as_arrays(stages.dtype(phys))
    ck = io.load_checkpoint(h5)
    phys = grown_like(phys, ck.physics)
    st = io.restore(init.init_state(sf.scene, phys, p), ck)
    if mass_scale != 1.0:
        so = st.solid
        st = st.replace(solid=so.replace(mass=so.mass * mass_scale,
                                         inertia=so.inertia * mass_scale))
    step = jax.jit(lambda s: forward.step(phys, s, p))
    for _ in range(advance):
        st = step(st)
    return phys, p, st


def dominant_mode(phys, p, st, iterations, seed=0):
    """Power iteration on the step's Jacobian over the state's float fields (more than
    one value each). Returns (growth |λ| per step, sign of λ, the mode's largest parts as
    (norm share, field, particle))."""
    flat, paths = [], []
    for path, leaf in jax.tree_util.tree_flatten_with_path(st)[0]:
        flat.append(leaf)
        paths.append(jax.tree_util.keystr(path))
    leaves, tdef = jax.tree_util.tree_flatten(st)
    use = [hasattr(l, "dtype") and np.dtype(l.dtype).kind == "f" and l.size > 1
           for l in leaves]
    x0 = [l for l, u in zip(leaves, use) if u]
    names = [n for n, u in zip(paths, use) if u]
    scale = [jnp.maximum(jnp.std(l), 1e-6) for l in x0]

    def f(xs):
        it = iter(xs)
        full = [next(it) if u else l for l, u in zip(leaves, use)]
        out = jax.tree_util.tree_leaves(forward.step(phys, jax.tree_util.tree_unflatten(
            tdef, full), p))
        return [l for l, u in zip(out, use) if u]

    jvp = jax.jit(lambda t: jax.jvp(f, (x0,), (t,))[1])
    norm = lambda t: float(jnp.sqrt(sum(jnp.sum((a / s) ** 2) for a, s in zip(t, scale))))
    key = jax.random.PRNGKey(seed)
    t = [jax.random.normal(jax.random.fold_in(key, k), l.shape, l.dtype) * s
         for k, (l, s) in enumerate(zip(x0, scale))]
    n0 = norm(t)
    t = [a / n0 for a in t]
    growth, sign = 0.0, 0.0
    for _ in range(iterations):
        t2 = jvp(t)
        growth = norm(t2)
        sign = float(np.sign(sum(float(jnp.sum(a * b / s ** 2))
                                 for a, b, s in zip(t, t2, scale))))
        t = [a / growth for a in t2]
    parts = []
    for a, s, n in zip(t, scale, names):
        w = np.asarray(a / s)
        per = np.abs(w.reshape(w.shape[0], -1)).sum(-1)
        parts.append((float(np.sqrt(np.sum(w ** 2))), n, int(np.argmax(per))))
    parts.sort(reverse=True)
    return growth, sign, parts[:6]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("scene")
    ap.add_argument("h5", help="the unstable run's output (its last good frame)")
    ap.add_argument("--advance", type=int, default=30)
    ap.add_argument("--iterations", type=int, default=40)
    ap.add_argument("--mass-scale", type=float, nargs="*", default=[1.0])
    ap.add_argument("--dt-fraction", type=float, nargs="*", default=[1.0])
    a = ap.parse_args()
    rows = []
    for frac in a.dt_fraction:
        for ms in a.mass_scale:
            phys, p, st = restart(a.scene, a.h5, frac, ms, a.advance)
            growth, sign, parts = dominant_mode(phys, p, st, a.iterations)
            rows.append({"dt_fraction": frac, "mass_scale": ms,
                         "growth_per_step": growth, "sign": sign,
                         "parts": [{"share": s, "field": n, "particle": i}
                                   for s, n, i in parts]})
            print(f"dt x{frac:g}, disc masses x{ms:g}: |lambda| = {growth:.3f}, sign "
                  f"{sign:+.0f}; " + ", ".join(f"{n}[{i}] {s:.2f}" for s, n, i in parts[:4]),
                  flush=True)
    os.makedirs(OUT, exist_ok=True)
    with open(os.path.join(OUT, "unstable_mode.json"), "w") as fh:
        json.dump({"scene": a.scene, "advance": a.advance, "rows": rows}, fh, indent=1)


if __name__ == "__main__":
    main()
