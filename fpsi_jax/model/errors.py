"""The package's two exceptions and the range checks that raise them.

``ParameterError`` is bad user input, found before anything is compiled: its message names
the key and the allowed range, and the CLI turns it into one line and exit code 2.
``SimulationError`` is a run that went unstable: it names the step, time, particle and
quantity.
"""
from __future__ import annotations

import math

import numpy as np


class ParameterError(ValueError):
    """Bad user input: names the parameter and the allowed range."""


def require(name: str, value, lo=None, hi=None, lo_open=False, hi_open=False):
    """Raise ParameterError unless lo <= value <= hi (open ends where asked)."""
    v = float(value)
    bad = not math.isfinite(v)
    if lo is not None:
        bad |= v <= lo if lo_open else v < lo
    if hi is not None:
        bad |= v >= hi if hi_open else v > hi
    if bad:
        left = "(" if lo_open else "["
        right = ")" if hi_open else "]"
        rng = f"{left}{'-inf' if lo is None else lo}, {'inf' if hi is None else hi}{right}"
        raise ParameterError(f"{name} = {value!r} is out of range; allowed {rng}")


def check_positive(**kw):
    """Raise ParameterError for the first keyword whose value is not finite and > 0."""
    for k, v in kw.items():
        if not (np.isfinite(v) and v > 0):
            raise ParameterError(f"{k} = {v!r} out of range; allowed (0, inf)")


class SimulationError(RuntimeError):
    """A run went unstable. Attributes: step, time, particle, phase, quantity, output."""

    def __init__(self, step, t, particle, quantity, phase="fluid", output=None, t_good=None):
        self.step, self.time, self.particle = step, t, particle
        self.phase, self.quantity, self.output = phase, quantity, output
        where = f"; frames up to t = {t_good:.6g} s are in {output}" if output else ""
        super().__init__(f"run unstable at step {step} (t = {t:.6g} s): {phase} particle "
                         f"{particle}: {quantity}{where}")
