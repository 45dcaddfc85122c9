"""The registry of validation cases: each case is a function ``(quick, overrides) ->
list[Record]`` registered with :func:`register`, with its reference data in
``fpsi_jax/data`` (:func:`load_csv`)."""
from __future__ import annotations

import importlib.resources
from dataclasses import asdict, dataclass
from typing import Callable

import numpy as np


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


CASES: dict[str, Callable] = {}
DESCRIPTIONS: dict[str, str] = {}


def register(name: str, description: str):
    def deco(fn):
        CASES[name] = fn
        DESCRIPTIONS[name] = description
        return fn
    return deco


def data_path(name: str):
    return importlib.resources.files("fpsi_jax") / "data" / name


def load_csv(name: str) -> np.ndarray:
    with data_path(name).open() as fh:
        return np.loadtxt(fh, delimiter=",", skiprows=1)
