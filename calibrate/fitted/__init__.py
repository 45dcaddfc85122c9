"""Fitted parameter values, each with the data it was fitted to (a value tuned to one
case's data lives here, never as a model default).

    from calibrate import fitted
    from fpsi_jax import cases
    rec = fitted.load("elastic_gate_coarse")       # dict: values, scene keywords, data, …
    scene = cases.build("elastic_gate", **rec["scene_kwargs"])

Files are JSON beside this module, written by the experiment that fitted them.
"""
from __future__ import annotations

import json
import os

HERE = os.path.dirname(os.path.abspath(__file__))


def names() -> list[str]:
    return sorted(f[:-5] for f in os.listdir(HERE) if f.endswith(".json"))


def load(name: str) -> dict:
    path = os.path.join(HERE, f"{name}.json")
    if not os.path.exists(path):
        from fpsi_jax.model.errors import ParameterError
        raise ParameterError(f"no fitted record {name!r}; known: {', '.join(names())}")
    with open(path) as fh:
        return json.load(fh)


def record(name: str, rec: dict) -> str:
    path = os.path.join(HERE, f"{name}.json")
    with open(path, "w") as fh:
        json.dump(rec, fh, indent=1, default=float)
    return path
