"""``fpsi calibrate <case> [--steps N] [--optimizer lm|adam|sgd] [--lr LR] [--fit SPEC ...]
[--set key=value ...] [--out DIR]``: fit a ready-made case (calibrate.cases) and write
<out>/<case>.json (parameters before/after, loss history, standard errors, wall time) and
<out>/<case>.png (loss history and the fit)."""
from __future__ import annotations

import inspect
import json
import os

from fpsi_jax.cases import overrides as ov
from fpsi_jax.model.errors import ParameterError

from . import cases
from .fit import OPTIMIZERS, fit, plot_fit


def add_parser(sub):
    c = sub.add_parser("calibrate", help="fit parameters of a calibration case")
    c.add_argument("case", help=f"one of: {', '.join(cases.CASES)}")
    c.add_argument("--steps", type=int, default=30, help="optimiser steps (max)")
    c.add_argument("--optimizer", default="lm", choices=OPTIMIZERS)
    c.add_argument("--lr", type=float, default=0.1, help="learning rate (adam/sgd), z units")
    c.add_argument("--noise", type=float, default=None,
                   help="assumed residual error for the standard errors")
    c.add_argument("--set", action="append", metavar="KEY=VALUE",
                   help="a keyword of the case builder (e.g. zeta=0.05, d=0.0025)")
    c.add_argument("--out", default="results/calibrate", help="output folder")
    c.add_argument("--quiet", action="store_true")
    return c


def run(args) -> int:
    builder = cases.get(args.case)
    kw = ov.parse_pairs(args.set)
    sig = inspect.signature(builder).parameters
    allowed = [n for n, q in sig.items() if q.kind == q.KEYWORD_ONLY]
    if any(q.kind == q.VAR_KEYWORD for q in sig.values()):      # the rest go to the scene
        from fpsi_jax.cases import builder_keys
        allowed += [k for k in builder_keys(cases.SCENE_OF[args.case])
                    if k not in allowed and k not in ("damping", "t_end", "variant")]
    bad = [k for k in kw if k not in allowed]
    if bad:
        raise ParameterError(f"unknown key {bad[0]!r} for calibration case {args.case!r}; "
                             f"allowed: {', '.join(allowed)}")
    if args.steps < 1:
        raise ParameterError(f"--steps = {args.steps} out of range; allowed [1, inf)")
    case = builder(**kw)
    res = fit(case.calibration, optimizer=args.optimizer, learning_rate=args.lr,
              max_steps=args.steps, noise=args.noise, progress=not args.quiet,
              loss_tol=1e-12)
    res.extra.update(meta=case.meta, truth=case.truth, builder_kwargs=kw)
    os.makedirs(args.out, exist_ok=True)
    js = os.path.join(args.out, f"{args.case}.json")
    png = os.path.join(args.out, f"{args.case}.png")
    res.save(js)
    plot_fit(case.calibration, res, png, title=f"{args.case}: {res.best}")
    print(json.dumps({"start": {k: res.start[k] for k in res.names},
                      "fitted": {k: res.best[k] for k in res.names},
                      "loss": [res.loss_start, res.loss_best], "steps": res.steps,
                      "stopped": res.stopped, "wall_s": round(res.wall_s, 1)}, indent=1))
    print(f"wrote {js} and {png}")
    return 0


def list_cases():
    """``fpsi list``: the ready-made calibration cases."""
    print("calibration cases:")
    for name, fn in cases.CASES.items():
        doc = (fn.__doc__ or "").strip().splitlines()[0]
        print(f"  {name:20s} {doc}")
