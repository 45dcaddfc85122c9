"""The package's two exceptions and the range checks that raise them.

``ParameterError`` is bad user input, found before anything is compiled: its message names
the key and the allowed range, and the CLI turns it into one line and exit code 2.
``SimulationError`` is a run that went unstable: it names the step, time, particle and
quantity, and where the particle was in the last good frame (with its voidage among grains).
"""
from __future__ import annotations

import math

import numpy as np


class ParameterError(ValueError):
    """Bad user input: names the parameter and the allowed range."""


def fmt(value) -> str:
    """A value as a user writes it: numbers plain (``0.5``, ``5e+08``; never numpy's
    ``np.float64(...)``), strings quoted, anything else by repr."""
    if isinstance(value, (bool, np.bool_)):
        return "true" if value else "false"
    if isinstance(value, (int, float, np.integer, np.floating)):
        return f"{float(value):g}" if not isinstance(value, (int, np.integer)) else str(int(value))
    return repr(value)


def number(name: str, value, lo=None, hi=None, lo_open=False, hi_open=False,
           integer=False) -> float:
    """``value`` as a finite float (int with ``integer``) inside [lo, hi] (open ends where
    asked); ParameterError naming ``name`` otherwise. Booleans, strings, None, NaN and ±inf
    are not numbers here."""
    kind = "an integer" if integer else "a number"
    left = "(" if lo_open or lo is None else "["
    right = ")" if hi_open or hi is None else "]"
    rng = f"{left}{'-inf' if lo is None else fmt(lo)}, {'inf' if hi is None else fmt(hi)}{right}"
    if lo is None and hi is None:
        rng = f"any finite {'integer' if integer else 'number'}"
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer,
                                                                      np.floating)):
        raise ParameterError(f"{name} = {fmt(value)} is not {kind}; allowed {rng}")
    v = float(value)
    if not math.isfinite(v):
        raise ParameterError(f"{name} = {fmt(value)} is not finite; allowed {rng}")
    if integer and v != int(v):
        raise ParameterError(f"{name} = {fmt(value)} is not {kind}; allowed {rng}")
    bad = False
    if lo is not None:
        bad |= v <= lo if lo_open else v < lo
    if hi is not None:
        bad |= v >= hi if hi_open else v > hi
    if bad:
        raise ParameterError(f"{name} = {fmt(value)} is out of range; allowed {rng}")
    return int(v) if integer else v


def require(name: str, value, lo=None, hi=None, lo_open=False, hi_open=False):
    """Raise ParameterError unless ``value`` is a finite number with lo <= value <= hi (open
    ends where asked). Arrays (traced or not) pass through unchecked when not scalars."""
    if np.ndim(value) != 0 or _traced(value):
        return
    if hasattr(value, "item") and not isinstance(value, (np.integer, np.floating)):
        value = value.item()            # a 0-d array
    number(name, value, lo, hi, lo_open, hi_open)


def _traced(value) -> bool:
    return type(value).__module__.startswith("jax") and not hasattr(value, "item")


def check_positive(**kw):
    """Raise ParameterError for the first keyword whose value is not a finite number > 0."""
    for k, v in kw.items():
        number(k, v.item() if hasattr(v, "item") and np.ndim(v) == 0 else v, 0.0, None,
               lo_open=True)


#: the seeds' floor of the fluid voidage in their packed beds (W6.2.2, W6.3)
FLOORED_VOIDAGE = 0.8


class SimulationError(RuntimeError):
    """A run went unstable. Attributes: step, time, particle, phase, quantity, output,
    position (the particle's (x, y) in the last good frame, or None) and voidage (a fluid
    particle's ε there among grains, else None). ``set_up``: the remedies the run already
    has ('floored'; 'no_pore_h': Physics.pore_neighbours already 1, or a pressure
    coupling other than 'shared', where it does nothing), which the hint then leaves out."""

    def __init__(self, step, t, particle, quantity, phase="fluid", output=None, t_good=None,
                 position=None, voidage=None, set_up=()):
        self.step, self.time, self.particle = step, t, particle
        self.phase, self.quantity, self.output = phase, quantity, output
        self.position, self.voidage = position, voidage
        at = ""
        if position is not None:
            eps = f", voidage {voidage:.3g}" if voidage is not None else ""
            at = (f" (at x = {position[0]:.4g}, y = {position[1]:.4g} m in the last good "
                  f"frame{eps})")
        where = f"; frames up to t = {t_good:.6g} s are in {output}" if output else ""
        hint = ""
        if voidage is not None and voidage < FLOORED_VOIDAGE and "floored" not in set_up:
            hint = "; pore fluid of a packed bed can go unstable (docs/physics.md, Packed beds)"
            if "no_pore_h" not in set_up:
                hint += (": a larger [physics] pore_neighbours (default 0.5, at most 1) gives "
                         "the water among the grains a wider kernel")
            hint += (f"; [physics] voidage = \"mapped\" with eps_floor = {FLOORED_VOIDAGE} "
                     "runs it floored, as the seeds did")
        super().__init__(f"run unstable at step {step} (t = {t:.6g} s): {phase} particle "
                         f"{particle}: {quantity}{at}{where}{hint}")


class Interrupted(RuntimeError):
    """A run stopped by SIGINT or SIGTERM at the end of a chunk. Attributes: signal (its
    name), step, time, frames (in the output file), output."""

    def __init__(self, signal, step, t, frames=0, output=None):
        self.signal, self.step, self.time = signal, step, t
        self.frames, self.output = frames, output
        where = f"; {frames} frames in {output} (fpsi run --resume {output})" if output else ""
        super().__init__(f"interrupted by {signal} at step {step} (t = {t:.6g} s){where}")
