"""The cantilever calibrations.

    python experiments/calibrate_cantilever.py                    # all three + landscape
    python experiments/calibrate_cantilever.py --only synthetic --adam   # + the Adam loop

* synthetic  K6.3.3's strip (discs 2.5 mm, the full 79.375 mm length), free vibration
             over 2.25 periods; the truth has stiffness scale 1 and damping c = 4 1/s; the
             fit starts at stiffness ×2 and damping ×3 and must recover both within 1 % in
             ≤ 100 steps (Levenberg–Marquardt; --adam also runs optax Adam for comparison)
* static     the strip at the seed's d = 1.25 mm, 1 N at the tip: stiffness so the static
             tip deflection is 1.6 mm (PL³/3EI) within 0.5 %
* damping    the strip at d = 1.25 mm, free vibration: c so the first mode decays with a
             damping ratio of 5 % within 5 %; compared with the analytic c = 4π f1 ζ
* landscape  16 stiffness and 16 damping values around the synthetic optimum, each set in
             one compiled call (batch.landscape: the sets in sequence inside it)
Writes experiments/results/calibrate_cantilever.json and calibrate_cantilever_*.png.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import time

import jax

jax.config.update("jax_enable_x64", True)

import numpy as np  # noqa: E402

from calibrate import batch, cases  # noqa: E402
from calibrate.fit import fit, plot_fit  # noqa: E402

OUT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "results")


def synthetic(adam=False):
    t0 = time.perf_counter()
    case = cases.cantilever_synthetic()
    setup_s = time.perf_counter() - t0
    cal = case.calibration
    res = fit(cal, max_steps=100, loss_tol=1e-14, noise=0.01)
    plot_fit(cal, res, os.path.join(OUT, "calibrate_cantilever_synthetic.png"),
             title="Cantilever, synthetic truth: stiffness ×2, damping ×3 → recovered")
    out = {"meta": case.meta, "truth": case.truth, "setup_s": setup_s, "fit": res.to_json(),
           "rel_error": {k: res.best[k] / case.truth[k] - 1 for k in case.truth}}
    # loss landscape: 16 values of each quantity in one compiled call
    curves = {}
    for name, lo, hi in (("stiffness", 0.8, 1.25), ("dem.damping", 2.0, 8.0)):
        t1 = time.perf_counter()
        v, l, used = batch.landscape(cal, res.z_best, name, np.geomspace(lo, hi, 16))
        curves[name] = (v, l, res.best[name])
        out.setdefault("landscape", {})[name] = {"values": v.tolist(), "loss": l.tolist(),
                                                 "wall_s": time.perf_counter() - t1,
                                                 "devices": used}
    batch.plot_landscape(curves, os.path.join(OUT, "calibrate_cantilever_landscape.png"),
                         "Synthetic cantilever: loss around the optimum (16 sets per call)")
    if adam:
        ra = fit(cal, optimizer="adam", learning_rate=0.1, max_steps=100, loss_tol=1e-14,
                 patience=100, noise=0.01)
        out["adam"] = {"fit": ra.to_json(),
                       "rel_error": {k: ra.best[k] / case.truth[k] - 1 for k in case.truth}}
    return out


def static():
    case = cases.cantilever_static()
    cal = case.calibration
    res = fit(cal, max_steps=30, loss_tol=1e-10, noise=1e-3)
    plot_fit(cal, res, os.path.join(OUT, "calibrate_cantilever_static.png"),
             title="Cantilever, static tip deflection → 1.6 mm (PL³/3EI)")
    rep = cal.targets[0].report(cal.problem.times, cal.observe(res.z_best))
    rep0 = cal.targets[0].report(cal.problem.times, cal.observe(res.z_start))
    return {"meta": case.meta, "fit": res.to_json(), "before": rep0, "after": rep,
            "E_fitted_Pa": case.meta["E"] * res.best["stiffness"]}


def damping():
    case = cases.cantilever_damping()
    cal = case.calibration
    res = fit(cal, max_steps=30, loss_tol=1e-10, noise=0.01)
    plot_fit(cal, res, os.path.join(OUT, "calibrate_cantilever_damping.png"),
             title="Cantilever, free vibration: damping ratio → 5 %")
    tg = cal.targets[0]
    rep = tg.report(cal.problem.times, cal.observe(res.z_best))
    c_analytic = 4 * math.pi * rep["frequency_hz"] * tg.damping_ratio
    return {"meta": case.meta, "fit": res.to_json(), "after": rep,
            "c_fitted": res.best["dem.damping"], "c_analytic_4pi_f1_zeta": c_analytic,
            "c_rel_diff": res.best["dem.damping"] / c_analytic - 1}


def main(args):
    os.makedirs(OUT, exist_ok=True)
    path = os.path.join(OUT, "calibrate_cantilever.json")
    res = json.load(open(path)) if os.path.exists(path) else {}
    for name in args.only:
        t0 = time.perf_counter()
        res[name] = {"synthetic": lambda: synthetic(args.adam), "static": static,
                     "damping": damping}[name]()
        res[name]["total_wall_s"] = time.perf_counter() - t0
        with open(path, "w") as fh:
            json.dump(res, fh, indent=1, default=float)
        print(name, json.dumps({k: v for k, v in res[name].items()
                                if k in ("rel_error", "after", "E_fitted_Pa", "c_rel_diff",
                                         "total_wall_s")}, default=float), flush=True)


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--only", nargs="*", default=["synthetic", "static", "damping"])
    ap.add_argument("--adam", action="store_true")
    main(ap.parse_args())
