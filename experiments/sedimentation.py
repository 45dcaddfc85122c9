"""Single-grain sedimentation in the Glowinski channel (W6.2.1) and what moves it.

    python experiments/sedimentation.py [--quick]

Runs the scene as built (fluid 1.5 mm → 1.538 mm fitted, h = 2d = 5 mm, cylinder drag,
added mass), at fluid spacings 2 and 1 mm, without the added mass, at W6.2.1's h = 3 mm,
and with the 'gradient' buoyancy and the 3D-mapped voidage in the fluid equations. Writes
experiments/results/sedimentation.json (errors vs Zhang 2019 FPM, settling velocity, run
time), sedimentation_y.csv (y(t) of each run) and sedimentation.png (y(t) and v(t)
against the reference).
"""
from __future__ import annotations

import argparse
import json
import os
import time

import numpy as np

from fpsi_jax.cases import overrides as ov
from fpsi_jax.cases.registry import load_csv
from fpsi_jax.cases.sedimentation import (SEDIMENTATION_REFERENCE, grain_run,
                                          sedimentation_metrics, terminal_slip)

OUT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "results")

RUNS = {   # label: (builder overrides, physics options)
    "as built: dx 1.54 mm, h 5 mm, added mass": ({}, {}),
    "dx 2 mm": ({"dx": 0.002}, {}),
    "dx 1 mm": ({"dx": 0.001}, {}),
    "no added mass": ({"added_mass": False}, {}),
    "W6.2.1's h 3 mm": ({"h0": 0.003}, {}),
    "gradient buoyancy": ({}, {"fpi_pressure": "gradient"}),
    "mapped voidage in the fluid": ({"voidage": "mapped"}, {}),
}

if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="0.3 s, seed resolution only")
    args = ap.parse_args()
    os.makedirs(OUT, exist_ok=True)
    ref = load_csv(SEDIMENTATION_REFERENCE)
    ref = ref[np.argsort(ref[:, 0])]
    runs = {k: RUNS[k] for k in list(RUNS)[:1]} if args.quick else RUNS
    records, curves = [], {}
    for label, (kw, opts) in runs.items():
        scene, phys = ov.build("sedimentation", {**kw, **opts},
                               {"t_end": 0.3} if args.quick else {})
        t0 = time.perf_counter()
        t, x, v, u, e, res = grain_run(scene, every=scene.t_end / 10, **phys)
        wall = time.perf_counter() - t0
        b = scene.builder_kwargs
        rms, v_ours, v_ref = sedimentation_metrics(t, x[:, 1], ref, b["y0"])
        eps = float(np.mean(e[(t > 0.2) & (t < 0.6)])) if t[-1] > 0.6 else float(np.mean(e))
        slip_root = terminal_slip(eps, b["rho_grain"], b["rho_fluid"], b["d"], b["mu"], 9.81,
                                  scene.options["drag"])
        hit = t[np.argmax(x[:, 1] <= b["d"] / 2 + 1e-4)] if np.any(x[:, 1] <= b["d"] / 2 + 1e-4) else None
        rec = {"run": label, "fluid_dx_mm": 1e3 * scene.params.sph.dp, "h_mm": 1e3 * b["h0"],
               "dx_over_d": scene.params.sph.dp / b["d"], "n_fluid": scene.fluid.n,
               "n_particles": scene.n_particles, "steps": res.n_steps, "dt": float(res.params.dt),
               "wall_s": wall, "particle_steps_per_s": res.particle_steps_per_s,
               "rms_y_over_fall": rms, "v_settle_ours": v_ours, "v_settle_ref": v_ref,
               "v_settle_rel_error": (v_ours - v_ref) / v_ref, "eps_p": eps,
               "terminal_slip_drag_law": slip_root,
               "mean_fluid_uy_at_grain": float(np.mean(u[(t > 0.2) & (t < 0.6), 1]))
               if t[-1] > 0.6 else None, "t_reach_floor_s": None if hit is None else float(hit),
               "options": {**kw, **opts}}
        print(json.dumps(rec))
        records.append(rec)
        curves[label] = (t, x[:, 1], v[:, 1])
    with open(os.path.join(OUT, "sedimentation.json"), "w") as fh:
        json.dump({"reference": SEDIMENTATION_REFERENCE, "runs": records}, fh, indent=1)
    tg = np.arange(0.0, max(c[0][-1] for c in curves.values()), 0.005)
    cols = [tg] + [np.interp(tg, c[0], c[1]) for c in curves.values()]
    np.savetxt(os.path.join(OUT, "sedimentation_y.csv"), np.stack(cols, 1), delimiter=",",
               header="t_s," + ",".join(f'"y_m {k}"' for k in curves), comments="",
               fmt="%.6g")
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4.2))
    a1.plot(ref[:, 0], ref[:, 1], "ko", ms=4, label="Zhang 2019 FPM (reference)")
    for k, (t, y, vy) in curves.items():
        a1.plot(t, y, label=k)
        a2.plot(t, -vy, label=k)
    a2.axhline(records[0]["v_settle_ref"], color="k", ls="--", lw=1,
               label="reference settling velocity (fit 0.2-0.6 s)")
    a1.set_xlabel("t [s]"); a1.set_ylabel("grain centre y [m]"); a1.legend(fontsize=7)
    a2.set_xlabel("t [s]"); a2.set_ylabel("settling velocity [m/s]"); a2.legend(fontsize=7)
    fig.suptitle("Sedimentation, d = 2.5 mm, rho 1250 in mu = 0.01 Pa s (W6.2.1)")
    fig.tight_layout()
    fig.savefig(os.path.join(OUT, "sedimentation.png"), dpi=110)
