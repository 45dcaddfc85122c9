"""Scene files: your own case described in TOML, with SI units, and run with
``fpsi run my_case.toml`` (or ``fpsi calibrate my_case.toml --data measured.csv``).

    from fpsi_jax import scenefile
    case = scenefile.load("examples/elastic_gate.toml")
    res = simulate(case.scene, probes=case.probes)

A file has one table per part of the scene: ``[scene]`` (time, gravity, domain),
``[fluid]`` with ``[[fluid.region]]`` bodies of water, ``[tank]``, ``[[obstacle]]`` fixed
bodies, disc bodies (``[[structure]]`` bonded, ``[[grains]]``, ``[[discs]]``,
``[[kinematic]]`` moving at a prescribed velocity), ``[contacts]``, ``[bonds]``, ``[fpi]``,
``[physics]`` options, ``[output]``, ``[[probe]]`` measurements and ``[calibration]``
defaults. Every key, its unit and default: docs/scene-file.md (generated from
:mod:`.schema`). A bad file is refused with one line naming the file, the table and the key,
before anything is compiled.
"""
from __future__ import annotations

from .compose import GROUPS, SceneFile, compose
from .reader import FileError, read


def load(path: str) -> SceneFile:
    """Read, check and build the scene file at ``path``."""
    return compose(read(path), path)


__all__ = ["GROUPS", "FileError", "SceneFile", "compose", "load", "read"]
