"""``fpsi calibrate``: fit parameters of a scene file against measured data, or of a
ready-made case.

    fpsi calibrate my_case.toml --data measured.csv --fit E,damping [--probe tip]
                  [--window 0,0.2] [--holdout 0.2,0.36] [--target trajectory|static|vibration]
                  [--start damping=0.5] [--steps N] [--optimizer lm|adam|sgd]
                  [--jacobian ad|fd] [--noise S] [--set key=value] [--out DIR]
    fpsi calibrate <case> [--steps N] [--optimizer ...] [--set key=value ...] [--out DIR]

A scene file's ``[calibration]`` table gives defaults for every flag of the first form
(a flag wins); what can be fitted, the data format and the targets:
:mod:`calibrate.usercase`. Writes <out>/<name>.json (start, fitted values, standard
errors, loss history, RMS per component on the fitted and held-out windows before and
after, wall times) and <out>/<name>.png (measured against simulated, and the loss).
Every check runs before anything is compiled: a bad file, flag or data file is one line
on stderr, exit code 2, nothing written.

The ready-made cases (calibrate.cases) write <out>/<case>.json and <out>/<case>.png.
"""
from __future__ import annotations

import inspect
import json
import os
import shlex
import sys

from fpsi_jax.cases import overrides as ov
from fpsi_jax.cli import set_pairs
from fpsi_jax.model.errors import ParameterError, SimulationError, fmt, number

from . import cases
from .fit import OPTIMIZERS, fit, plot_fit

#: stopping rule of a scene-file fit: every step is a full rollout, so four steps that
#: do not lower the best loss by 0.1 % end it
REL_TOL, PATIENCE, LOSS_TOL = 1e-3, 4, 1e-12


def add_parser(sub):
    c = sub.add_parser("calibrate", help="fit parameters of a scene file to data, or of a "
                       "ready-made calibration case")
    c.add_argument("case", help="a scene file (my_case.toml) or one of: "
                   f"{', '.join(cases.CASES)}")
    c.add_argument("--data", default=None, help="measured CSV: 't [s]' then probe "
                   "components with units ('tip.ux [mm]')")
    c.add_argument("--fit", action="append", default=None, metavar="NAME[:LO:HI],...",
                   help="what to fit: a Params leaf (dem.damping, damping), <structure>.E, "
                   "<structure>.sigma_c, <structure>.tau_c (E, sigma_c, tau_c with one "
                   "structure), stiffness; comma list or repeated")
    c.add_argument("--probe", default=None, help="the probe the data measures (default: "
                   "the file's only one)")
    c.add_argument("--window", default=None, metavar="A,B", help="fitted time window [s] "
                   "(default: the data's span)")
    c.add_argument("--holdout", default=None, metavar="A,B",
                   help="held-out window [s]: reported, not fitted")
    c.add_argument("--target", default=None, choices=("trajectory", "static", "vibration"))
    c.add_argument("--start", action="append", default=None, metavar="NAME=VALUE",
                   help="start value of a fitted quantity (SI units)")
    c.add_argument("--steps", type=int, default=None, help="optimiser steps (max; "
                   "default 30)")
    c.add_argument("--optimizer", default=None, choices=OPTIMIZERS)
    c.add_argument("--jacobian", default=None, choices=("ad", "fd"),
                   help="LM Jacobian: 'ad' forward mode, 'fd' secant (chaotic coupled runs)")
    c.add_argument("--lr", type=float, default=0.1, help="learning rate (adam/sgd), z units")
    c.add_argument("--noise", type=float, default=None,
                   help="assumed residual error for the standard errors (needed when there "
                        "are no more residuals than parameters)")
    c.add_argument("--set", action="append", metavar="KEY=VALUE",
                   help="scene file: a Params leaf or Physics option; case: a keyword of the "
                        "case builder (e.g. zeta=0.05, d=0.0025)")
    c.add_argument("--out", default="results/calibrate", help="output folder")
    c.add_argument("--quiet", action="store_true")
    return c


def check_args(args) -> None:
    """The numeric flags and the output folder, checked before anything is read or built."""
    from fpsi_jax.run import io
    number("--lr", args.lr, 0.0, None, lo_open=True)
    if args.noise is not None:
        number("--noise", args.noise, 0.0, None, lo_open=True)
    if args.steps is not None and args.steps < 1:
        raise ParameterError(f"--steps = {args.steps} out of range; allowed [1, inf)")
    io.check_output(args.out, kind="folder")


#: ranges (lo, hi, lo_open, hi_open) of the ready-made cases' numeric keywords (others:
#: (0, inf))
CASE_RANGES = {"damping": (0.0, None, False, False), "zeta": (0.0, 1.0, True, True)}


def check_case_kwargs(name: str, builder, kw: dict) -> dict:
    """A ready-made case's own keywords checked by the kind of their default (numbers
    finite and in range, bounds two numbers 0 < lo < hi, ``chunk`` a positive integer,
    switches true/false); the scene's keywords by the scene builder's kinds."""
    from fpsi_jax.cases import registry
    sig = inspect.signature(builder).parameters
    out, scene_kw = {}, {}
    for k, v in kw.items():
        q = sig.get(k)
        if q is None or q.kind != q.KEYWORD_ONLY:
            scene_kw[k] = v
            continue
        default, what = q.default, f"calibration case {name!r}: {k}"
        if isinstance(default, bool):
            if not isinstance(v, bool):
                raise ParameterError(f"{what} = {fmt(v)} is not true or false")
        elif k == "chunk":
            if v is not None:
                v = number(what, v, 1, None, integer=True)
        elif isinstance(default, tuple):
            if not (isinstance(v, (list, tuple)) and len(v) == 2):
                raise ParameterError(f"{what} = {fmt(v)} is not two numbers [lo, hi] with "
                                     "0 < lo < hi")
            lo = number(f"{what}[0]", v[0], 0.0, None, lo_open=True)
            v = (lo, number(f"{what}[1]", v[1], lo, None, lo_open=True))
        elif isinstance(default, (int, float)) or default is None:
            if not (default is None and v is None):
                lo, hi, lo_open, hi_open = CASE_RANGES.get(k, (0.0, None, True, False))
                v = number(what, v, lo, hi, lo_open, hi_open)
        elif isinstance(default, str) and not isinstance(v, str):
            raise ParameterError(f"{what} = {fmt(v)} is not a string (default {default!r})")
        out[k] = v
    if scene_kw:
        scene_kw = registry.check_kinds(cases.SCENE_OF[name], scene_kw)
    return {**out, **scene_kw}


def run(args) -> int:
    from fpsi_jax.cli import is_scene_file
    check_args(args)
    if is_scene_file(args.case):
        return run_file(args)
    file_only = [f"--{k}" for k in ("data", "fit", "probe", "window", "holdout", "target",
                                    "start", "jacobian") if getattr(args, k) is not None]
    if file_only:
        raise ParameterError(f"{file_only[0]} needs a scene file (my_case.toml); the "
                             f"ready-made case {args.case!r} sets its own")
    return run_case(args)


# --- a scene file -------------------------------------------------------------------------
def run_file(args) -> int:
    from fpsi_jax import scenefile
    from . import usercase as uc
    sf = scenefile.load(args.case)
    physics = ov.apply(sf.scene, set_pairs(args.set, ov.known_to(sf.scene)),
                       f"scene file {args.case!r}", listing=args.case)
    s = uc.settings(sf, data=args.data, fit=args.fit, probe=args.probe, window=args.window,
                    holdout=args.holdout, target=args.target, start=args.start,
                    steps=args.steps, optimizer=args.optimizer, jacobian=args.jacobian)
    case = uc.build(sf, s, physics)                     # every check, nothing compiled yet
    log = (lambda *a: None) if args.quiet else print
    for line in s.notes:
        log(line)
    try:
        res = fit(case.calibration, optimizer=s.optimizer, learning_rate=args.lr,
                  max_steps=s.steps, noise=args.noise, progress=not args.quiet,
                  loss_tol=LOSS_TOL, rel_tol=REL_TOL, patience=PATIENCE, jacobian=s.jacobian)
        rec, curves = uc.report(case, res, progress=None if args.quiet else print)
    except SimulationError as e:
        print(f"error: {e}", file=sys.stderr)
        return 3
    stem = os.path.splitext(os.path.basename(args.case))[0]
    os.makedirs(args.out, exist_ok=True)
    js, png = os.path.join(args.out, f"{stem}.json"), os.path.join(args.out, f"{stem}.png")
    rec["command"] = "fpsi calibrate " + shlex.join(getattr(args, "argv", [])
                                                    or [args.case])
    with open(js, "w") as fh:
        json.dump(rec, fh, indent=1, default=float)
    fitted = ", ".join(f"{k} = {v:.4g}" for k, v in rec["fitted"].items())
    uc.plot(case, rec, curves, png, title=f"{stem}: {fitted}")
    log(uc.summary(rec))
    print(f"{res.steps} steps ({res.stopped}), fit {res.wall_s:.1f} s; wrote {js} and {png}")
    return 0


# --- a ready-made case --------------------------------------------------------------------
def run_case(args) -> int:
    builder = cases.get(args.case)
    kw = set_pairs(args.set)
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
    kw = check_case_kwargs(args.case, builder, kw)
    steps = 30 if args.steps is None else args.steps
    case = builder(**kw)
    res = fit(case.calibration, optimizer=args.optimizer or "lm", learning_rate=args.lr,
              max_steps=steps, noise=args.noise, progress=not args.quiet,
              loss_tol=LOSS_TOL, rel_tol=REL_TOL, patience=PATIENCE, jacobian=case.jacobian)
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
    print("calibration cases (also as scene files: examples/calibrate/*.toml):")
    for name, fn in cases.CASES.items():
        doc = (fn.__doc__ or "").strip().splitlines()[0]
        print(f"  {name:20s} {doc}")
