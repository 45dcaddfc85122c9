"""The registries of shipped scenes and validation cases, and the decorators that fill them.

* :func:`scene` registers a builder ``(**physical keywords) -> Scene`` in :data:`SCENES` and
  records the keywords it was called with (defaults included) in ``Scene.builder_kwargs``;
  a builder adds the values it resolves itself (``h0`` from ``dx``, ``c0`` from the scene's
  speed, ...) by returning them in ``builder_kwargs``.
* :func:`validation` registers a case ``(quick, overrides) -> list[Record]`` of a scene in
  :data:`CASES`, with its one-line description.
* :func:`observer` and :func:`plot` give a scene what ``fpsi run`` records every step and
  draws after the run (scenes without a plot get the particle snapshot).

Reference data lives in ``fpsi_jax/data`` (:func:`load_csv`).
"""
from __future__ import annotations

import functools
import importlib.resources
import inspect
from dataclasses import asdict, dataclass
from typing import Callable

import numpy as np

from ..model import limits
from ..model.errors import ParameterError, fmt, number


@dataclass
class Record:
    case: str
    quantity: str
    value: float
    reference: float
    rel_error: float
    tolerance: float
    passed: bool
    wall_s: float
    params: dict

    def as_dict(self):
        return asdict(self)


SCENES: dict[str, Callable] = {}      # scene name -> builder
CASES: dict[str, Callable] = {}       # validation case -> (quick, overrides) -> [Record]
DESCRIPTIONS: dict[str, str] = {}     # validation case -> one line
SCENE_OF: dict[str, str] = {}         # validation case -> the scene it runs
OBSERVERS: dict[str, Callable] = {}   # scene name -> observer(scene) -> (state -> pytree)
PLOTS: dict[str, Callable] = {}       # scene name -> plot(scene, result, png) -> [lines]


def scene(fn: Callable | None = None, *, name: str | None = None):
    """Register a scene builder under ``name`` (default: the function's name).

    The returned builder fills ``Scene.builder_kwargs`` with every keyword of the call,
    defaults included, in the signature's order, updated by what the builder itself put in
    ``builder_kwargs`` (resolved defaults and derived figures, which come last)."""
    def deco(fn):
        key = name or fn.__name__
        sig = inspect.signature(fn)

        @functools.wraps(fn)
        def build(**kwargs):
            bound = sig.bind(**kwargs)
            bound.apply_defaults()
            sc = fn(**kwargs)
            sc.builder_kwargs = {**bound.arguments, **(sc.builder_kwargs or {})}
            return sc

        if key in SCENES:
            raise ValueError(f"scene {key!r} registered twice")
        SCENES[key] = build
        return build
    return deco(fn) if fn is not None else deco


def variant(base: Callable, name: str, doc: str, **defaults) -> Callable:
    """Register scene ``name``: the scene of the builder ``base`` with other ``defaults``
    (every keyword of ``base`` still accepted; ``builder_kwargs`` as ``base``'s)."""
    def build(**kwargs):
        sc = base(**{**defaults, **kwargs})
        sc.name = name
        return sc

    sig = inspect.signature(base)
    build.__signature__ = sig.replace(parameters=[
        p.replace(default=defaults.get(p.name, p.default)) for p in sig.parameters.values()])
    build.__name__ = build.__qualname__ = name
    build.__doc__ = doc
    build.__module__ = base.__module__
    return scene(build, name=name)


def validation(name: str, description: str, scene: str | None = None):
    """Register a validation case ``(quick=False, overrides=None) -> list[Record]`` that runs
    the scene ``scene`` (default: the scene of the same name)."""
    def deco(fn):
        if name in CASES:
            raise ValueError(f"validation case {name!r} registered twice")
        CASES[name] = fn
        DESCRIPTIONS[name] = description
        SCENE_OF[name] = scene or name
        return fn
    return deco


def observer(*scenes: str):
    """Register ``observer(scene) -> observe`` as what ``fpsi run`` records for ``scenes``."""
    def deco(fn):
        for s in scenes:
            OBSERVERS[s] = fn
        return fn
    return deco


def plot(*scenes: str):
    """Register ``plot(scene, result, png) -> lines`` as ``fpsi run --plot``'s figure for
    ``scenes``: it writes ``png`` (and any companion figure) and returns the lines to print
    (what it wrote and its figures of merit)."""
    def deco(fn):
        for s in scenes:
            PLOTS[s] = fn
        return fn
    return deco


def get(name: str):
    try:
        return SCENES[name]
    except KeyError:
        raise ParameterError(f"unknown scene {name!r}; available: {', '.join(SCENES)}") from None


def builder_keys(name: str) -> list[str]:
    return list(inspect.signature(get(name)).parameters)


def build(name: str, **kwargs):
    """The scene ``name`` built with ``kwargs`` (unknown keywords refused) and validated."""
    fn = get(name)
    keys = builder_keys(name)
    bad = [k for k in kwargs if k not in keys]
    if bad:
        raise ParameterError(f"scene {name!r} has no parameter {bad[0]!r}; allowed: "
                             f"{', '.join(keys)}")
    return fn(**check_kinds(name, kwargs)).validate()


def check_kinds(name: str, kwargs: dict) -> dict:
    """``kwargs`` checked against the kinds of the builder's defaults, before it runs: a
    float default takes a finite number, an int one an integer, a bool one true/false, a
    str one a string, a None default a finite number or None. (Ranges are the builder's
    own checks.) Returns the values, integral floats for int keys made ints."""
    params = inspect.signature(get(name)).parameters
    out = {}
    for k, v in kwargs.items():
        default = params[k].default
        what = f"scene {name!r}: {k}"
        if isinstance(default, bool):
            if not isinstance(v, (bool, np.bool_)):
                raise ParameterError(f"{what} = {fmt(v)} is not true or false")
        elif isinstance(default, int):
            # an integer keyword counts particles, rows or columns: never more than the
            # machine holds (model.limits)
            v = _kind(number, what, v, default, integer=True, hi=limits.max_particles())
        elif isinstance(default, float) or (default is None and v is not None):
            v = _kind(number, what, v, default)
            if k == "t_end" and v is not None:         # every scene's end time
                v = number(what, v, 0.0, None, lo_open=True)
        elif isinstance(default, str) and not isinstance(v, str):
            raise ParameterError(f"{what} = {fmt(v)} is not a string (default {default!r})")
        out[k] = v
    return out


def _kind(check, what, v, default, **kw):
    """``check(what, v, **kw)`` with the default named in its message (the builder's own
    range check follows for a value of the right kind)."""
    try:
        return check(what, v, **kw)
    except ParameterError as e:
        tail = "derived from the scene" if default is None else fmt(default)
        raise ParameterError(f"{e} (default {tail})") from None


def data_path(name: str):
    return importlib.resources.files("fpsi_jax") / "data" / name


def load_csv(name: str) -> np.ndarray:
    with data_path(name).open() as fh:
        return np.loadtxt(fh, delimiter=",", skiprows=1)
