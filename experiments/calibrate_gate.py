"""Calibrate the elastic gate's stiffness (E) and viscous damping against the
Antoci et al. (2007) experiment, fitting on t ≤ 0.2 s and validating on 0.2–0.36 s.

    python experiments/calibrate_gate.py                  # coarse (fluid 3.5 mm, discs 2.5 mm)
    python experiments/calibrate_gate.py --seed-check     # + the fitted values at seed resolution

Writes experiments/results/calibrate_gate.json (fit record, RMS of u_x and u_y before and
after on 0–0.2, 0.2–0.36 and 0–0.36 s, fitted E against the published 7.8–12 MPa, wall
times), calibrate_gate.png and calibrate_gate_tip.csv.
"""
from __future__ import annotations

import argparse
import json
import os
import time

import numpy as np

from calibrate import cases
from calibrate.fit import fit, plot_fit

OUT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "results")
WINDOWS = {"fit_0_0.2": (0.0, 0.2), "validation_0.2_0.36": (0.2, 0.36),
           "all_0_0.36": (0.0, 0.36)}


def rms_table(target, t, u):
    out = {}
    for name, w in WINDOWS.items():
        rx, ry = target.rms(t, u, window=w)
        out[name] = {"rms_ux_m": rx, "rms_uy_m": ry}
    return out


def save_fitted(args, case, best, E, out):
    """The fitted values, with the data and window they were fitted to, in
    calibrate/fitted/ (what a user applies: the scene keywords E and damping)."""
    from calibrate import fitted
    kw = dict(cases.GATE_COARSE) if args.resolution == "coarse" else {}
    kw.update(E=E, damping=best["dem.damping"])
    fitted.record(f"elastic_gate_{args.resolution}", {
        "scene": "elastic_gate", "scene_kwargs": kw,
        "fitted": {"stiffness_scale": best["stiffness"], "E_Pa": E,
                   "damping_per_s": best["dem.damping"]},
        "data": "fpsi_jax/data/antoci2007_gate_tip_displacement_experiment_consensus.csv "
                "(tip u_x, u_y; consensus of two digitisations of Antoci et al. 2007)",
        "window_s": [0.0, args.t_fit], "resolution": args.resolution,
        "rms_fitted": out["rms_fitted"], "rms_defaults": out["rms_defaults"],
        "by": "experiments/calibrate_gate.py"})


def main(args):
    os.makedirs(OUT, exist_ok=True)
    t0 = time.perf_counter()
    case = cases.elastic_gate(resolution=args.resolution, t_fit=args.t_fit)
    cal = case.calibration
    target = cases.gate_target(args.t_fit)
    print(json.dumps(case.meta), flush=True)
    base = cal.problem.scene.params
    default = base.replace(dem=base.dem.replace(damping=0.0))
    tb, ub, _ = cases.evaluate(case, None, args.t_end, params=default)
    before = rms_table(target, tb, ub)
    print("defaults", json.dumps(before), flush=True)
    res = fit(cal, max_steps=args.steps, rel_tol=1e-3, patience=4, jacobian=args.jacobian)
    best = {k: res.best[k] for k in res.names}
    ta, ua, run = cases.evaluate(case, best, args.t_end)
    after = rms_table(target, ta, ua)
    print("fitted", json.dumps(after), flush=True)
    E = case.meta["E"] * best["stiffness"]
    nu = case.meta["nu"]
    drop = {w: {c: 1 - after[w][c] / before[w][c] for c in ("rms_ux_m", "rms_uy_m")}
            for w in WINDOWS}
    out = {"meta": case.meta, "fit": res.to_json(), "fitted": best,
           "E_fitted_Pa": E, "E_plane_strain_fitted_Pa": E / (1 - nu ** 2) if
           case.meta["plane_strain"] else E, "E_published_range_Pa": [7.8e6, 12.0e6],
           "rms_defaults": before, "rms_fitted": after, "rms_drop": drop,
           "forward_run_s": run.wall_s, "total_wall_s": time.perf_counter() - t0}
    if args.seed_check:
        seed = cases.elastic_gate(resolution="seed", t_fit=args.t_fit)
        sb = seed.calibration.problem.scene.params
        ts, us, rs = cases.evaluate(seed, None, args.t_end,
                                    params=sb.replace(dem=sb.dem.replace(damping=0.0)))
        tf, uf, rf = cases.evaluate(seed, best, args.t_end)
        out["seed_resolution"] = {"rms_defaults": rms_table(target, ts, us),
                                  "rms_fitted_coarse_values": rms_table(target, tf, uf),
                                  "wall_s": rs.wall_s + rf.wall_s}
        extra = [("seed res., defaults", ts, us), ("seed res., fitted values", tf, uf)]
    else:
        extra = []
    name = f"calibrate_gate{'' if args.resolution == 'coarse' else '_seed'}"
    save_fitted(args, case, best, E, out)
    with open(os.path.join(OUT, name + ".json"), "w") as fh:
        json.dump(out, fh, indent=1, default=float)
    np.savetxt(os.path.join(OUT, name + "_tip.csv"),
               np.concatenate([np.stack([tb, ub[:, 0], ub[:, 1]], 1)[::20],
                               np.stack([ta, ua[:, 0], ua[:, 1]], 1)[::20]], 1),
               delimiter=",", header="t_default,ux_default,uy_default,t_fitted,ux_fitted,"
               "uy_fitted", comments="")
    # the plot shows the whole 0–0.36 s against the experiment
    plot_fit(cal, res, os.path.join(OUT, name + ".png"),
             title=f"Elastic gate: fit on t ≤ {args.t_fit} s ({args.resolution}); "
                   f"E = {E / 1e6:.2f} MPa, c = {best['dem.damping']:.3g} 1/s",
             extra_curves=[("defaults, 0–0.36 s", tb, ub), ("fitted, 0–0.36 s", ta, ua)]
             + extra)
    print(json.dumps({"E_fitted_MPa": E / 1e6, "damping": best["dem.damping"],
                      "rms_drop": drop, "wall_s": out["total_wall_s"]}, indent=1))


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--resolution", default="coarse", choices=["coarse", "seed"])
    ap.add_argument("--t-fit", type=float, default=0.2)
    ap.add_argument("--t-end", type=float, default=0.36)
    ap.add_argument("--steps", type=int, default=12)
    ap.add_argument("--seed-check", action="store_true")
    ap.add_argument("--jacobian", default="fd", choices=["ad", "fd"],
                    help="LM Jacobian: 'fd' secant (default here, see README) or 'ad'")
    main(ap.parse_args())
