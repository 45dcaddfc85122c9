"""Read a scene file (TOML, :mod:`tomllib`) and check it against :mod:`.schema`.

Every problem is one :class:`~fpsi_jax.model.errors.ParameterError` line naming the file,
the table and the key, raised before anything is built or compiled:

    flume.toml: [[structure]] 'gate': key 'E' = -1 is out of range; allowed (0, inf) Pa
"""
from __future__ import annotations

import math
import os
import re
import tomllib

from ..model.errors import ParameterError
from .schema import TABLES


class FileError(ParameterError):
    """A scene-file problem, located by file, table and key."""


def where(path, table, item=None, index=None) -> str:
    """``file: [table]`` or ``file: [[table]] 'name'`` (or ``#index`` without a name)."""
    array = TABLES.get(table, (False,))[0]
    label = f"[[{table}]]" if array else f"[{table}]"
    if array:
        name = item.get("name") if isinstance(item, dict) else None
        label += f" {name!r}" if name else (f" #{index + 1}" if index is not None else "")
    return f"{os.path.basename(path)}: {label}"


def fail(path, table, msg, item=None, index=None):
    raise FileError(f"{where(path, table, item, index)}: {msg}")


def load_toml(path: str) -> dict:
    if not os.path.exists(path):
        raise FileError(f"{path}: no such scene file")
    try:
        with open(path, "rb") as fh:
            return tomllib.load(fh)
    except tomllib.TOMLDecodeError as e:
        raise FileError(f"{os.path.basename(path)}: not valid TOML: {e}") from None
    except UnicodeDecodeError as e:
        raise FileError(f"{os.path.basename(path)}: not a text file ({e.reason})") from None


def _number(v):
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _pairs(v, n_min):
    return (isinstance(v, list) and len(v) >= n_min and
            all(isinstance(p, list) and len(p) == 2 and all(_number(c) and math.isfinite(c)
                                                             for c in p) for p in v))


def _is_box(v):
    return (isinstance(v, list) and len(v) == 4 and all(_number(c) and math.isfinite(c)
                                                        for c in v)
            and v[2] > v[0] and v[3] > v[1])


# units a number may be written in, as a string "<value> <unit>" (e.g. dx = "3.5 mm",
# E = "10 MPa"): unit -> (SI unit of the schema, factor to SI)
QUANTITY_UNITS = {
    "m": ("m", 1.0), "mm": ("m", 1e-3), "cm": ("m", 1e-2), "km": ("m", 1e3),
    "s": ("s", 1.0), "ms": ("s", 1e-3),
    "Pa": ("Pa", 1.0), "kPa": ("Pa", 1e3), "MPa": ("Pa", 1e6), "GPa": ("Pa", 1e9),
    "kg/m³": ("kg/m³", 1.0), "kg/m3": ("kg/m³", 1.0), "g/cm³": ("kg/m³", 1e3),
    "g/cm3": ("kg/m³", 1e3),
    "Pa s": ("Pa s", 1.0), "mPa s": ("Pa s", 1e-3),
    "m/s": ("m/s", 1.0), "mm/s": ("m/s", 1e-3), "cm/s": ("m/s", 1e-2),
    "m/s²": ("m/s²", 1.0), "m/s2": ("m/s²", 1.0),
    "N": ("N", 1.0), "kN": ("N", 1e3), "N/m": ("N/m", 1.0), "kN/m": ("N/m", 1e3),
    "MN/m": ("N/m", 1e6), "GN/m": ("N/m", 1e9),
    "Pa/m": ("Pa/m", 1.0), "1/s": ("1/s", 1.0), "Hz": ("1/s", 1.0),
}


_NUMBER_AND_UNIT = re.compile(r"\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*(.*?)\s*$")


def split_quantity(text: str):
    """(value, unit) of ``"<value> <unit>"``, the space optional ("5 mm", "5mm", "2e-3 m");
    None if it does not start with a number."""
    m = _NUMBER_AND_UNIT.fullmatch(text)
    return None if m is None else (float(m.group(1)), m.group(2))


def quantity(key, text: str) -> float:
    """``"<value> <unit>"`` in the key's SI unit; ValueError naming the unit if it measures
    something else."""
    parts = split_quantity(text)
    if any(c in text for c in "()*^") or re.search(r"\b(sin|cos|exp|pi|t)\b", text):
        raise ValueError(f"= {text!r} is an expression; a scene file takes numbers, with or "
                         f"without a unit [{key.unit}] (a motion in time: a [[kinematic]] "
                         "body's `oscillate` or `track`)")
    if parts is None:
        raise ValueError(f"= {text!r} is not a number [{key.unit}]")
    value, unit = parts
    si, f = QUANTITY_UNITS.get(unit, (None, None))
    if si != key.unit:
        allowed = [u for u, (s, _) in QUANTITY_UNITS.items() if s == key.unit]
        what = ("is missing" if not unit else f"is not a unit of {key.unit}" if key.unit
                else "is given to a pure number")
        raise ValueError(f"= {text!r}: unit {unit!r} {what}; allowed units: "
                         f"{', '.join(allowed) or 'none (write a plain number)'}")
    return value * f


def _with_units(key, v):
    """``v`` with every string inside its lists read as a quantity in ``key``'s unit
    (``["0 mm", "10 cm"]``)."""
    if isinstance(v, list):
        return [_with_units(key, c) for c in v]
    return quantity(key, v) if isinstance(v, str) and key.unit else v


def _table(name, v, keys, convert_one, optional=()):
    """A small inline table {a = …, b = …} with exactly ``keys`` and any of ``optional``,
    each converted by ``convert_one(key, value)``; ValueError naming the missing, unknown
    or bad entry."""
    form = "{" + ", ".join([f"{k} = [...]" for k in keys]
                           + [f"[{k} = ...]" for k in optional]) + "}"
    if not isinstance(v, dict):
        raise ValueError(f"must be a table {form}")
    missing = [k for k in keys if k not in v]
    unknown = sorted(set(v) - set(keys) - set(optional))
    if missing or unknown:
        what = (f"needs {', '.join(repr(k) for k in missing)}" if missing
                else f"has unknown key(s) {', '.join(repr(k) for k in unknown)}")
        raise ValueError(f"{what}: allowed a table {form}")
    out = {}
    for k in [*keys, *(k for k in optional if k in v)]:
        try:
            out[k] = convert_one(k, v[k])
        except ValueError as e:
            raise ValueError(f": {k} {e}") from None
    return out


def convert(key, v):
    """``v`` checked against ``key``'s type and range; returns the value or raises
    ValueError with what is wrong."""
    t = key.type
    unit = f" {key.unit}" if key.unit else ""
    if t in ("point", "range", "box", "polygon", "polyline", "points", "vectors", "region"):
        v = _with_units(key, v)
    if t == "float" and isinstance(v, str) and key.unit:
        v = quantity(key, v)
    if t in ("float", "int"):
        if not _number(v) or (t == "int" and not isinstance(v, int)):
            raise ValueError(f"= {v!r} is not {'an integer' if t == 'int' else 'a number'}"
                             f"{' [' + key.unit + ']' if key.unit else ''}")
        v = float(v) if t == "float" else int(v)
        if not math.isfinite(v):
            raise ValueError(f"= {v!r} is not finite")
        lo, hi = key.lo, key.hi
        bad = (lo is not None and (v <= lo if key.lo_open else v < lo)) or \
              (hi is not None and (v >= hi if key.hi_open else v > hi))
        if bad:
            raise ValueError(f"= {v!r} is out of range; allowed {key.range_text()}{unit}")
        return v
    if t == "bool":
        if not isinstance(v, bool):
            raise ValueError(f"= {v!r} is not true or false")
        return v
    if t == "str":
        if not isinstance(v, str):
            raise ValueError(f"= {v!r} is not a string")
        if key.choices and v not in key.choices:
            raise ValueError(f"= {v!r} is not a choice; allowed {key.range_text()}")
        return v
    if t == "list":
        if isinstance(v, str):
            v = [s.strip() for s in v.split(",") if s.strip()]
        if not (isinstance(v, list) and v and all(isinstance(s, str) for s in v)):
            raise ValueError(f"= {v!r} is not a list of strings")
        return v
    if t == "point":
        if not (isinstance(v, list) and len(v) == 2 and all(_number(c) and math.isfinite(c)
                                                            for c in v)):
            raise ValueError(f"= {v!r} is not a point [x, y]{' [' + key.unit + ']' if unit else ''}")
        return tuple(float(c) for c in v)
    if t == "range":
        if not (isinstance(v, list) and len(v) == 2 and all(_number(c) for c in v)
                and v[1] > v[0]):
            raise ValueError(f"= {v!r} is not a range [a, b] with a < b [{key.unit}]")
        return (float(v[0]), float(v[1]))
    if t == "box":
        if not _is_box(v):
            raise ValueError(f"= {v!r} is not a box [x0, y0, x1, y1] with x1 > x0 and "
                             f"y1 > y0 [{key.unit}]")
        return tuple(float(c) for c in v)
    if t in ("polygon", "polyline", "points"):
        n_min = {"polygon": 3, "polyline": 2, "points": 1}[t]
        if not _pairs(v, n_min):
            raise ValueError(f"is not a list of at least {n_min} points [[x, y], ...] "
                             f"[{key.unit}]")
        return [tuple(float(c) for c in p) for p in v]
    if t == "vectors":
        if isinstance(v, list) and len(v) == 2 and all(_number(c) for c in v):
            return tuple(float(c) for c in v)
        if _pairs(v, 1):
            return [tuple(float(c) for c in p) for p in v]
        raise ValueError(f"= {v!r} is not a vector [vx, vy] or a list of them [{key.unit}]")
    if t == "region":
        if _is_box(v):
            return tuple(float(c) for c in v)
        if _pairs(v, 3):
            return [tuple(float(c) for c in p) for p in v]
        if isinstance(v, list) and v and all(_is_box(r) or _pairs(r, 3) for r in v):
            return {"union": [tuple(float(c) for c in r) if _is_box(r)
                              else [tuple(float(c) for c in p) for p in r] for r in v]}
        raise ValueError(f"= {v!r} is not a region: a box [x0, y0, x1, y1], a polygon "
                         f"[[x, y], ...] or a list of them [{key.unit}]")
    if t == "radii":
        many = isinstance(v, list)
        vals = [quantity(key, c) if isinstance(c, str) else c for c in (v if many else [v])]
        if not (vals and all(_number(c) and math.isfinite(c) and c > 0 for c in vals)):
            raise ValueError(f"= {v!r} is not a positive number or a list of them [{key.unit}]")
        return tuple(float(c) for c in vals) if many else float(vals[0])
    if t in ("load", "move"):
        from .schema import Key
        kinds = {"region": Key("region", "region", "m", None, ""),
                 "force": Key("force", "point", "N", None, ""),
                 "velocity": Key("velocity", "point", "m/s", None, "")}
        keys = ("region", "force") if t == "load" else ("region", "velocity")
        return _table(key.name, v, keys, lambda k, x: convert(kinds[k], x))
    if t == "oscillate":
        from .schema import Key
        kinds = {"amplitude": Key("amplitude", "point", "m", None, ""),
                 "period": Key("period", "float", "s", None, "", lo=0.0, lo_open=True),
                 "phase": Key("phase", "float", "", None, ""),
                 "ramp": Key("ramp", "float", "s", None, "", lo=0.0)}
        return _table(key.name, v, ("amplitude", "period"), lambda k, x: convert(kinds[k], x),
                      optional=("phase", "ramp"))
    raise AssertionError(t)


#: the probe kinds each optional [[probe]] key applies to (a key given to another kind
#: would be silently ignored: refused instead)
PROBE_KEY_KINDS = {
    "body": ("displacement", "force", "bed_profile", "broken_bonds", "front"),
    "region": ("displacement", "force", "bed_profile", "broken_bonds", "front"),
    "point": ("pressure", "displacement"),
    "about": ("force",),
    "x": ("water_level",),
    "direction": ("front",),
    "above": ("front",),
    "x_range": ("bed_profile",),
    "bins": ("bed_profile",),
    "floor": ("water_level", "bed_profile"),
}


def _check_table(path, tname, raw, index=None):
    array, keys, _ = TABLES[tname]
    if not isinstance(raw, dict):
        fail(path, tname, "must be a table", index=index)
    known = {k.name: k for k in keys}
    subs = {n.split(".", 1)[1] for n in TABLES if n.startswith(tname + ".")}
    out = {}
    for k, v in raw.items():
        if k in subs:
            continue
        if k not in known:
            allowed = ", ".join(list(known) + sorted(subs))
            fail(path, tname, f"unknown key {k!r}; allowed: {allowed}", raw, index)
        try:
            out[k] = convert(known[k], v)
        except ValueError as e:
            sep = "" if str(e).startswith(":") else " "
            fail(path, tname, f"key {k!r}{sep}{e}", raw, index)
    for k in keys:
        if k.name not in out:
            if k.required:
                fail(path, tname, f"key {k.name!r} is required ({k.doc}"
                     f"{', ' + k.unit if k.unit else ''})", raw, index)
            out[k.name] = k.default
    if tname == "probe":
        for k in raw:
            kinds = PROBE_KEY_KINDS.get(k)
            if kinds and out["kind"] not in kinds:
                fail(path, tname, f"key {k!r} does not apply to kind {out['kind']!r} (it is "
                     f"for {', '.join(kinds)})", raw, index)
    return out


def read(path: str) -> dict:
    """The file as {table: dict or list of dicts}, every key checked and defaults filled;
    absent tables are absent (arrays: empty lists)."""
    raw = load_toml(path)
    top = {n.split(".")[0] for n in TABLES}
    for k in raw:
        if k not in top:
            raise FileError(f"{os.path.basename(path)}: unknown table [{k}]; allowed: "
                            f"{', '.join(sorted(top))}")
    spec = {}
    for tname, (array, _, _) in TABLES.items():
        parent, _, child = tname.partition(".")
        src = raw.get(parent)
        if child:
            if src is None:
                continue
            src = src.get(child) if isinstance(src, dict) else None
            if src is None:
                spec[tname] = []
                continue
        if src is None:
            if array:
                spec[tname] = []
            continue
        if array:
            if not isinstance(src, list):
                raise FileError(f"{os.path.basename(path)}: [{tname}] must be an array of "
                                f"tables: write [[{tname}]]")
            spec[tname] = [_check_table(path, tname, item, i) for i, item in enumerate(src)]
        else:
            if isinstance(src, list):
                raise FileError(f"{os.path.basename(path)}: [[{tname}]] must be a single "
                                f"table: write [{tname}]")
            spec[tname] = _check_table(path, tname, src)
    if "scene" not in spec:
        raise FileError(f"{os.path.basename(path)}: table [scene] is required (t_end)")
    return spec
