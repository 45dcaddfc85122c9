"""Reverse-mode gradients through rollouts against central finite differences.

    python experiments/gradient_check.py                # cantilever (d 1.25 mm) + gate 0.05 s
    python experiments/gradient_check.py --cases gate

Cantilever: K6.3.3's strip at the seed's d = 1.25 mm, tip-loaded with viscous damping,
4000 DEM steps; loss = its tip trajectory against one with stiffness ×0.8 and damping ×2.
Gate: the coarse elastic gate (fluid 3.5 mm, discs 2.5 mm, 20 DEM sub-steps per SPH step)
over 0.05 s, loss = the tip trajectory against the one of stiffness ×0.8 and damping
×2, sampled every 1 ms. Both in float64. For each fitted quantity (stiffness scale and
viscous damping, in the optimiser's z): the gradient by reverse mode through the
checkpointed rollout, and (L(z + h) − L(z − h))/2h for h = 1e-3, 1e-4, 1e-5. Writes
experiments/results/gradient_check.json.
"""
from __future__ import annotations

import argparse
import json
import os
import time

import jax

jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

from calibrate import cases, space as sp  # noqa: E402
from calibrate.fit import Calibration  # noqa: E402
from calibrate.rollout import prepare  # noqa: E402
from calibrate.targets import StaticDeflection, Trajectory  # noqa: E402
from fpsi_jax.cases import build  # noqa: E402

OUT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "results")
STEPS_H = (1e-3, 1e-4, 1e-5)


def cantilever_problem(n_steps=4000, d=0.00125):
    scene = build("cantilever", variant="tip", alpha=0.0, damping=20.0, d=d)
    return prepare(scene, n_steps * 2.0e-6, cases.tracker(scene, cases.cantilever_tip(scene)),
                   dt=2.0e-6)


def gate_problem(t_end=0.05):
    scene = build("elastic_gate", damping=5.0, **cases.GATE_COARSE)
    from fpsi_jax.cases.elastic_gate import gate_tip
    space0 = sp.ParamSpace(scene.params, [sp.stiffness(0.25, 4.0)])
    return prepare(scene, t_end, cases.tracker(scene, gate_tip(scene)),
                   stiffest=space0.extreme("hi"), x64=True)


def calibration(pr, every):
    space = sp.ParamSpace(pr.params, [sp.stiffness(0.25, 4.0),
                                      sp.param("dem.damping", 0.1, 1000.0)])
    probe = Calibration(pr, space, [StaticDeflection(value=1.0)])
    zref = space.z_of({"stiffness": 0.8, "dem.damping": 2 * space.start["dem.damping"]})
    u = probe.observe(zref)
    k = np.arange(every - 1, pr.n_steps, every)
    ref = Trajectory(t_ref=tuple(pr.times[k]), values=tuple(map(tuple, u[k])),
                     components=(0, 1))
    return Calibration(pr, space, [ref])


def check(name, pr, every):
    cal = calibration(pr, every)
    z = jnp.asarray(cal.space.z0, jnp.float64)
    t0 = time.perf_counter()
    (loss, _), g = cal.value_and_grad(z)
    t_grad = time.perf_counter() - t0
    rec = {"case": name, "n_steps": pr.n_steps, "dt": pr.dt, "loss": float(loss),
           "grad_s_with_compile": t_grad, "params": {}}
    if pr.phys.has_fluid:
        rec["dem_substeps"] = pr.phys.dem_substeps
    for k, pname in enumerate(cal.space.names):
        row = {"reverse_mode": float(g[k]), "fd": {}}
        for h in STEPS_H:
            e = jnp.zeros_like(z).at[k].set(h)
            fd = (float(cal.value(z + e)[0]) - float(cal.value(z - e)[0])) / (2 * h)
            row["fd"][str(h)] = {"value": fd, "rel_diff": float(g[k]) / fd - 1.0}
        rec["params"][pname] = row
        print(name, pname, json.dumps(row), flush=True)
    rec["max_abs_rel_diff_h1e-4"] = max(abs(r["fd"]["0.0001"]["rel_diff"])
                                        for r in rec["params"].values())
    rec["wall_s"] = time.perf_counter() - t0
    return rec


def main(args):
    os.makedirs(OUT, exist_ok=True)
    path = os.path.join(OUT, "gradient_check.json")
    res = json.load(open(path)) if os.path.exists(path) else {}
    if "cantilever" in args.cases:
        res["cantilever"] = check("cantilever", cantilever_problem(), 100)
    if "gate" in args.cases:
        pr = gate_problem(args.gate_t)
        res["gate"] = check("gate", pr, max(1, int(round(1e-3 / pr.dt))))
    with open(path, "w") as fh:
        json.dump(res, fh, indent=1)
    print(json.dumps({k: v["max_abs_rel_diff_h1e-4"] for k, v in res.items()}))


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--cases", nargs="*", default=["cantilever", "gate"])
    ap.add_argument("--gate-t", type=float, default=0.05)
    main(ap.parse_args())
