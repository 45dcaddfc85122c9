"""Where the unfloored sediment flush goes unstable: restart from its last good frame with
one setting changed at a time.

    fpsi run unfloored.toml --out results/flush.h5       # stops with exit 3 at ~0.48 s
    python experiments/flushing_instability.py unfloored.toml results/flush.h5

``unfloored.toml`` is examples/sediment_flushing.toml with ``voidage = "area"``,
``fpi_pressure = "shared"``, no ``eps_floor`` and ``pore_neighbours = 0`` (h fixed to the
density; with the default 0.5 the flush runs its 0.6 s). Each variant restarts from the file's last
checkpoint and runs ``--steps`` steps (of its own step; ``dt_fraction`` scales it) and
reports whether it stays finite; writes experiments/results/flushing_instability.json.
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import os

import fpsi_jax  # noqa: F401  (XLA flags before JAX starts)
import jax
import numpy as np

from fpsi_jax import scenefile
from fpsi_jax.run import io
from fpsi_jax.run.driver import grown_like, setup
from fpsi_jax.solver import forward, init, stages

OUT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "results")
VARIANTS = [("as run", 1.0, {}), ("0.9 of the step", 0.9, {}), ("0.75 of the step", 0.75, {}),
            ("no wall images", 1.0, {"wall_images": False}),
            ("no delta-SPH", 1.0, {"delta_sph": False}),
            ("no lubrication", 1.0, {"lubrication": False}),
            ("no XSPH", 1.0, {"xsph": False}),
            ("no artificial viscosity", 1.0, {"artificial_viscosity": False}),
            ("no anti-clump", 1.0, {"anticlump": False}),
            ("no anti-clump at walls", 1.0, {"anticlump_boundary": False}),
            ("continuity at v", 1.0, {"transport_continuity": False}),
            ("fixed h", 1.0, {"variable_h": False})]


def run(path, h5, frac, switches, steps):
    sf = scenefile.load(path)
    _, params = setup(sf.scene)
    phys, params = setup(sf.scene, dt=float(params.dt) * frac)
    phys = dataclasses.replace(phys, **switches)
    p = params.as_arrays(stages.dtype(phys))
    ck = io.load_checkpoint(h5)
    phys = grown_like(phys, ck.physics)
    st = io.restore(init.init_state(sf.scene, phys, p), ck)
    t0 = float(ck.leaves.get(".t", np.nan)) if hasattr(ck, "leaves") else float("nan")
    chunk = jax.jit(lambda s: jax.lax.fori_loop(0, 20, lambda i, c: forward.step(phys, c, p), s))
    for k in range(steps // 20):
        st = chunk(st)
        if bool(st.status.bad):
            return {"finite": False, "steps_before_failure": 20 * (k + 1), "start_t": t0}
    rho = np.asarray(st.fluid.rho) / float(sf.scene.params.sph.rho0) - 1.0
    return {"finite": True, "steps": steps, "start_t": t0,
            "max_density_error": float(np.abs(rho).max())}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("scene")
    ap.add_argument("h5")
    ap.add_argument("--steps", type=int, default=400)
    a = ap.parse_args()
    rows = {}
    for name, frac, sw in VARIANTS:
        rows[name] = run(a.scene, a.h5, frac, sw, a.steps)
        print(name, rows[name], flush=True)
    os.makedirs(OUT, exist_ok=True)
    with open(os.path.join(OUT, "flushing_instability.json"), "w") as fh:
        json.dump(rows, fh, indent=1)


if __name__ == "__main__":
    main()
