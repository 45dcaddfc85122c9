"""Elastic gate (Antoci et al. 2007) at the seed's resolution, every coupling method, and the
multi-rate check.

    python experiments/elastic_gate.py                 # all four couplings, seed resolution
    python experiments/elastic_gate.py --multirate     # sub-stepped vs single-rate run
    python experiments/elastic_gate.py --set alpha=0.157   # K's local damping

Writes experiments/results/elastic_gate.json (peak ux, its time, RMS of ux and uy over
0–0.36 s against the experiment, run time, steps, sub-steps, particle counts, per method),
elastic_gate_methods.png, and for --multirate elastic_gate_multirate[_coarse].json.
"""
from __future__ import annotations

import argparse
import json
import os
import time

import numpy as np

from fpsi_jax.cases import overrides as ov
from fpsi_jax.cases.elastic_gate import GATE_COARSE as COARSE
from fpsi_jax.cases.elastic_gate import gate_metrics, plot_gate, tip_displacement, tip_observer
from fpsi_jax.model.errors import SimulationError
from fpsi_jax.model.options import FsiMethod
from fpsi_jax.run.driver import simulate

OUT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "results")


def run(kw, t_end=None, **phys):
    scene, opts = ov.build("elastic_gate", kw)
    opts.update(phys)
    t0 = time.perf_counter()
    try:
        res = simulate(scene, t_end=t_end, progress=False, observe=tip_observer(scene),
                       every=0.02, **opts)
    except SimulationError as e:
        return scene, None, {"error": str(e), "wall_s": time.perf_counter() - t0}
    wall = time.perf_counter() - t0
    t, ux, uy = tip_displacement(scene, res)
    info = {"wall_s": wall, "sph_steps": res.n_steps, "dem_substeps": res.physics.dem_substeps,
            "dem_steps": res.n_steps * res.physics.dem_substeps, "dt_s": float(res.params.dt),
            "n_fluid": scene.fluid.n, "n_boundary": scene.boundary.n, "n_discs": scene.solid.n,
            "n_bonds": scene.bonds.n, "particle_steps_per_s": res.particle_steps_per_s,
            "compile_s": res.compile_s}
    return scene, (t, ux, uy), info


def methods(args):
    rows, curves = {}, []
    for m in args.methods:
        scene, tu, info = run({"coupling": m, **(COARSE if args.coarse else {}),
                               **ov.parse_pairs(args.set)})
        if tu is not None:
            info.update(gate_metrics(*tu))
            curves.append((f"fpsi-jax, {m}", *tu))
            np.savetxt(os.path.join(OUT, f"elastic_gate_tip_{m}.csv"),
                       np.stack(tu, axis=1)[::10], delimiter=",", header="t_s,ux_m,uy_m",
                       comments="")
        rows[m] = info
        print(m, json.dumps({k: (round(v, 5) if isinstance(v, float) else v)
                             for k, v in info.items()}), flush=True)
    meta = {"resolution": "coarse" if args.coarse else "seed (dx 1.75 mm, d 1.25 mm)",
            "scene_defaults": {k: v for k, v in scene.builder_kwargs.items() if k != "tip"}}
    name = "elastic_gate_coarse" if args.coarse else "elastic_gate"
    if args.set:
        name += "_" + "_".join(x.replace("=", "") for x in args.set)
    with open(os.path.join(OUT, f"{name}.json"), "w") as fh:
        json.dump({"methods": rows, **meta}, fh, indent=1, default=float)
    plot_gate(curves, os.path.join(OUT, f"{name}_methods.png"),
              "Elastic gate, coupling methods (defaults, uncalibrated)")


def multirate(args):
    kw = {**(COARSE if args.coarse else {}), **ov.parse_pairs(args.set)}
    t_end = args.t_end
    out = {}
    for label, phys in (("multi_rate", {}), ("single_rate", {"dem_substeps": 1})):
        _, tu, info = run(kw, t_end=t_end, **phys)
        t, ux, uy = tu
        k = int(np.argmax(ux))
        info.update(peak_ux_m=float(ux[k]), t_peak_s=float(t[k]))
        out[label] = info
        print(label, info, flush=True)
    m, s = out["multi_rate"], out["single_rate"]
    out["peak_ux_rel_difference"] = m["peak_ux_m"] / s["peak_ux_m"] - 1.0
    out["speed_up"] = s["wall_s"] / m["wall_s"]
    out["resolution"] = "coarse (dx 3.5 mm, d 2.5 mm)" if args.coarse else "seed"
    out["t_end_s"] = t_end
    print(json.dumps({k: out[k] for k in ("peak_ux_rel_difference", "speed_up")}))
    name = "elastic_gate_multirate" + ("_coarse" if args.coarse else "")
    with open(os.path.join(OUT, f"{name}.json"), "w") as fh:
        json.dump(out, fh, indent=1, default=float)


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--methods", nargs="*", default=[m.value for m in FsiMethod])
    ap.add_argument("--multirate", action="store_true")
    ap.add_argument("--coarse", action="store_true")
    ap.add_argument("--t-end", type=float, default=0.4)
    ap.add_argument("--set", action="append", default=[], help="scene keyword, e.g. alpha=0.157")
    args = ap.parse_args()
    os.makedirs(OUT, exist_ok=True)
    multirate(args) if args.multirate else methods(args)
