"""Prescribed motions of kinematic disc groups (Physics.kinematic_motion).

A kinematic disc moves at a velocity the scene prescribes, whatever the forces on it: a
gate lifted at a constant speed, a piston wave maker, a platen. Each motion names
a contiguous group of held discs a … b − 1 and prescribes the displacement X(t) of the
whole group from where it was built. Each DEM sub-step [t, t + Δt] moves the group at
its mean velocity over the sub-step, (X(t + Δt) − X(t))/Δt (:func:`mean_velocity`;
stages.scheduled), so the group is where X puts it at every sub-step's end, to
round-off, whatever the sub-step's length (the midpoint rule, V at the middle, gave a
wave maker's stroke 0.1 % too long at 41 steps a period, and a track's corner a
displacement error of ½ΔV Δt each). The mean is formed from the sub-step's length and
the trigonometric difference formulas, not as the difference of two X at large float32
times (at t = 10 s float32 resolves 1 µs, a tenth of a small sub-step).

Three kinds, each a NamedTuple of plain numbers (hashable: Physics is static):

* :class:`Window` — (vx, vy) while t_on ≤ t < t_off, at rest otherwise;
* :class:`Oscillation` — a sinusoidal stroke X(τ) = r(τ) A (sin(ωτ + φ) − sin φ),
  τ = t − t_on, ω = 2π/T, with a half-cosine ramp r(τ) = ½(1 − cos(πτ/T_r)) over the
  first T_r (DualSPHysics' rectilinear sinusoidal motion; the ramp spares the fluid the
  jump in acceleration of a paddle started at full stroke), V = dX/dt exactly;
* :class:`Track` — a displacement time series (t_i, x_i, y_i) followed piecewise
  linearly: V = (x_{i+1} − x_i, y_{i+1} − y_i)/(t_{i+1} − t_i) on [t_i, t_{i+1}), at
  rest before the first row and after the last (a piston stroke from a wave-maker
  transfer function, a measured gate opening; DualSPHysics' motion from a file).
"""
from __future__ import annotations

import math
from typing import NamedTuple

import jax.numpy as jnp
import numpy as np

from .errors import ParameterError


class Window(NamedTuple):
    """Discs a … b − 1 move at (vx, vy) while t_on ≤ t < t_off and stand otherwise."""
    a: int
    b: int
    vx: float
    vy: float
    t_on: float = 0.0
    t_off: float = math.inf


class Oscillation(NamedTuple):
    """Discs a … b − 1 follow X(τ) = r(τ) A (sin(ωτ + φ) − sin φ), τ = t − t_on,
    A = (ax, ay) the stroke's amplitude [m], ω = 2π/``period``, φ = ``phase`` [rad], r a
    half-cosine ramp over the first ``ramp`` seconds (0: none), from t_on to t_off (they
    stand outside it)."""
    a: int
    b: int
    ax: float
    ay: float
    period: float
    phase: float = 0.0
    ramp: float = 0.0
    t_on: float = 0.0
    t_off: float = math.inf


class Track(NamedTuple):
    """Discs a … b − 1 follow the displacement (x_i, y_i) [m] at times t_i [s] (tuples,
    t strictly increasing), piecewise linearly; they stand before t_0 and after t_last.
    The displacement is counted from the first row (the group is built where t_0 puts
    it)."""
    a: int
    b: int
    t: tuple
    x: tuple
    y: tuple


def _segments(m: Track):
    """A track's row times (n,) and the velocity of each segment between rows (n − 1, 2)."""
    ts = np.asarray(m.t, float)
    return ts, np.stack([np.diff(m.x), np.diff(m.y)], axis=1) / np.diff(ts)[:, None]


def _ramp(tau, ramp):
    """r(τ) = ½(1 − cos(πτ/T_r)) for τ < T_r, else 1, with dr/dτ and d²r/dτ²."""
    if ramp <= 0.0:
        return jnp.ones_like(tau), jnp.zeros_like(tau), jnp.zeros_like(tau)
    s = jnp.clip(tau / ramp, 0.0, 1.0)
    k = math.pi / ramp
    r = 0.5 * (1.0 - jnp.cos(jnp.pi * s))
    dr = jnp.where(s < 1.0, 0.5 * k * jnp.sin(jnp.pi * s), 0.0)
    ddr = jnp.where(s < 1.0, 0.5 * k * k * jnp.cos(jnp.pi * s), 0.0)
    return r, dr, ddr


def velocity(m, t, dtype=jnp.float32):
    """The group's prescribed velocity (2,) at time ``t`` (a traced scalar) under motion
    ``m`` (:class:`Window`, :class:`Oscillation` or :class:`Track`)."""
    t = jnp.asarray(t, dtype)
    zero = jnp.zeros(2, dtype)
    if isinstance(m, Window):
        on = (t >= m.t_on) & (t < m.t_off)
        return jnp.where(on, jnp.asarray([m.vx, m.vy], dtype), zero)
    if isinstance(m, Oscillation):
        on = (t >= m.t_on) & (t < m.t_off)
        tau = jnp.maximum(t - m.t_on, 0.0)
        w = 2.0 * math.pi / m.period
        r, dr, _ = _ramp(tau, m.ramp)
        rate = dr * (jnp.sin(w * tau + m.phase) - math.sin(m.phase)) \
            + r * w * jnp.cos(w * tau + m.phase)
        return jnp.where(on, rate * jnp.asarray([m.ax, m.ay], dtype), zero)
    if isinstance(m, Track):
        ts, slopes = _segments(m)
        k = jnp.searchsorted(jnp.asarray(ts, dtype), t, side="right") - 1
        inside = (k >= 0) & (k < len(ts) - 1)
        v = jnp.asarray(slopes, dtype)[jnp.clip(k, 0, len(ts) - 2)]
        return jnp.where(inside, v, zero)
    raise TypeError(f"not a motion: {m!r}")


def acceleration(m, t, dtype=jnp.float32):
    """The group's prescribed acceleration (2,) at time ``t``: what a moving wall adds to
    the pressure the fluid extrapolates onto it (Adami et al. 2012: g − a_w). A window's
    is 0 (its jumps in velocity are not resolved); an oscillation's d²X/dt² exactly; a
    track's the change of slope at each row over half the two segments, (s_i − s_{i−1}) /
    ((t_{i+1} − t_{i−1})/2), interpolated linearly between rows (0 outside them)."""
    t = jnp.asarray(t, dtype)
    if isinstance(m, Window):
        return jnp.zeros(2, dtype)
    if isinstance(m, Oscillation):
        on = (t >= m.t_on) & (t < m.t_off)
        tau = jnp.maximum(t - m.t_on, 0.0)
        w = 2.0 * math.pi / m.period
        s = jnp.sin(w * tau + m.phase) - math.sin(m.phase)
        ds = w * jnp.cos(w * tau + m.phase)
        dds = -w * w * jnp.sin(w * tau + m.phase)
        r, dr, ddr = _ramp(tau, m.ramp)
        rate = ddr * s + 2.0 * dr * ds + r * dds
        return jnp.where(on, rate * jnp.asarray([m.ax, m.ay], dtype), jnp.zeros(2, dtype))
    if isinstance(m, Track):
        ts, slopes = _segments(m)
        s = np.vstack([np.zeros((1, 2)), slopes, np.zeros((1, 2))])     # at rest outside
        half = 0.5 * (np.diff(np.concatenate([ts[:1], ts, ts[-1:]]))[:-1]
                      + np.diff(np.concatenate([ts[:1], ts, ts[-1:]]))[1:])
        acc = np.diff(s, axis=0) / np.maximum(half, 1e-300)[:, None]    # at each row
        tj = jnp.asarray(ts, dtype)
        inside = (t >= tj[0]) & (t <= tj[-1])
        out = jnp.stack([jnp.interp(t, tj, jnp.asarray(acc[:, c], dtype)) for c in (0, 1)])
        return jnp.where(inside, out, jnp.zeros(2, dtype))
    raise TypeError(f"not a motion: {m!r}")


def _overlap(t0, dt, lo, hi):
    """The length of [t0, t0 + dt] ∩ [lo, hi], formed from ``dt`` so that a sub-step
    wholly inside has exactly ``dt`` (lo may be −inf, hi inf)."""
    return jnp.clip(dt - jnp.maximum(lo - t0, 0.0) - jnp.maximum(t0 + dt - hi, 0.0), 0.0, dt)


def mean_velocity(m, t0, dt, dtype=jnp.float32):
    """The group's mean velocity (2,) over the sub-step [t0, t0 + ``dt``] under motion
    ``m``: (X(t0 + dt) − X(t0))/dt, what moves it exactly along X (module docstring)."""
    t0 = jnp.asarray(t0, dtype)
    dt = jnp.asarray(dt, dtype)
    if isinstance(m, Window):
        frac = _overlap(t0, dt, m.t_on, m.t_off) / dt
        return frac * jnp.asarray([m.vx, m.vy], dtype)
    if isinstance(m, Oscillation):
        w = 2.0 * math.pi / m.period
        tau0 = jnp.clip(t0 - m.t_on, 0.0, m.t_off - m.t_on)
        dtau = _overlap(t0, dt, m.t_on, m.t_off)
        tau1 = tau0 + dtau
        s0, s1 = (jnp.sin(w * tau + m.phase) - math.sin(m.phase) for tau in (tau0, tau1))
        ds = 2.0 * jnp.cos(w * (tau0 + 0.5 * dtau) + m.phase) * jnp.sin(0.5 * w * dtau)
        if m.ramp > 0.0:
            a0, a1 = (jnp.clip(tau / m.ramp, 0.0, 1.0) for tau in (tau0, tau1))
            r0, r1 = (0.5 * (1.0 - jnp.cos(jnp.pi * a)) for a in (a0, a1))
            dr = jnp.sin(0.5 * jnp.pi * (a0 + a1)) * jnp.sin(0.5 * jnp.pi * (a1 - a0))
            dx = 0.5 * (r0 + r1) * ds + 0.5 * (s0 + s1) * dr
        else:
            dx = ds
        return dx / dt * jnp.asarray([m.ax, m.ay], dtype)
    if isinstance(m, Track):
        ts, slopes = _segments(m)
        frac = _overlap(t0, dt, jnp.asarray(ts[:-1], dtype), jnp.asarray(ts[1:], dtype)) / dt
        return frac @ jnp.asarray(slopes, dtype)
    raise TypeError(f"not a motion: {m!r}")


def displacement(m, t) -> np.ndarray:
    """The group's prescribed displacement (2,) from where it was built, at time ``t``
    (host-side numpy; what the sub-steps' midpoint rule follows)."""
    if isinstance(m, Window):
        return np.array([m.vx, m.vy]) * (min(max(t, m.t_on), m.t_off) - m.t_on)
    if isinstance(m, Oscillation):
        tau = min(max(t, m.t_on), m.t_off) - m.t_on
        r = 1.0 if m.ramp <= 0 or tau >= m.ramp else 0.5 * (1 - math.cos(math.pi * tau / m.ramp))
        w = 2.0 * math.pi / m.period
        return r * np.array([m.ax, m.ay]) * (math.sin(w * tau + m.phase) - math.sin(m.phase))
    if isinstance(m, Track):
        return np.array([np.interp(t, m.t, m.x) - m.x[0], np.interp(t, m.t, m.y) - m.y[0]])
    raise TypeError(f"not a motion: {m!r}")


def _finite(*vals):
    return all(isinstance(v, (int, float, np.integer, np.floating)) and math.isfinite(v)
               for v in vals)


def canonical(m, n: int, fixed) -> Window | Oscillation | Track:
    """One entry of ``Physics.kinematic_motion`` checked against the scene (``n`` discs,
    ``fixed`` their held mask) and returned as its NamedTuple; a plain 6-tuple (a, b, vx,
    vy, t_on, t_off) is a :class:`Window`, lists read back from JSON are taken by their
    kind's length (9: Oscillation, 5: Track). Raises ParameterError naming what is
    wrong."""
    def bad(what):
        raise ParameterError(f"kinematic_motion entry {m!r}: {what}")

    if isinstance(m, (Window, Oscillation, Track)):
        kind = type(m)
    elif isinstance(m, (tuple, list)):
        kind = {6: Window, 9: Oscillation, 5: Track}.get(len(m))
        if kind is None:
            bad("allowed (a, b, vx, vy, t_on, t_off), a motion.Oscillation or a motion.Track")
        m = kind(*m)
    else:
        bad("allowed (a, b, vx, vy, t_on, t_off), a motion.Oscillation or a motion.Track")
    a, b = m.a, m.b
    if not (isinstance(a, (int, np.integer)) and isinstance(b, (int, np.integer))
            and 0 <= a < b <= n and bool(np.all(np.asarray(fixed, bool)[a:b]))):
        bad(f"discs a … b − 1 must be held discs, 0 <= a < b <= {n}")
    if kind is Window:
        if not (_finite(m.vx, m.vy, m.t_on) and float(m.t_on) < float(m.t_off)):
            bad("allowed finite vx, vy and t_on < t_off (t_off may be inf)")
        return Window(int(a), int(b), float(m.vx), float(m.vy), float(m.t_on), float(m.t_off))
    if kind is Oscillation:
        if not (_finite(m.ax, m.ay, m.period, m.phase, m.ramp, m.t_on) and m.period > 0
                and m.ramp >= 0 and float(m.t_on) < float(m.t_off)):
            bad("allowed finite amplitude and phase, period > 0, ramp >= 0, t_on < t_off")
        return Oscillation(int(a), int(b), *(float(v) for v in m[2:]))
    ts, xs, ys = (tuple(float(v) for v in np.ravel(np.asarray(c, float))) for c in m[2:])
    if not (len(ts) >= 2 and len(xs) == len(ts) == len(ys) and np.all(np.isfinite(ts + xs + ys))
            and np.all(np.diff(ts) > 0) and ts[0] >= 0):
        bad("a track needs >= 2 rows of finite (t, x, y) with t >= 0 strictly increasing")
    return Track(int(a), int(b), ts, xs, ys)
