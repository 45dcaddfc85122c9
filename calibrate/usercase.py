"""Calibration of your own scene file against your own measurements.

    fpsi calibrate my_case.toml --data measured.csv --fit E,damping [--probe tip]
                  [--window 0,0.2] [--holdout 0.2,0.36] [--target trajectory]

or, from Python,

    from fpsi_jax import scenefile
    from calibrate import fit, usercase
    sf = scenefile.load("my_case.toml")
    case = usercase.build(sf, usercase.settings(sf, data="measured.csv", fit=["E"]))
    res = fit.fit(case.calibration)
    record, curves = usercase.report(case, res)  # the JSON record and the curves
    usercase.plot(case, record, curves, "fit.png")

What is fitted (``--fit``, comma separated, each ``name`` or ``name:lo:hi``):

* any scalar ``Params`` leaf by its dotted name (``dem.damping``) or a short name that
  names one leaf (``damping``);
* ``<structure>.E`` — Young's modulus of a ``[[structure]]`` [Pa]. Every spring E sets
  scales linearly with it (the K42–K43 mapping, plane strain or not, is linear in E):
  ``bond.kn``, ``bond.ks`` and ``dem.kn``, ``dem.ks`` — except those ``[bonds]`` or
  ``[contacts]`` give explicitly. Default bounds ×0.2 – ×5 of the file's E;
* ``<structure>.sigma_c``, ``<structure>.tau_c`` — bond strengths [Pa] (``bond.sigma_c``,
  ``bond.tau_c``); with one structure in the file, plain ``E``, ``sigma_c``, ``tau_c``
  mean its constants;
* ``stiffness`` — a factor on every spring (bond and contact, normal and shear).

``dem.damping`` (c [1/s]) gets default bounds ×0.01 – ×100 around its start value; a
positive quantity is fitted in log space (its start must then be > 0: ``--start
damping=0.5`` when the file has none). Start values default to the file's.

The data file: ``t [s]`` first, then columns ``<probe>.<component> [unit]`` (or
``<component> [unit]``) of the probe the data measures (:mod:`fpsi_jax.scenefile.data`;
units converted to SI and checked against the probe's).

Targets (``--target``):

* ``trajectory``  every sample inside the fitted window, each component divided by its
  largest |measured value| (:class:`~calibrate.targets.Trajectory`);
* ``static``  the mean of each component over the window, simulation against data
  (:class:`~calibrate.targets.WindowMean`): a static state at the end of a damped run;
* ``vibration``  the frequency and damping ratio of the free vibration of the component
  with the largest amplitude, measured from the data curve and from the simulation
  sampled at the data's times (:class:`~calibrate.targets.FreeVibration`).

How long the runs are: every rollout of the fit lasts to the end of the fitted window
(data after it cannot change the loss, and a shorter run is cheaper, also for the
gradient). The report's forward runs, at the start and at the fitted values, last to the
end of the held-out window when one is given. Both windows must lie inside the scene's
[0, t_end]. Every check — fit names, bounds and start values, the probe, the data's
columns, units and times, the windows — happens before anything is compiled; each
failure is one line naming the file, the table and the key.
"""
from __future__ import annotations

import dataclasses
import math
import os
import time

import numpy as np

from fpsi_jax.model.errors import ParameterError, fmt
from fpsi_jax.scenefile import data as datafile
from fpsi_jax.scenefile.reader import FileError, fail

from . import space as sp
from .fit import Calibration
from .rollout import prepare
from .targets import FreeVibration, Trajectory, WindowMean

TARGETS = ("trajectory", "static", "vibration")
E_BOUNDS = (0.2, 5.0)              # × the file's E
DAMPING_BOUNDS = (0.01, 100.0)     # × the start value of dem.damping
MATERIAL_CONSTANTS = ("E", "sigma_c", "tau_c")
UNITS = {"E": "Pa", "sigma_c": "Pa", "tau_c": "Pa", "dem.damping": "1/s",
         "stiffness": "-", "dem.kn": "N/m", "dem.ks": "N/m", "bond.kn": "Pa/m",
         "bond.ks": "Pa/m", "bond.sigma_c": "Pa", "bond.tau_c": "Pa", "dem.load_ramp": "s"}
DEFAULTS = {"target": "trajectory", "steps": 30, "optimizer": "lm", "jacobian": "ad"}


# --- settings ------------------------------------------------------------------------------
@dataclasses.dataclass(frozen=True)
class Settings:
    """What to fit against what: the file's [calibration] table with the command line's
    flags on top (a flag wins)."""

    data: str
    fit: tuple
    probe: str | None = None
    window: tuple | None = None
    holdout: tuple | None = None
    target: str = "trajectory"
    start: tuple = ()                 # ("name=value", ...)
    start_from_file: bool = False     # the table's start values: those of unfitted names
                                      # are ignored (a --fit flag may fit fewer)
    steps: int = 30
    optimizer: str = "lm"
    jacobian: str = "ad"
    notes: tuple = ()                 # lines fpsi calibrate prints before the fit


def _bad(sf, key, msg):
    """Refuse a setting, named as the user can have given it: the flag alone where the
    file's [calibration] table lacks the key, else both (a flag wins over the table)."""
    if key in (sf.calibration or {}):
        fail(sf.path, "calibration", f"key {key!r} (or --{key}){msg}")
    raise FileError(f"{os.path.basename(sf.path)}: --{key}{msg}")


def split_list(items) -> list[str]:
    """``["E,damping", "tau_c:1e5:1e7"]`` → ``["E", "damping", "tau_c:1e5:1e7"]``."""
    if items is None:
        return []
    if isinstance(items, str):
        items = [items]
    return [s.strip() for item in items for s in str(item).split(",") if s.strip()]


def settings(sf, **flags) -> Settings:
    """Settings from the scene file's [calibration] table, each overridden by the flag of
    the same name when that is not None (``data`` relative to the working folder, the
    table's relative to the scene file)."""
    table = dict(sf.calibration or {})
    got = {k: (flags[k] if flags.get(k) not in (None, [], ()) else table.get(k))
           for k in Settings.__dataclass_fields__ if k != "notes"}
    notes = []
    dem = sf.scene.params.dem
    # K25's local damping and the rolling resistance switch with a sign: derivatives
    # through them are not the loss's
    signs = [] if dem is None else [
        (key, float(v)) for key, v in (("alpha", dem.alpha), ("rolling_friction", dem.mu_roll))
        if v is not None and float(v) > 0]
    if signs:
        key, value = signs[0]
        what = f"[contacts] {key} = {fmt(value)}"
        if got["optimizer"] in ("adam", "sgd"):
            _bad(sf, "optimizer", f" = {got['optimizer']!r} follows the gradient, and {what} "
                 "makes it wrong (its sign switches); fit with 'lm'"
                 + (", or damp with [contacts] damping instead" if key == "alpha" else ""))
        if got["jacobian"] is None:
            got["jacobian"] = "fd"
            notes.append(f"note: {what}: derivatives through its sign switch are not the "
                         "loss's, so the fit takes a secant Jacobian (--jacobian fd)"
                         + ("; [contacts] damping keeps them exact" if key == "alpha"
                            else ""))
    for k, v in DEFAULTS.items():
        if got[k] is None:
            got[k] = v
    if not got["data"]:
        _bad(sf, "data", " is required: the measured CSV (give --data or [calibration] "
             "data)")
    if not split_list(got["fit"]):
        _bad(sf, "fit", " is required: what to fit, e.g. --fit E,damping (or "
             "[calibration] fit)")
    if got["target"] not in TARGETS:
        _bad(sf, "target", f" = {got['target']!r} is not a choice; allowed "
             f"{', '.join(map(repr, TARGETS))}")
    if got["optimizer"] not in ("lm", "adam", "sgd"):
        _bad(sf, "optimizer", f" = {got['optimizer']!r} is not a choice; allowed 'lm', "
             "'adam', 'sgd'")
    if got["jacobian"] not in ("ad", "fd"):
        _bad(sf, "jacobian", f" = {got['jacobian']!r} is not a choice; allowed 'ad', 'fd'")
    if not (isinstance(got["steps"], int) and got["steps"] >= 1):
        _bad(sf, "steps", f" = {got['steps']!r} is out of range; allowed [1, inf)")
    for key in ("window", "holdout"):
        got[key] = _range(sf, key, got[key])
    return Settings(data=os.path.abspath(got["data"]), fit=tuple(split_list(got["fit"])),
                    probe=got["probe"], window=got["window"], holdout=got["holdout"],
                    target=got["target"], start=tuple(split_list(got["start"])),
                    start_from_file=flags.get("start") in (None, [], ()),
                    steps=int(got["steps"]), optimizer=got["optimizer"],
                    jacobian=got["jacobian"], notes=tuple(notes))


def _range(sf, key, v):
    if v is None:
        return None
    if isinstance(v, str):
        v = v.split(",")
    try:
        a, b = (float(x) for x in v)
    except (TypeError, ValueError):
        _bad(sf, key, f" = {v!r} is not a range a,b [s]")
    if not (math.isfinite(a) and math.isfinite(b) and b > a):
        _bad(sf, key, f" = [{a}, {b}] is not a range a,b with a < b [s]")
    return (a, b)


# --- what can be fitted ----------------------------------------------------------------------
def fittable(sf) -> list[str]:
    """Every name ``--fit`` accepts for this scene file."""
    p = sf.scene.params
    out = ["stiffness"] if _stiffness_leaves(p) else []
    for s in sf.materials:
        out += [f"{s}.{c}" for c in MATERIAL_CONSTANTS]
    return out + [n for n in p.names() if _scalar_leaf(p, n)]


def _scalar_leaf(params, name) -> bool:
    return name != "dt" and np.ndim(params.get(name)) == 0


def _stiffness_leaves(params):
    names = params.names()
    return [leaf for leaf in sp.STIFFNESS_LEAVES if leaf in names]


def e_leaves(sf) -> tuple[str, ...]:
    """The Params leaves a structure's E sets in this file: the bond springs unless
    [bonds] gives them, the contact springs unless [contacts] does (ks also follows kn
    when only kn is given)."""
    names = sf.scene.params.names()
    bonds = sf.spec.get("bonds") or {}
    cont = sf.spec.get("contacts") or {}
    out = []
    if bonds.get("kn") is None:
        out.append("bond.kn")
    if bonds.get("ks") is None:
        out.append("bond.ks")
    if cont.get("kn") is None:
        out.append("dem.kn")
        if cont.get("ks") is None:
            out.append("dem.ks")
    return tuple(leaf for leaf in out if leaf in names)


@dataclasses.dataclass(frozen=True)
class Spec:
    """One ``--fit`` item: the name as written, its bounds (or None)."""

    text: str
    name: str
    lo: float | None
    hi: float | None


def parse_spec(sf, text: str) -> Spec:
    parts = [p.strip() for p in text.split(":")]
    if len(parts) not in (1, 3) or not parts[0]:
        _bad(sf, "fit", f": {text!r} is not 'name' or 'name:lo:hi'")
    lo = hi = None
    if len(parts) == 3:
        try:
            lo, hi = float(parts[1]), float(parts[2])
        except ValueError:
            _bad(sf, "fit", f": {text!r}: the bounds are not numbers (name:lo:hi)")
        if not (math.isfinite(lo) and math.isfinite(hi) and hi > lo):
            _bad(sf, "fit", f": {text!r}: the bounds must satisfy lo < hi")
    return Spec(text, parts[0], lo, hi)


def _structure_constant(sf, name):
    """(structure, constant) when ``name`` is one, else None."""
    if "." in name:
        s, c = name.split(".", 1)
        return (s, c) if s in sf.materials else None
    if name in MATERIAL_CONSTANTS and len(sf.materials) == 1:
        return (next(iter(sf.materials)), name)
    if name == "E" and len(sf.materials) > 1:
        _bad(sf, "fit", f": 'E' is ambiguous, the file has structures "
             f"{', '.join(sf.materials)}: give <structure>.E")
    return None


def resolve(sf, spec: Spec, start: dict) -> sp.Fitted:
    """The :class:`~calibrate.space.Fitted` quantity a ``--fit`` item names (see the
    module docstring), with its default bounds; ``start`` (name → value) may hold its
    start value under the name written or the name resolved."""
    p = sf.scene.params
    sc = _structure_constant(sf, spec.name)
    if sc is not None:
        s, c = sc
        if c not in MATERIAL_CONSTANTS:
            _unknown(sf, spec.name)
        if c == "E":
            leaves = e_leaves(sf)
            if not leaves:
                _bad(sf, "fit", f": {s}.E sets no spring here ([bonds] and [contacts] give "
                     "kn and ks explicitly): fit those leaves instead")
            E = float(sf.materials[s]["E"])
            lo, hi = ((E * E_BOUNDS[0], E * E_BOUNDS[1]) if spec.lo is None
                      else (spec.lo, spec.hi))
            return sp.scale(f"{s}.E", leaves, lo, hi, ref=E)
        leaf = f"bond.{c}"
        if leaf not in p.names():
            _bad(sf, "fit", f": {spec.name!r}: the scene has no bonds")
        return _leaf(sf, f"{s}.{c}", leaf, spec, start)
    if spec.name == "stiffness":
        leaves = _stiffness_leaves(p)
        if not leaves:
            _unknown(sf, spec.name)
        lo, hi = (0.1, 10.0) if spec.lo is None else (spec.lo, spec.hi)
        return sp.scale("stiffness", leaves, lo, hi)
    try:
        leaf = p.resolve(spec.name)
    except ParameterError as e:
        if "ambiguous" in str(e):
            _bad(sf, "fit", f": {e}")
        _unknown(sf, spec.name)
    if not _scalar_leaf(p, leaf):
        _unknown(sf, spec.name)
    return _leaf(sf, leaf, leaf, spec, start)


def _leaf(sf, name, leaf, spec, start):
    v0 = start.get(spec.name, start.get(name, float(np.asarray(sf.scene.params.get(leaf)))))
    lo, hi = spec.lo, spec.hi
    if lo is None and leaf == "dem.damping":
        if not v0 > 0:
            _bad(sf, "fit", f": {name} starts at {v0!r} and is fitted in log space: give a "
                 f"start value > 0 (--start {spec.name}=0.5) or bounds "
                 f"({spec.name}:lo:hi)")
        lo, hi = v0 * DAMPING_BOUNDS[0], v0 * DAMPING_BOUNDS[1]
    log = lo is None or lo > 0
    if lo is None and not v0 > 0:
        _bad(sf, "fit", f": {name} starts at {v0!r}: a quantity fitted without bounds must "
             f"start > 0 (log space); give bounds ({spec.name}:lo:hi) or --start "
             f"{spec.name}=<value>")
    return sp.Fitted(name=name, leaves=(leaf,), lo=lo, hi=hi, log=log)


def _unknown(sf, name):
    _bad(sf, "fit", f": {name!r} is not a parameter of this file; can be fitted: "
         f"{', '.join(fittable(sf))}")


def start_values(sf, items) -> dict:
    """``["damping=0.5", "gate.E=8e6"]`` → {name: value} (names as written)."""
    out = {}
    for item in items:
        name, eq, value = item.partition("=")
        try:
            out[name.strip()] = float(value)
        except ValueError:
            _bad(sf, "start", f": {item!r} is not name=value (a number in SI units)")
        if not eq or not name.strip():
            _bad(sf, "start", f": {item!r} is not name=value")
    return out


def fitted_quantities(sf, specs, start_given: dict, lenient: bool = False):
    """(Fitted list, start values by fitted name) for the ``--fit`` items; a start value
    of a quantity not fitted is an error, or ignored with ``lenient`` (the file's
    [calibration] start list under a --fit flag that fits fewer)."""
    fitted, by_written = [], {}
    for spec in specs:
        f = resolve(sf, spec, start_given)
        fitted.append(f)
        by_written[spec.name] = f.name
    names = [f.name for f in fitted]
    dup = {n for n in names if names.count(n) > 1}
    if dup:
        _bad(sf, "fit", f": {sorted(dup)[0]!r} is named twice")
    start = {}
    for k, v in start_given.items():
        name = by_written.get(k, k)
        if name not in names:
            try:
                name = sf.scene.params.resolve(k)
            except ParameterError:
                pass
        if name not in names:
            if lenient:
                continue
            _bad(sf, "start", f": {k!r} is not fitted; fitted: {', '.join(names)}")
        start[name] = v
    return fitted, start


# --- the case ------------------------------------------------------------------------------
@dataclasses.dataclass
class UserCase:
    """A scene file's calibration ready to fit, with what its report needs."""

    calibration: Calibration
    sf: object                     # the SceneFile
    settings: Settings
    probe: object                  # the Probe the data measures
    t: np.ndarray                  # data times [s]
    y: np.ndarray                  # data values (n, c), SI
    components: list               # probe component index of each data column
    window: tuple
    holdout: tuple | None
    t_report: float                # the report's runs last this long [s]
    initial: np.ndarray            # the probe at t = 0
    file_values: dict              # the fitted quantities at the file's own values
    physics: dict                  # Physics overrides (--set)
    setup_s: float = 0.0


def _probe(sf, name):
    if not sf.probes:
        fail(sf.path, "probe", "the file has no [[probe]]: add the measurement the data "
             "holds (e.g. kind = 'displacement')")
    if name is None:
        if len(sf.probes) > 1:
            _bad(sf, "probe", f" is required: the file has probes "
                 f"{', '.join(p.name for p in sf.probes)}")
        return sf.probes[0]
    p = sf.probe(name)
    if p is None:
        _bad(sf, "probe", f" = {name!r} names no probe; probes: "
             f"{', '.join(q.name for q in sf.probes)}")
    return p


def _inside_run(sf, key, w, t_end):
    if w is not None and (w[0] < 0 or w[1] > t_end * (1 + 1e-9)):
        _bad(sf, key, f" = [{w[0]:.6g}, {w[1]:.6g}] s is outside the run [0, {t_end:.6g}] s "
             "([scene] t_end)")


def _samples(t, window):
    return (t > 0) & (t >= window[0]) & (t <= window[1] + 1e-12)


def check_data(sf, s: Settings, probe):
    """(t, y, components, window, holdout) after every check of the data against the
    probe, the windows and the run (DataError / FileError, one line)."""
    names, units, values = datafile.read_csv(s.data)
    t, y, comps = datafile.match(s.data, probe, names, units, values)
    t_end = float(sf.scene.t_end)
    _inside_run(sf, "window", s.window, t_end)
    _inside_run(sf, "holdout", s.holdout, t_end)
    window = s.window or (max(0.0, float(t[0])), min(float(t[-1]), t_end))
    if not window[1] > window[0]:
        _data_fail(s.data, f"its times [{t[0]:.4g}, {t[-1]:.4g}] s lie outside the "
                       f"run's [0, {t_end:.4g}] s")
    late = int(np.sum(t > t_end * (1 + 1e-9)))
    # a run's own probe file ends at its last step, ⌈t_end/Δt⌉ Δt, within one sample of
    # t_end: that sample lies outside the default window, it is not a mistake
    own_end = late == 1 and len(t) > 1 and float(t[-1] - t_end) <= float(t[-1] - t[-2])
    if s.window is None and late and not own_end:
        _data_fail(s.data, f"{late} of its {len(t)} samples lie after the run's end "
                   f"(t up to {t[-1]:.6g} s, [scene] t_end = {t_end:.6g} s): lengthen the "
                   "run, cut the file, or fit a --window inside the run")
    datafile.check_span(s.data, t, t_end, window)
    if s.holdout is not None:
        datafile.check_span(s.data, t, t_end, s.holdout)
    return t, y, comps, window, s.holdout


def _data_fail(path, msg):
    raise datafile.DataError(f"{os.path.basename(path)}: {msg}")


def _vibration_column(y, inside):
    return int(np.argmax(np.max(np.abs(y[inside]), axis=0)))


def _target(kind, t, y, comps, window, initial):
    inside = _samples(t, window)
    if kind == "trajectory":
        return Trajectory(t_ref=tuple(map(float, t)), values=tuple(map(tuple, y)),
                          components=tuple(comps), window=tuple(window),
                          initial=tuple(map(float, initial)), name="data")
    if kind == "static":
        mean = y[inside].mean(axis=0)
        peak = np.max(np.abs(y), axis=0)
        scale = np.where(mean != 0, np.abs(mean), np.where(peak > 0, peak, 1.0))
        return WindowMean(values=tuple(map(float, mean)), components=tuple(comps),
                          window=tuple(window), scale=tuple(map(float, scale)), name="data")
    j = _vibration_column(y, inside)
    return FreeVibration.from_data(t[inside], y[inside, j], component=comps[j],
                                   initial=tuple(map(float, initial)), name="data")


def build(sf, s: Settings, physics: dict | None = None, chunk: int | None = None
          ) -> UserCase:
    """Check everything, then make the differentiable problem: the probe observed after
    every step, the time step (and DEM sub-steps) derived for the stiffest parameter set
    the bounds allow and fixed for the whole fit."""
    t0 = time.perf_counter()
    physics = dict(physics or {})
    probe = _probe(sf, s.probe)
    t, y, comps, window, holdout = check_data(sf, s, probe)
    specs = [parse_spec(sf, x) for x in s.fit]
    fitted, start = fitted_quantities(sf, specs, start_values(sf, s.start),
                                      lenient=s.start_from_file)
    try:
        space0 = sp.ParamSpace(sf.scene.params, fitted, start=start)
    except ParameterError as e:
        fail(sf.path, "calibration", f"key 'start': {e}")
    if s.target == "vibration":            # enough half cycles in the data (host check)
        inside = _samples(t, window)
        try:
            _target("vibration", t, y, comps, window, np.zeros(len(probe.components)))
        except ValueError as e:
            col = probe.components[comps[_vibration_column(y, inside)]]
            _data_fail(s.data, f"column {probe.name}.{col} in the window {list(window)} s: "
                       f"{e}")
    file_values = {f.name: (f.ref if f.scale else float(np.asarray(sf.scene.params.get(
        f.leaves[0])))) for f in space0.fitted}
    problem = prepare(sf.scene, window[1], probe, stiffest=space0.extreme("hi"),
                      chunk=chunk, remat_step=sf.scene.fluid is not None, **physics)
    space = sp.ParamSpace(problem.params, fitted, start=start)
    initial = np.asarray(probe(problem.state0), float)
    target = _target(s.target, t, y, comps, window, initial)
    cal = Calibration(problem, space, [target])
    t_report = max(window[1], holdout[1] if holdout else window[1])
    return UserCase(calibration=cal, sf=sf, settings=s, probe=probe, t=t, y=y,
                    components=list(comps), window=tuple(window), holdout=holdout,
                    t_report=float(t_report), initial=initial, file_values=file_values,
                    physics=physics, setup_s=time.perf_counter() - t0)


def forward(sf, t_end: float, probe: str | None = None, physics: dict | None = None):
    """(t, observations (n, k)) of the file's probe in a run of the file's own values to
    ``t_end``, with the time step a fit of its [calibration] table takes (derived for the
    upper bounds of what it fits): synthetic data that a fit must reproduce exactly."""
    from fpsi_jax.run.driver import simulate
    table = dict(sf.calibration or {})
    p = _probe(sf, probe or table.get("probe"))
    specs = [parse_spec(sf, x) for x in split_list(table.get("fit"))]
    fitted, start = fitted_quantities(sf, specs, start_values(sf, split_list(
        table.get("start"))))
    stiffest = sp.ParamSpace(sf.scene.params, fitted, start=start).extreme("hi")
    pr = prepare(sf.scene, t_end, p, stiffest=stiffest, **dict(physics or {}))
    opts = dict(physics or {})
    if pr.phys.has_fluid and pr.phys.has_solid:
        opts["dem_substeps"] = pr.phys.dem_substeps
    res = simulate(sf.scene, t_end=t_end, params=sf.scene.params.replace(dt=pr.dt),
                   dt=pr.dt, observe=p, progress=False, every=min(t_end, 0.02), **opts)
    u = np.asarray(res.observations, float)
    return (np.arange(u.shape[0]) + 1) * pr.dt, u


# --- evaluation and report -------------------------------------------------------------------
def host_params(case: UserCase, values: dict | None):
    """Host Params of the scene with the fitted quantities at ``values`` (by name; None:
    the file's own values) and the fit's time step."""
    import jax
    pr, space = case.calibration.problem, case.calibration.space
    base = case.sf.scene.params.replace(dt=pr.dt)
    if values is None:
        return base
    p = space.params(space.z_of(values), base=base)
    return jax.tree_util.tree_map(lambda a: np.asarray(a).item() if np.ndim(a) == 0
                                  else np.asarray(a), p)


def evaluate(case: UserCase, values: dict | None, t_end: float | None = None):
    """(t, observations (n, k)) of a forward run to ``t_end`` (default: the report's
    length) with the same step and sub-steps as the fit."""
    from fpsi_jax.run.driver import simulate
    pr = case.calibration.problem
    t_end = case.t_report if t_end is None else t_end
    opts = dict(case.physics)
    if pr.phys.has_fluid and pr.phys.has_solid:
        opts["dem_substeps"] = pr.phys.dem_substeps
    res = simulate(pr.scene, t_end=t_end, params=host_params(case, values), dt=pr.dt,
                   observe=pr.observe, progress=False, every=min(t_end, 0.02), **opts)
    u = np.asarray(res.observations, float)
    return (np.arange(u.shape[0]) + 1) * pr.dt, u


def rms(case: UserCase, t, u, window) -> dict:
    """RMS of simulation − data per measured component over the samples in ``window``
    (the simulation interpolated at the data's times), SI units."""
    tr = Trajectory(t_ref=tuple(map(float, case.t)), values=tuple(map(tuple, case.y)),
                    components=tuple(case.components), window=tuple(window),
                    initial=tuple(map(float, case.initial)))
    import jax.numpy as jnp
    vals = tr.rms(t, jnp.asarray(u), window=tuple(window))
    names = [case.probe.components[c] for c in case.components]
    return dict(zip(names, vals))


def _curves(case, res):
    """name → fitted-quantity values of each curve the report evaluates: the start, the
    fit, and the file's own values when the fit did not start there."""
    names = res.names
    curves = {"start": {k: res.start[k] for k in names},
              "fitted": {k: res.best[k] for k in names}}
    same = all(math.isclose(case.file_values[k], curves["start"][k], rel_tol=1e-6)
               for k in names)
    if not same:
        curves = {"file": None, **curves}
    return curves


def report(case: UserCase, res, progress=print) -> tuple[dict, dict]:
    """(the JSON record, the evaluated curves name → (t, u)) of a finished fit."""
    s, cal = case.settings, case.calibration
    pr = cal.problem
    curves, rms_table, target_rep = {}, {}, {}
    windows = {"window": case.window}
    if case.holdout is not None:
        windows["holdout"] = case.holdout
    for k, (label, values) in enumerate(_curves(case, res).items()):
        t0 = time.perf_counter()
        t, u = evaluate(case, values)
        curves[label] = (t, u)
        if progress:                # the first evaluation compiles the reporting rollout
            progress(f"forward run ({label}) to {case.t_report:.4g} s: "
                     f"{time.perf_counter() - t0:.1f} s" + (" (compile included)" if k == 0
                                                             else ""))
        for w, span in windows.items():
            rms_table.setdefault(w, {})[label] = rms(case, t, u, span)
        n = pr.n_steps
        target_rep[label] = cal.targets[0].report(pr.times, u[:n])
    units = {f.name: UNITS.get(f.name.split(".")[-1] if f.scale else f.name,
                               UNITS.get(f.leaves[0], "")) for f in cal.space.fitted}
    stderr = res.stderr or {}
    rec = {
        "scene_file": os.path.abspath(case.sf.path), "data": s.data,
        "probe": case.probe.name,
        "components": [case.probe.components[c] for c in case.components],
        "units": [case.probe.units[c] for c in case.components],
        "fit": list(s.fit),
        "quantities": [{"name": f.name, "leaves": list(f.leaves), "lo": f.lo, "hi": f.hi,
                        "log": f.log, "unit": units[f.name]} for f in cal.space.fitted],
        "target": s.target, "window_s": list(case.window),
        "holdout_s": list(case.holdout) if case.holdout else None,
        "optimizer": s.optimizer, "jacobian": s.jacobian,
        "file_values": case.file_values,
        "start": {k: res.start[k] for k in res.names},
        "fitted": {k: res.best[k] for k in res.names},
        "std_error": {k: stderr[k]["std_error"] for k in res.names if k in stderr},
        "rel_std_error": {k: stderr[k]["rel_std_error"] for k in res.names if k in stderr},
        "std_error_note": _stderr_note(stderr, res.stopped),
        "loss_start": res.loss_start, "loss_fitted": res.loss_best,
        "loss_history": [h["loss"] for h in res.history],
        "steps": res.steps, "stopped": res.stopped,
        "rms": rms_table, "target_report": target_rep,
        "run": {"dt_s": pr.dt, "n_steps_fit": pr.n_steps, "t_fit_end_s": case.window[1],
                "t_report_end_s": case.t_report,
                "dem_substeps": pr.phys.dem_substeps if pr.phys.has_fluid else None,
                "x64": bool(pr.phys.x64)},
        "wall_s": {"setup": case.setup_s, "fit": res.wall_s},
        "fit_record": res.to_json(),
    }
    return rec, curves


# --- plot ----------------------------------------------------------------------------------
DISPLAY = {"m": ("mm", 1e3), "Pa": ("kPa", 1e-3)}

STYLE = {"file": dict(color="0.55", lw=1.0, ls="--", label="file's values"),
         "start": dict(color="0.35", lw=1.0, label="start"),
         "fitted": dict(color="C0", lw=1.5, label="fitted")}


def plot(case: UserCase, rec: dict, curves: dict, path: str, title: str = ""):
    """Measured samples (markers) against the simulation at the start and fitted values
    (lines), one panel per measured component, the fitted window shaded blue and the
    held-out one orange; and the loss history."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    comps = case.components
    fig, axes = plt.subplots(1, 1 + len(comps), figsize=(4.3 * (1 + len(comps)), 3.7))
    ax = axes[0]
    hist = rec["loss_history"]
    ax.semilogy(range(len(hist)), hist, "o-", ms=3)
    ax.set_xlabel("optimiser step")
    ax.set_ylabel("loss")
    ax.grid(alpha=0.3)
    for j, (ax, c) in enumerate(zip(axes[1:], comps)):
        unit = case.probe.units[c]
        shown, f = DISPLAY.get(unit, (unit, 1.0))
        ax.axvspan(*case.window, color="C0", alpha=0.08, label="fitted window")
        if case.holdout is not None:
            ax.axvspan(*case.holdout, color="C1", alpha=0.10, label="held out")
        for label, (t, u) in curves.items():
            ax.plot(t, u[:, c] * f, **STYLE[label])
        ax.plot(case.t, case.y[:, j] * f, "ko", ms=3.5, mfc="none", label="measured")
        ax.set_xlabel("t [s]")
        ax.set_ylabel(f"{case.probe.name}.{case.probe.components[c]} [{shown}]")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    if title:
        fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _stderr_note(stderr: dict, stopped: str) -> str | None:
    """What the standard errors are: their residual scale, why there are none, which
    quantity the data do not determine, and whether the fit converged (a fit that stopped
    without improving sits where it stalled, maybe in a local minimum of a chaotic loss:
    its Gauss–Newton errors describe the loss's curvature there, not the distance to the
    truth)."""
    parts = [p for p in (stderr.get("note"), stderr.get("s_from")) if p]
    if stopped.startswith("no improvement"):
        parts.append(f"the fit stopped ({stopped}): the errors are the curvature where it "
                     "stalled, not a confidence interval; try other starts or a shorter "
                     "window (docs/scene-file.md, [calibration])")
    return "; ".join(parts) or None


def summary(rec: dict) -> str:
    """One line per fitted quantity and per window: start → fitted ± error; RMS; for a
    free-vibration target, the data's and the model's frequency and damping ratio."""
    lines = []
    for q in rec["quantities"]:
        n = q["name"]
        se = rec["std_error"].get(n)
        lines.append(f"{n}: {rec['start'][n]:.6g} -> {rec['fitted'][n]:.6g}"
                     + (f" ± {se:.3g}" if se is not None else "") + f" {q['unit']}")
    for w, by in rec["rms"].items():
        span = rec["window_s"] if w == "window" else rec["holdout_s"]
        parts = [f"{label} " + ", ".join(f"{k} {v:.4g}" for k, v in vals.items())
                 for label, vals in by.items()]
        lines.append(f"RMS on {w} {span} s [SI]: " + "; ".join(parts))
    report = rec.get("target_report") or {}
    if "frequency_ref" in (report.get("fitted") or {}):        # a free-vibration target
        def freq(r):
            return f"f {r['frequency_hz']:.5g} Hz, ζ {r['damping_ratio']:.4g}"
        lines.append(f"free vibration: data {report['fitted']['frequency_ref']:.5g} Hz, "
                     f"ζ {report['fitted']['damping_ratio_ref']:.4g}; start "
                     f"{freq(report['start'])}; fitted {freq(report['fitted'])}")
    note = rec.get("std_error_note") or ""
    if "do not change" in note or "stopped" in note or not rec["std_error"]:
        lines.append(f"standard errors: {note or 'none'}")
    return "\n".join(lines)
