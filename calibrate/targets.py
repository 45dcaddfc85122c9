"""Targets: reference data turned into differentiable residuals.

Every target reads the per-step observations of a :class:`~calibrate.rollout.Problem`
(here the displacement u = (u_x, u_y) of a tracked point, shape (n_steps, 2)) and returns
a residual vector r(u) in jnp; the loss of a fit is Σ_targets w·mean(r²), and the
Gauss–Newton standard errors use the Jacobian of the stacked residuals.

* :class:`StaticDeflection`  the mean of one component over the last part of a damped run
  against a value (Euler–Bernoulli δ = PL³/3EI for the cantilever): r = ū/u* − 1.
* :class:`FreeVibration`  damped frequency and decay of a free vibration, measured as an
  experimentalist would: zero crossings (linearly interpolated between steps) give the
  half periods, the largest |u| between successive crossings gives the peaks, and
  least squares over the crossings and log-peaks give f_d and the logarithmic decrement
  δ per half cycle; ζ = δ/√(π² + δ²), f_n = f_d/√(1 − ζ²). r = log(f_n/f*), log(ζ/ζ*).
  Which crossing falls in which step is piecewise constant, so the gradient flows
  through the interpolated crossing times and the peak values (exact to O(Δt²)).
* :class:`Trajectory`  a sampled curve (e.g. the gate's tip u_x, u_y from the experiment)
  interpolated at the reference times inside a window: r = (u(t_k) − u*_k)/scale.
* :class:`WindowMean`  the mean of each measured component over a time window (a static
  state reached at the end of a damped run) against the mean of the data there:
  r = (ū − ū*)/s with s = |ū*| (or the data's largest |value| when ū* = 0).

A measured curve is compared where it was sampled: the simulation, recorded after every
step, is interpolated linearly at the data's times (the value at t = 0 being the
observation of the initial state), so a free vibration measured from the data and from the
simulation sees the same sampling.
"""
from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np

from fpsi_jax.model.errors import ParameterError


def _window(times, t0, t1):
    t = np.asarray(times)
    return (t >= (t0 if t0 is not None else -np.inf)) & (t <= (t1 if t1 is not None
                                                                   else np.inf))


@dataclasses.dataclass(frozen=True)
class StaticDeflection:
    """Mean of component ``component`` of u over the last ``tail`` fraction of the run
    against ``value``."""

    value: float
    component: int = 1
    tail: float = 0.1
    weight: float = 1.0
    name: str = "static_deflection"

    def measure(self, times, u):
        n = u.shape[0]
        k = max(1, int(round(self.tail * n)))
        return jnp.mean(u[n - k:, self.component])

    def residuals(self, times, u):
        return jnp.atleast_1d(self.measure(times, u) / self.value - 1.0)

    def report(self, times, u) -> dict:
        m = float(self.measure(times, jnp.asarray(u)))
        return {"quantity": "static deflection [m]", "value": m, "reference": self.value,
                "rel_error": m / self.value - 1.0}


def interpolate(t_query, times, u, initial=None):
    """u (n, c) recorded at ``times`` (after each step), linearly interpolated at
    ``t_query``; ``initial`` (c,) is the value at t = 0 (default zeros, a displacement)."""
    u = jnp.asarray(u)
    u0 = (jnp.zeros((1, u.shape[1]), u.dtype) if initial is None
          else jnp.asarray(initial, u.dtype).reshape(1, -1))
    tt = jnp.concatenate([jnp.zeros(1, u.dtype), jnp.asarray(times, u.dtype)])
    uu = jnp.concatenate([u0, u])
    tq = jnp.asarray(t_query, u.dtype)
    return jnp.stack([jnp.interp(tq, tt, uu[:, c]) for c in range(u.shape[1])], axis=1)


def free_vibration(times, y, max_crossings: int = 64, skip: int = 0):
    """(f_n [Hz], ζ, number of half cycles used) of the free vibration y(t) (jnp,
    differentiable), sampled at increasing ``times`` (uniform or not). ``skip`` drops the
    first crossings (an initial transient)."""
    times = jnp.asarray(times)
    s = jnp.sign(y)
    cross = (s[:-1] * s[1:]) < 0                        # a crossing between k and k + 1
    k = jnp.nonzero(cross, size=max_crossings, fill_value=0)[0]
    n = jnp.minimum(jnp.sum(cross), max_crossings)
    y0, y1 = y[k], y[k + 1]
    tc = times[k] + (times[k + 1] - times[k]) * y0 / (y0 - y1)
    valid = (jnp.arange(max_crossings) < n) & (jnp.arange(max_crossings) >= skip)
    # half cycle m lies between crossings m and m + 1
    seg = jnp.cumsum(jnp.concatenate([jnp.zeros(1, jnp.int32), cross.astype(jnp.int32)]))
    peaks = jax.ops.segment_max(jnp.abs(y), seg, num_segments=max_crossings + 1)[1:]
    pvalid = valid & (jnp.arange(max_crossings) + 1 < n)
    idx = jnp.arange(max_crossings, dtype=y.dtype)

    def slope(xv, yv, w):
        w = w.astype(yv.dtype)
        sw = jnp.sum(w)
        xm, ym = jnp.sum(w * xv) / sw, jnp.sum(w * yv) / sw
        return jnp.sum(w * (xv - xm) * (yv - ym)) / jnp.sum(w * (xv - xm) ** 2)

    half_period = slope(idx, tc, valid)
    delta = -slope(idx, jnp.log(jnp.where(pvalid, peaks, 1.0)), pvalid)
    zeta = delta / jnp.sqrt(jnp.pi ** 2 + delta ** 2)
    f_n = 1.0 / (2.0 * half_period) / jnp.sqrt(1.0 - zeta ** 2)
    return f_n, zeta, jnp.sum(pvalid)


@dataclasses.dataclass(frozen=True)
class FreeVibration:
    """Frequency and/or damping ratio of the free vibration of component ``component``.
    Either reference may be None (not fitted). Needs ≥ 3 half cycles in the run."""

    frequency: float | None = None
    damping_ratio: float | None = None
    component: int = 1
    max_crossings: int = 64
    skip: int = 0
    weight: float = 1.0
    name: str = "free_vibration"
    t_ref: tuple | None = None
    initial: tuple | None = None

    def measure(self, times, u):
        """(f_n, ζ, half cycles) of the simulated component: at every step, or, with
        ``t_ref``, at those sample times (a measured curve's, see :meth:`from_data`)."""
        if self.t_ref is None:
            return free_vibration(times, u[:, self.component], self.max_crossings, self.skip)
        y = interpolate(self.t_ref, times, u, self.initial)[:, self.component]
        return free_vibration(jnp.asarray(self.t_ref, y.dtype), y, self.max_crossings,
                              self.skip)

    @classmethod
    def from_data(cls, t, y, component: int, initial=None, fit=("frequency",
                                                                  "damping_ratio"), **kw):
        """The target a measured curve y(t) (samples at ``t`` > 0) defines: its frequency
        and damping ratio, measured the same way as the simulation's at the same times.
        ``fit`` names the references kept."""
        t = np.asarray(t, float)
        f, z, n = free_vibration(jnp.asarray(t), jnp.asarray(np.asarray(y, float)),
                                 kw.get("max_crossings", 64), kw.get("skip", 0))
        if int(n) < 2:
            raise ValueError(f"only {int(n)} complete half cycles of the free vibration in "
                             "the window; a frequency and a damping ratio need at least 2")
        return cls(frequency=float(f) if "frequency" in fit else None,
                   damping_ratio=float(z) if "damping_ratio" in fit else None,
                   component=component, t_ref=tuple(map(float, t)),
                   initial=None if initial is None else tuple(map(float, initial)), **kw)

    def residuals(self, times, u):
        f, z, _ = self.measure(times, u)
        r = []
        if self.frequency is not None:
            r.append(jnp.log(f / self.frequency))
        if self.damping_ratio is not None:
            r.append(jnp.log(z / self.damping_ratio))
        return jnp.stack(r)

    @classmethod
    def from_signal(cls, times, u, **kw):
        """The target a synthetic run's own frequency and damping ratio define."""
        c = cls(**{k: v for k, v in kw.items() if k in ("component", "max_crossings",
                                                        "skip", "weight", "name")})
        f, z, n = c.measure(times, jnp.asarray(u))
        if int(n) < 2:
            raise ValueError(f"free vibration: only {int(n)} complete half cycles; run longer")
        return dataclasses.replace(c, frequency=float(f), damping_ratio=float(z))

    def report(self, times, u) -> dict:
        f, z, n = (float(a) for a in self.measure(times, jnp.asarray(u)))
        out = {"quantity": "free vibration", "frequency_hz": f, "damping_ratio": z,
               "half_cycles": int(n)}
        if self.frequency is not None:
            out.update(frequency_ref=self.frequency, frequency_rel_error=f / self.frequency - 1)
        if self.damping_ratio is not None:
            out.update(damping_ratio_ref=self.damping_ratio,
                       damping_ratio_rel_error=z / self.damping_ratio - 1)
        return out


@dataclasses.dataclass(frozen=True)
class Trajectory:
    """Reference samples ``values`` (m, c) at ``t_ref`` of the components ``components``,
    compared inside ``window`` = (t0, t1) after dividing by ``scale`` (one per component;
    default: the largest |value| of each)."""

    t_ref: tuple
    values: tuple
    components: tuple = (0, 1)
    window: tuple = (None, None)
    scale: tuple | None = None
    weight: float = 1.0
    name: str = "trajectory"
    initial: tuple | None = None

    def __post_init__(self):
        v = np.asarray(self.values, float)
        if not np.all(np.isfinite(v)):
            raise ParameterError(f"{self.name}: the reference values contain NaN or inf")
        scale = self._scale()
        if np.any(~np.isfinite(scale) | (scale <= 0)):
            k = int(np.argmax(~np.isfinite(scale) | (scale <= 0)))
            raise ParameterError(
                f"{self.name}: component {k} of the reference is zero everywhere, so it has "
                "no scale to compare against; give its scale (or fit another component)")

    def _sel(self, times):
        t = np.asarray(self.t_ref, float)
        tmax = float(np.asarray(times)[-1])
        inside = _window(t, *self.window) & (t <= tmax + 1e-12) & (t > 0)
        if not inside.any():
            raise ValueError(f"{self.name}: no reference sample inside the window "
                             f"{self.window} and the run (t ≤ {tmax:.4g} s)")
        return inside

    def _scale(self):
        v = np.asarray(self.values, float)
        return (np.max(np.abs(v), axis=0) if self.scale is None
                else np.asarray(self.scale, float))

    def sample(self, times, u):
        """The simulated components at the reference times inside the window (m, c)."""
        inside = self._sel(times)
        tq = np.asarray(self.t_ref, float)[inside]
        return interpolate(tq, times, u, self.initial)[:, list(self.components)]

    def residuals(self, times, u):
        inside = self._sel(times)
        ref = jnp.asarray(np.asarray(self.values, float)[inside], u.dtype)
        return ((self.sample(times, u) - ref) / jnp.asarray(self._scale(), u.dtype)).ravel()

    def rms(self, times, u, window=None) -> list[float]:
        """RMS error of each component [m] inside ``window`` (default: the target's)."""
        t = dataclasses.replace(self, window=window or self.window)
        inside = t._sel(times)
        ref = np.asarray(self.values, float)[inside]
        d = np.asarray(t.sample(times, jnp.asarray(u))) - ref
        return [float(np.sqrt(np.mean(d[:, k] ** 2))) for k in range(d.shape[1])]

    def report(self, times, u) -> dict:
        r = self.rms(times, u)
        return {"quantity": f"RMS of components {list(self.components)} [m]", "rms": r,
                "window": list(self.window)}


@dataclasses.dataclass(frozen=True)
class WindowMean:
    """The mean of components ``components`` of the observation over the steps with
    t0 ≤ t ≤ t1 (``window``) against ``values`` (one per component, e.g. the mean of the
    measured samples there); residuals divided by ``scale`` (one per component)."""

    values: tuple
    components: tuple
    window: tuple
    scale: tuple
    weight: float = 1.0
    name: str = "window_mean"

    def _steps(self, times):
        inside = _window(times, *self.window)
        if not inside.any():
            raise ValueError(f"{self.name}: no step inside the window {self.window}")
        return np.nonzero(inside)[0]

    def measure(self, times, u):
        k = jnp.asarray(self._steps(times))
        return jnp.mean(u[k][:, list(self.components)], axis=0)

    def residuals(self, times, u):
        m = self.measure(times, u)
        return (m - jnp.asarray(self.values, m.dtype)) / jnp.asarray(self.scale, m.dtype)

    def report(self, times, u) -> dict:
        m = np.asarray(self.measure(times, jnp.asarray(u)), float)
        return {"quantity": f"mean over {list(self.window)} s", "value": m.tolist(),
                "reference": list(self.values),
                "rel_error": (m / np.where(np.asarray(self.values) != 0,
                                           np.asarray(self.values), np.nan) - 1).tolist()}


def total_residuals(targets, times, u):
    """Stacked residuals, each target's scaled by √(w/m) so that Σ r² = Σ w·mean(r_t²)."""
    out = []
    for t in targets:
        r = t.residuals(times, u)
        out.append(r * jnp.sqrt(t.weight / r.shape[0]))
    return jnp.concatenate(out)
