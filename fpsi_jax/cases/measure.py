"""Measurements several cases share: the zero crossings of a sampled signal (contact
times, vibration periods) and a run that records the mean displacement of some discs."""
from __future__ import annotations

import time

import numpy as np

from ..run import observers
from ..run.driver import simulate


def crossings(t, y, rising=False):
    """Times where y crosses 0 downwards (upwards if ``rising``), linearly interpolated."""
    s = np.sign(y)
    k = np.where((s[:-1] < 0) & (s[1:] >= 0) if rising else (s[:-1] > 0) & (s[1:] <= 0))[0]
    return t[k] + (t[k + 1] - t[k]) * y[k] / (y[k] - y[k + 1])


def displacement_run(scene, phys, discs, axis=1):
    """Run ``scene`` (Physics options ``phys``) observing the mean displacement along
    ``axis`` of the discs ``discs`` (indices or a mask) every step; returns
    (displacements, result, wall seconds)."""
    t0 = time.perf_counter()
    res = simulate(scene, progress=False, **phys,
                   observe=observers.mean_displacement(scene.solid.x, discs, axis))
    return np.asarray(res.observations), res, time.perf_counter() - t0
