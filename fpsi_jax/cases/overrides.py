"""``--set key=value`` overrides, shared by ``fpsi run`` and ``fpsi validate``.

A key is looked up, in order, among the scene builder's keyword arguments, the leaves of its
Params (``mu`` or ``sph.mu``) and the Physics options. Unknown keys and bad values raise
ParameterError before anything is compiled or written.
"""
from __future__ import annotations

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
    return scene, apply(scene, rest, f"scene {scene_name!r}",
                        f"scene parameters {', '.join(keys)}; ")


def known_to(scene):
    """``known(key)`` for :func:`apply` on a built ``scene``: ``dt``, a Physics option or a
    Params leaf (bare, even if ambiguous, or dotted)."""
    names = scene.params.names()
    leaves = {n.split(".")[-1] for n in names}
    return lambda k: k == "dt" or k in Physics.OPTIONS or k in names or k in leaves


def apply(scene, overrides: dict, what: str, also: str = "") -> dict:
    """Apply ``overrides`` that are not builder keywords to a built ``scene``: ``dt``, Params
    leaves (``mu`` or ``sph.mu``) and Physics options (returned, checked). ``what`` names
    the scene in errors; ``also`` lists what else would have been allowed."""
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
                in_file = ("; the scene's own keys (its [fluid] dx, a structure's E, …) "
                           "are set in the file" if what.startswith("scene file") else "")
                raise ParameterError(
                    f"unknown key {k!r} for {what}{in_file}; allowed: {also}params "
                    f"{', '.join(params.names())}; physics options "
                    f"{', '.join(Physics.OPTIONS)}") from None
            raise
    scene.params = params
    Physics.for_scene(scene, **phys_opts)   # validate the options now
    return phys_opts
