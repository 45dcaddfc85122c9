"""Measured or reference curves in CSV, matched to probes.

A data file has a header row naming each column with its unit in brackets, then one row
per sample (lines starting with ``#`` are comments):

    t [s], tip.ux [mm], tip.uy [mm]
    0.04, 12.7, 0.84

The first column is the time. The others are probe components, ``<probe>.<component>``
(or just ``<component>`` when the probe is named otherwise, e.g. ``--probe tip``). Units are
converted to SI and checked against the probe's (a column in ``mm`` for a component in
``m`` is fine, one in ``N`` is refused).
"""
from __future__ import annotations

import csv
import os
import re

import numpy as np

from ..model.errors import ParameterError

# unit -> (SI unit, factor to SI)
UNITS = {
    "s": ("s", 1.0), "ms": ("s", 1e-3),
    "m": ("m", 1.0), "mm": ("m", 1e-3), "cm": ("m", 1e-2), "um": ("m", 1e-6),
    "µm": ("m", 1e-6),
    "Pa": ("Pa", 1.0), "kPa": ("Pa", 1e3), "MPa": ("Pa", 1e6), "hPa": ("Pa", 1e2),
    "bar": ("Pa", 1e5), "mbar": ("Pa", 1e2),
    "N/m": ("N/m", 1.0), "kN/m": ("N/m", 1e3),
    "N m/m": ("N m/m", 1.0), "N*m/m": ("N m/m", 1.0), "Nm/m": ("N m/m", 1.0),
    "kN m/m": ("N m/m", 1e3),
    "-": ("-", 1.0), "1": ("-", 1.0), "": ("-", 1.0),
}

_HEADER = re.compile(r"^\s*([^\[\]]+?)\s*\[\s*([^\]]*?)\s*\]\s*$")


class DataError(ParameterError):
    """A data file that cannot be used: one line naming the file, the column and why."""


def _fail(path, msg):
    raise DataError(f"{os.path.basename(path)}: {msg}")


def read_csv(path: str):
    """(names, units, SI values (n, c)) of a data file; every column converted to SI."""
    if not os.path.exists(path):
        raise DataError(f"{path}: no such data file")
    try:
        with open(path, newline="") as fh:
            rows = [r for r in csv.reader(line for line in fh
                                          if line.strip() and not line.lstrip().startswith("#"))]
    except UnicodeDecodeError as e:
        _fail(path, f"is not a text CSV file ({e.reason}); write the curve as 't [s], …' "
              "columns")
    if not rows:
        _fail(path, "is empty")
    names, units, factors = [], [], []
    for k, col in enumerate(rows[0]):
        m = _HEADER.match(col)
        if not m:
            _fail(path, f"column {k + 1} header {col.strip()!r} has no unit; write it as "
                  "'name [unit]', e.g. 't [s]' or 'tip.ux [mm]'")
        name, unit = m.group(1).strip(), m.group(2).strip()
        if unit not in UNITS:
            hint = (" (forces are per metre of out-of-plane thickness here: N/m, kN/m)"
                    if unit in ("N", "kN") else "")
            _fail(path, f"column {name!r}: unknown unit {unit!r}{hint}; known: "
                  f"{', '.join(u for u in UNITS if u)}")
        si, f = UNITS[unit]
        names.append(name)
        units.append(si)
        factors.append(f)
    if names[0] not in ("t", "time") or units[0] != "s":
        _fail(path, f"the first column must be the time, 't [s]' (or ms); got "
              f"{rows[0][0].strip()!r}")
    if len(rows) < 2:
        _fail(path, "has a header but no data rows")
    try:
        values = np.array([[float(v) for v in r] for r in rows[1:]], float)
    except ValueError as e:
        _fail(path, f"a value is not a number ({e})")
    if values.ndim != 2 or values.shape[1] != len(names):
        _fail(path, f"every row must have {len(names)} values")
    if not np.all(np.isfinite(values)):
        _fail(path, "contains non-finite values")
    if np.any(np.diff(values[:, 0]) <= 0):
        _fail(path, "times must increase from row to row")
    return names, units, values * np.asarray(factors)[None, :]


def match(path: str, probe, names=None, units=None, values=None):
    """(t, y (n, k), components): the columns of the data file at ``path`` that measure
    ``probe``'s components (``<probe>.<component>`` or ``<component>``), in SI, with the
    component indices they fill. At least one column must match; units must agree; a
    column named for the probe must name one of its components."""
    if names is None:
        names, units, values = read_csv(path)
    comps, cols = [], []
    for k, (n, u) in enumerate(zip(names[1:], units[1:]), start=1):
        c = n.split(".", 1)[1] if n.startswith(probe.name + ".") else n
        if c not in probe.components:
            if n.startswith(probe.name + "."):      # the probe's, a component it lacks
                _fail(path, f"column {n!r}: probe {probe.name!r} ({probe.kind}) has "
                      f"components {', '.join(probe.components)}")
            continue
        j = probe.components.index(c)
        if u != probe.units[j]:
            _fail(path, f"column {n!r} is in {u}, but probe {probe.name!r} measures "
                  f"{c} in {probe.units[j]}")
        comps.append(j)
        cols.append(k)
    if not cols:
        want = ", ".join(f"{probe.name}.{c} [{u}]" for c, u in zip(probe.components,
                                                                    probe.units))
        _fail(path, f"no column measures probe {probe.name!r}; expected some of: {want}")
    return values[:, 0], values[:, cols], comps


def check_span(path: str, t, t_end: float, window=None):
    """Refuse data that lies outside the run's time span [0, t_end] (or has no sample in
    ``window``)."""
    if t[0] > t_end or t[-1] < 0:
        _fail(path, f"its times [{t[0]:.4g}, {t[-1]:.4g}] s lie outside the run's "
              f"[0, {t_end:.4g}] s")
    inside = (t > 0) & (t <= t_end + 1e-12)
    if window is not None:
        inside &= (t >= window[0]) & (t <= window[1])
    if not inside.any():
        span = f"window {list(window)}" if window is not None else "run"
        _fail(path, f"no sample inside the {span} (t in (0, {t_end:.4g}] s)")
    return inside
