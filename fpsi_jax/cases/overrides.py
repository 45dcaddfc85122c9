"""``--set key=value`` overrides, shared by ``fpsi run`` and ``fpsi validate``.

A key is looked up, in order, among the scene builder's keyword arguments, the leaves of its
Params (``mu`` or ``sph.mu``) and the Physics options. Unknown keys and bad values raise
ParameterError before anything is compiled or written.
"""
from __future__ import annotations

import difflib
import enum
import inspect
import json

from . import registry
from ..model.config import Physics
from ..model.errors import ParameterError


def parse_value(text: str):
    """A ``--set`` value: true/false (on/off, yes/no), none, a JSON number, list or string,
    nan/inf as floats (refused later as not finite), anything else the text itself."""
    low = text.strip().lower()
    if low in ("true", "on", "yes"):
        return True
    if low in ("false", "off", "no"):
        return False
    if low in ("none", "null"):
        return None
    if low in ("nan", "inf", "+inf", "-inf", "infinity", "-infinity"):
        return float(low)                    # refused as not finite, by name
    try:
        return json.loads(text)
    except ValueError:
        return text


def parse_pairs(pairs) -> dict:
    out = {}
    for item in pairs or []:
        if "=" not in item:
            raise ParameterError(f"--set expects key=value, got {item!r}")
        k, v = item.split("=", 1)
        out[k.strip()] = parse_value(v)
    return out


def build(scene_name: str, overrides: dict, base: dict | None = None):
    """Build ``scene_name`` with ``base`` then ``overrides`` applied.
    Returns (scene, physics_overrides)."""
    keys = registry.builder_keys(scene_name)
    kw = dict(base or {})
    rest = {}
    for k, v in overrides.items():
        (kw if k in keys else rest)[k] = v
    scene = registry.build(scene_name, **kw)
    return scene, apply(scene, rest, f"scene {scene_name!r}", keys, scene_name)


#: Physics options the run's set-up derives unless the scene sets them
DERIVED_AT_SETUP = ("dem_substeps",)

#: a scene file's key -> the Params leaf it sets, where --set on the leaf does what the
#: key does (not density, sound speed or gravity: the start's hydrostatic densities and
#: masses are built from them)
FILE_KEYS = {"friction": "dem.mu", "rolling_friction": "dem.mu_roll", "beta_n": "dem.beta_n",
             "viscosity": "sph.mu"}


def unknown_key(key: str, what: str, scene_keys, params, listing: str) -> ParameterError:
    """The one-line error for a ``--set`` key that nothing takes: the nearest keys it may
    have meant (:func:`difflib.get_close_matches`) and the command that lists them all."""
    names = params.names() if params is not None else []
    known = dict.fromkeys([*scene_keys, "dt", *names, *(n.split(".")[-1] for n in names),
                           *Physics.OPTIONS])
    near = difflib.get_close_matches(key, list(known), n=3, cutoff=0.6)
    leaf = FILE_KEYS.get(key)
    if leaf is not None and leaf in names:
        near = [leaf]
    hint = f"did you mean {' or '.join(map(repr, near))}? " if near else ""
    return ParameterError(f"unknown key {key!r} for {what}; {hint}`fpsi list {listing}` "
                          "lists the keys it takes")


def key_table(scene, scene_name: str | None = None) -> list[str]:
    """The keys ``--set`` takes for a built ``scene``, one per line with its value, for
    ``fpsi list NAME``: the builder's keywords (a registered scene), ``dt``, the Params
    leaves and the Physics options with their defaults (or the scene's own setting)."""
    lines = []
    if scene_name is not None:
        sig = inspect.signature(registry.get(scene_name)).parameters
        lines.append("scene parameters (the scene is rebuilt with them):")
        lines += [f"  {k:28s} {p.default!r}" for k, p in sig.items()]
    lines.append("parameters (Params leaves; a bare name where it is unambiguous):")
    for k, v in scene.params.flat().items():
        if k == "dt":
            given = "the stability bound" if scene.dt is None else f"{scene.dt:g}"
            lines.append(f"  {k:28s} {given} (the step asked for; a larger one than the "
                         "bound is refused)")
        else:
            lines.append(f"  {k:28s} {_value(v)}")
    lines.append("physics options (static; each recompiles the step):")
    phys = Physics.for_scene(scene)
    for k in Physics.OPTIONS:
        v = getattr(phys, k, scene.options.get(k, "derived from the scene"))
        if k in DERIVED_AT_SETUP and k not in scene.options:
            v = "derived from the step bounds"
        kind = Physics.CHOICES.get(k)
        choices = f"  [{', '.join(m.value for m in kind)}]" if kind is not None else ""
        lines.append(f"  {k:28s} {_value(v)}{choices}")
    return lines


def _value(v) -> str:
    if isinstance(v, bool):
        return str(v).lower()
    if isinstance(v, enum.Enum):
        return repr(v.value)
    if isinstance(v, str):
        return v
    if isinstance(v, tuple) and (len(v) > 4 or not all(isinstance(e, (int, float))
                                                        for e in v)):
        return f"({len(v)} entries set by the scene)"
    try:
        return f"{float(v):g}"
    except (TypeError, ValueError):
        return repr(v)


def known_to(scene):
    """``known(key)`` for :func:`apply` on a built ``scene``: ``dt``, a Physics option or a
    Params leaf (bare, even if ambiguous, or dotted)."""
    names = scene.params.names()
    leaves = {n.split(".")[-1] for n in names}
    return lambda k: k == "dt" or k in Physics.OPTIONS or k in names or k in leaves


def apply(scene, overrides: dict, what: str, scene_keys=(), listing: str = "") -> dict:
    """Apply ``overrides`` that are not builder keywords to a built ``scene``: ``dt``, Params
    leaves (``mu`` or ``sph.mu``) and Physics options (returned, checked). ``what`` names
    the scene in errors, ``scene_keys`` are the builder keywords that were also allowed and
    ``fpsi list {listing}`` lists every key."""
    phys_opts = {}
    params = scene.params
    for k, v in overrides.items():
        if k == "dt":                      # the step asked for; setup checks it
            if not (isinstance(v, (int, float)) and not isinstance(v, bool) and v > 0):
                raise ParameterError(f"dt = {v!r} out of range; allowed (0, bound] s")
            scene.dt = float(v)
            continue
        if k in Physics.OPTIONS:
            phys_opts[k] = v
            continue
        if k in ("dp", "sph.dp") and params.sph is not None:
            raise ParameterError(
                f"{k} is the fluid spacing the scene was built with ({float(params.sph.dp):g} m; "
                "the particles' masses and lattice follow it): set the scene's dx instead "
                "(--set dx=… for a registered scene, [fluid] dx in a scene file)")
        try:
            params = params.set(k, v)
        except ParameterError as e:
            if "unknown parameter" in str(e):
                in_file = (" (the scene's own keys, its [fluid] dx or a structure's E, are "
                           "set in the file)" if what.startswith("scene file") else "")
                raise unknown_key(k, what + in_file, scene_keys, params,
                                  listing or "SCENE") from None
            raise
    scene.params = params
    Physics.for_scene(scene, **phys_opts)   # validate the options now
    return phys_opts
