"""The calibration loop on the unconstrained z of a :class:`~calibrate.space.ParamSpace`:
Levenberg–Marquardt on the residuals (the default; the Jacobian by forward mode through
the rollout, or by secants where a chaotic run's derivative misleads), or an optax
optimiser on the loss with the gradient by reverse mode through the checkpointed rollout;
early stopping, Gauss–Newton standard errors, a JSON record and a plot.

    cal = Calibration(problem, space, [target, ...])
    res = fit(cal, max_steps=100)
    res.save("results/fit.json"); plot_fit(cal, res, "results/fit.png")
"""
from __future__ import annotations

import dataclasses
import json
import math
import os
import time
from types import SimpleNamespace
from typing import Sequence

import jax
import jax.numpy as jnp
import numpy as np
import optax

from fpsi_jax.model.errors import ParameterError, SimulationError
from fpsi_jax.run.driver import run_until_fits
from fpsi_jax.solver import stages

from .rollout import Problem
from .space import ParamSpace
from .targets import StaticDeflection, Trajectory, total_residuals


class Calibration:
    """A problem, the quantities fitted and the targets: the pure functions of z a fit needs
    (residuals, loss and their derivatives), jitted once per neighbour-list capacity.

    Every evaluation checks the run's status on the host: a neighbour overflow regrows the
    lists and redoes the evaluation (no pair is dropped, as in ``simulate``); an unstable
    run raises :class:`~fpsi_jax.model.errors.SimulationError`."""

    def __init__(self, problem: Problem, space: ParamSpace, targets: Sequence):
        if not targets:
            raise ParameterError("no calibration target given")
        self.problem, self.space, self.targets = problem, space, tuple(targets)
        self._build()

    @property
    def dtype(self):
        return stages.dtype(self.problem.phys)

    def _build(self):
        pr, space, targets, times = self.problem, self.space, self.targets, self.problem.times

        def residuals(z, state0, base):
            final, u = dataclasses.replace(pr, state0=state0).run(space.params(z, base))
            return total_residuals(targets, times, u), (u, final.status)

        def loss(z, state0, base):
            r, aux = residuals(z, state0, base)
            return jnp.sum(r * r), aux

        self.residuals_fn, self.loss_fn = residuals, loss
        self._fns = {
            "value_and_grad": jax.jit(jax.value_and_grad(loss, has_aux=True)),
            "value": jax.jit(loss),
            "jacobian": jax.jit(jax.jacfwd(residuals, has_aux=True)),
            "residuals": jax.jit(residuals),
        }

    def _call(self, kind: str, z):
        z = jnp.asarray(z, self.dtype)

        def attempt(phys, state0):
            if phys is not self.problem.phys:        # lists regrown: new programs
                self.problem = dataclasses.replace(self.problem, phys=phys, state0=state0)
                self._build()
            out = self._fns[kind](z, state0, self.problem.params)
            end = SimpleNamespace(status=out[0][1][1] if kind == "value_and_grad"
                                  else out[1][1])
            if end.status.must_redo():               # the lists to grow are the forward run's
                end, _ = jax.jit(self.problem.run)(self.space.params(z, self.problem.params))
            return end, out

        return run_until_fits(attempt, self.problem.phys, self.problem.state0,
                              self.problem.dt, max_regrowths=5).result

    def value_and_grad(self, z):
        """((loss, (u, status)), dloss/dz)."""
        return self._call("value_and_grad", z)

    def value(self, z):
        """(loss, (u, status))."""
        return self._call("value", z)

    def jacobian(self, z):
        """(d residuals/dz, (u, status)), forward mode: one JVP per fitted quantity."""
        return self._call("jacobian", z)

    def jacobian_fd(self, z, h: float = 0.05):
        """(forward-difference d residuals/dz with step ``h`` in z, (u, status) at z): a
        secant over a finite step, for losses whose pointwise derivative is dominated by
        chaotic growth (long float32 SPH rollouts; docs/design.md)."""
        z = jnp.asarray(z, self.dtype)
        r0, aux = self._call("residuals", z)
        cols = []
        for k in range(z.shape[0]):
            rk, _ = self._call("residuals", z.at[k].add(h))
            cols.append((rk - r0) / h)
        return jnp.stack(cols, axis=1), aux

    def observe(self, z) -> np.ndarray:
        """The observations (n_steps, …) at z."""
        return np.asarray(self.value(z)[1][0])


# --- uncertainty ----------------------------------------------------------------------------
def gauss_newton_stderr(cal: Calibration, z, noise: float | None = None, jac=None) -> dict:
    """Gauss–Newton standard errors of the fitted quantities at z.

    Cov_z = s² (JᵀJ)⁻¹ with J = ∂r/∂z; s² = RSS/(m − p) (residual variance) when there are
    more residuals m than parameters p, or ``noise``² when given (the residuals' assumed
    measurement error, in residual units). The errors of the physical values follow by the
    delta method, σ_v = |dv/dz| σ_z. Returns name → {std_error, rel_std_error}, plus the
    correlation matrix and s."""
    J, (u, _) = (jac or cal.jacobian)(z)
    J = np.asarray(J, float)
    z = jnp.asarray(z, cal.dtype)
    r = np.asarray(total_residuals(cal.targets, cal.problem.times, jnp.asarray(u)), float)
    m, p = J.shape
    finite_j = bool(np.all(np.isfinite(J)))
    if not (finite_j and np.all(np.isfinite(r))):
        bad = "residuals are" if finite_j else "Jacobian is"
        return {"note": f"the {bad} not finite at the fitted point (a chaotic float32 "
                        "tangent can overflow; design.md, Gradients and calibration): no "
                        "standard errors; try --jacobian fd or x64"}
    if noise is not None:
        s2, how = float(noise) ** 2, f"assumed residual error {noise}"
    elif m > p:
        s2, how = float(r @ r) / (m - p), f"RSS/(m - p), m = {m}, p = {p}"
    else:
        return {"note": f"m = {m} residuals for p = {p} parameters: give noise= for errors"}
    # a quantity the residuals do not move with (a strength no bond reaches, a damping
    # that acts on nothing) is not identifiable: its error is infinite, not the 0 that the
    # pseudo-inverse of a zero column would give
    col = np.linalg.norm(J, axis=0)
    blind = col <= 1e-12 * max(float(col.max()), 1e-300)
    cov = s2 * np.linalg.pinv(J.T @ J)
    dv = np.asarray(jax.jacfwd(cal.space.values)(z), float).diagonal()
    v = np.asarray(cal.space.values(z), float)
    sd_z = np.where(blind, np.inf, np.sqrt(np.clip(np.diag(cov), 0, None)))
    out = {name: {"value": float(v[k]), "std_error": float(abs(dv[k]) * sd_z[k]),
                  "rel_std_error": float(abs(dv[k]) * sd_z[k] / abs(v[k]))}
           for k, name in enumerate(cal.space.names)}
    d = np.where((sd_z > 0) & np.isfinite(sd_z), sd_z, 1.0)
    out["correlation"] = (cov / np.outer(d, d)).tolist()
    out["s"] = math.sqrt(s2)
    out["s_from"] = how
    if blind.any():
        names = ", ".join(n for n, b in zip(cal.space.names, blind) if b)
        out["note"] = (f"{names}: the residuals do not change with it at the fitted point, "
                       "so the data do not determine it (infinite standard error; e.g. a "
                       "bond strength no bond reaches in the window)")
    return out


# --- the loop -------------------------------------------------------------------------------
@dataclasses.dataclass
class FitResult:
    names: list
    start: dict
    best: dict
    z_start: list
    z_best: list
    history: list            # per step: {"step", "loss", "values", "grad_norm", "wall_s"}
    loss_start: float
    loss_best: float
    steps: int
    stopped: str
    wall_s: float
    stderr: dict | None = None
    extra: dict = dataclasses.field(default_factory=dict)

    def to_json(self) -> dict:
        return {k: v for k, v in dataclasses.asdict(self).items()}

    def save(self, path: str):
        os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
        with open(path, "w") as fh:
            json.dump(self.to_json(), fh, indent=1, default=float)


OPTIMIZERS = ("lm", "adam", "sgd")


def make_optimizer(name: str, learning_rate: float, max_steps: int):
    """optax 'adam' (cosine-decayed learning rate) or 'sgd' with momentum; z is O(1) per
    unit of log parameter, so a learning rate of 0.05–0.1 moves a parameter by 5–10 % per
    step."""
    sched = optax.cosine_decay_schedule(learning_rate, max(1, max_steps), alpha=0.05)
    if name == "adam":
        return optax.adam(sched)
    if name == "sgd":
        return optax.sgd(sched, momentum=0.9)
    raise ParameterError(f"optimizer = {name!r}; allowed {OPTIMIZERS}")


class FitError(SimulationError):
    """A fit that found no point with a finite loss (the CLI exits with code 3)."""

    def __init__(self, message: str):
        RuntimeError.__init__(self, message)
        self.step = self.time = self.particle = self.output = None
        self.phase, self.quantity = "calibration", message


class _Tracker:
    """History, best point and early stopping shared by both loops."""

    def __init__(self, cal, rel_tol, patience, progress, log):
        self.cal, self.rel_tol, self.patience = cal, rel_tol, patience
        self.progress, self.log = progress, log
        self.history, self.best, self.since, self.t0 = [], math.inf, 0, time.perf_counter()
        self.best_z = None

    def record(self, k, z, loss, grad_norm, **extra) -> bool:
        """Log step k; returns True when the patience has run out."""
        vals = dict(zip(self.cal.space.names, np.asarray(self.cal.space.values(z),
                                                         float).tolist()))
        self.history.append({"step": k, "loss": loss, "values": vals, "grad_norm": grad_norm,
                             "wall_s": time.perf_counter() - self.t0, **extra})
        if self.progress:
            self.log(f"step {k:3d}  loss {loss:.4e}  " + "  ".join(
                f"{n} {v:.6g}" for n, v in vals.items()))
        if loss < self.best * (1 - self.rel_tol):
            self.since = 0
        else:
            self.since += 1
        if loss < self.best:
            self.best, self.best_z = loss, z
        return self.since >= self.patience


def fit(cal: Calibration, *, z0=None, optimizer: str = "lm", learning_rate: float = 0.1,
        max_steps: int = 100, loss_tol: float = 0.0, rel_tol: float = 1e-4, patience: int = 10,
        noise: float | None = None, progress: bool = True, log=print,
        jacobian: str = "ad", fd_step: float = 0.05) -> FitResult:
    """Minimise the loss Σ r² of ``cal`` from z0 (default: the space's start).

    optimizer  'lm': Levenberg–Marquardt on the residuals, with the Jacobian by forward mode
               (one JVP per fitted quantity through the rollout; the right tool for a few
               parameters and a least-squares loss); 'adam' / 'sgd': optax first-order
               optimisers on the reverse-mode gradient through the checkpointed rollout
               (``learning_rate`` in z units; any number of parameters).
    Stops after ``max_steps`` optimiser steps, when the loss falls below ``loss_tol``, or
    when the best loss has not improved by a relative ``rel_tol`` for ``patience`` steps.
    jacobian   'ad' (forward mode, exact) or 'fd' (forward differences with ``fd_step`` in
               z: a secant, for chaotic long rollouts whose pointwise derivative does not
               point downhill; 'lm' only).
    The best point seen is returned, with Gauss–Newton standard errors
    (:func:`gauss_newton_stderr`)."""
    if max_steps < 1:
        raise ParameterError(f"max_steps = {max_steps} out of range; allowed [1, inf)")
    if optimizer not in OPTIMIZERS:
        raise ParameterError(f"optimizer = {optimizer!r}; allowed {OPTIMIZERS}")
    z = jnp.asarray(cal.space.z0 if z0 is None else z0, cal.dtype)
    tr = _Tracker(cal, rel_tol, patience, progress, log)
    if jacobian not in ("ad", "fd"):
        raise ParameterError(f"jacobian = {jacobian!r}; allowed 'ad', 'fd'")
    if optimizer == "lm":
        jac = cal.jacobian if jacobian == "ad" else (lambda zz: cal.jacobian_fd(zz, fd_step))
        stopped = _levenberg_marquardt(cal, z, tr, jac, max_steps, loss_tol)
    else:
        stopped = _first_order(cal, z, tr, optimizer, learning_rate, max_steps, loss_tol)
    if tr.best_z is None:
        raise FitError("the loss is not finite at any point tried: every run went "
                       "unstable or gave a non-finite probe")
    stderr = gauss_newton_stderr(cal, tr.best_z, noise, jac=None if jacobian == "ad"
                                 else (lambda zz: cal.jacobian_fd(zz, fd_step)))
    space = cal.space
    return FitResult(names=space.names, start=space.report(z), best=space.report(tr.best_z),
                     z_start=np.asarray(z).tolist(), z_best=np.asarray(tr.best_z).tolist(),
                     history=tr.history, loss_start=tr.history[0]["loss"],
                     loss_best=float(tr.best), steps=tr.history[-1]["step"], stopped=stopped,
                     wall_s=time.perf_counter() - tr.t0, stderr=stderr,
                     extra={"optimizer": optimizer, "jacobian": jacobian})


def _first_order(cal, z, tr, optimizer, learning_rate, max_steps, loss_tol) -> str:
    opt = make_optimizer(optimizer, learning_rate, max_steps)
    state = opt.init(z)
    for k in range(max_steps + 1):
        (loss, _), g = cal.value_and_grad(z)
        loss = float(loss)
        if not math.isfinite(loss) or not bool(jnp.all(jnp.isfinite(g))):
            return f"non-finite loss or gradient at step {k}"
        out = tr.record(k, z, loss, float(jnp.linalg.norm(g)))
        if loss <= loss_tol:
            return "loss_tol"
        if out:
            return f"no improvement in {tr.patience} steps"
        if k == max_steps:
            return "max_steps"
        upd, state = opt.update(g, state, z)
        z = optax.apply_updates(z, upd)
    return "max_steps"


def _residuals_at(jac, cal, z):
    J, (u, _) = jac(z)
    r = total_residuals(cal.targets, cal.problem.times, u)
    return np.asarray(J, float), np.asarray(r, float)


def _trial(jac, cal, z):
    """(J, r) at a trial point, or None when the rollout there goes unstable (the step is
    then rejected like one that raises the loss)."""
    try:
        return _residuals_at(jac, cal, z)
    except SimulationError:
        return None


def _loss_at(cal, z) -> float:
    """The loss at ``z`` from a forward rollout alone (inf where it goes unstable)."""
    try:
        return float(cal.value(jnp.asarray(z, cal.dtype))[0])
    except SimulationError:
        return math.inf


#: an LM step that lowers the loss by less than this fraction is slow; the second slow
#: step in a row also looks along the gradient
SLOW_STEP = 0.1
#: the gradient line's trial lengths, as fractions of the step cap
LINE_FRACTIONS = (1.0, 0.25, 0.0625)


def _levenberg_marquardt(cal, z, tr, jac, max_steps, loss_tol, max_step=1.0) -> str:
    """z ← z − (JᵀJ + μ diag JᵀJ)⁻¹ Jᵀr, the step capped at ``max_step`` in z (a trust
    region: a factor e per unit for a log parameter); a step that raises the loss is
    rejected (μ × 10), an accepted one relaxes μ (÷ 3).

    Each trial point's loss comes from a forward rollout; the Jacobian is evaluated once
    per accepted point. Where LM stalls, its step lowering the loss by less than
    ``SLOW_STEP`` (or not at all) twice in a row, the loss is also tried along the
    steepest descent −Jᵀr at ``LINE_FRACTIONS`` of the step cap, and the lowest point
    found is taken (μ unchanged when it is one of these): the Gauss–Newton model of an
    oscillating record is valid only near the fit (its derivative in a stiffness grows
    with time, a phase shift), so from far off LM's steps in that parameter are too
    short, while the loss itself falls steadily along it (docs/design.md, the
    sloshing-baffle recovery). Not at the first slow step: a greedy step along the
    gradient can also leave a curved valley that LM is following (the elastic gate's fit,
    whose second step lowers the loss by 7 %, ended at 11 times the loss with it)."""
    J, r = _residuals_at(jac, cal, z)
    mu = 1e-2
    loss = float(r @ r)
    trial, slow = None, 0
    for k in range(max_steps + 1):
        if not math.isfinite(loss):
            return f"non-finite loss at step {k}"
        g = J.T @ r
        out = tr.record(k, z, loss, float(2 * np.linalg.norm(g)), mu=mu, trial_loss=trial)
        if loss <= loss_tol:
            return "loss_tol"
        if out:
            return f"no improvement in {tr.patience} steps"
        if k == max_steps:
            return "max_steps"
        if not np.isfinite(J).all():
            return (f"non-finite Jacobian at step {k} (the derivative of the rollout "
                    "overflowed: try the secant, jacobian='fd')")
        A = J.T @ J
        d = np.diag(A)
        d = np.where(d > 0, d, max(float(d.max()), 1e-30) * 1e-12)
        step = -np.linalg.solve(A + mu * np.diag(d), g)
        n = float(np.max(np.abs(step)))
        if n > max_step:
            step *= max_step / n
        z_try = z + jnp.asarray(step, cal.dtype)
        trial = _loss_at(cal, z_try)
        from_line = False
        gmax = float(np.max(np.abs(g)))
        slow = 0 if trial < (1.0 - SLOW_STEP) * loss else slow + 1
        if slow >= 2 and gmax > 0:
            for a in LINE_FRACTIONS:
                z_line = z - jnp.asarray(g * (a * max_step / gmax), cal.dtype)
                got = _loss_at(cal, z_line)
                if got < trial:
                    z_try, trial, from_line = z_line, got, True
        got = _trial(jac, cal, z_try) if trial < loss else None
        if got is not None and float(got[1] @ got[1]) < loss:
            J, r = got
            z, loss = z_try, float(r @ r)
            if not from_line:
                mu = max(mu / 3.0, 1e-9)
        else:
            mu *= 10.0
    return "max_steps"


# --- plots ----------------------------------------------------------------------------------
def plot_fit(cal: Calibration, result: FitResult, path: str, title: str = "",
             component_names=("u_x", "u_y"), extra_curves=()):
    """Loss history, and the observed displacement at the start and at the best point
    against each target's reference (trajectory samples, static value)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = cal.problem.times
    u0 = cal.observe(result.z_start)
    u1 = cal.observe(result.z_best)
    comps = sorted({c for tg in cal.targets for c in getattr(tg, "components",
                                                              (getattr(tg, "component", 1),))})
    fig, axes = plt.subplots(1, 1 + len(comps), figsize=(4.2 * (1 + len(comps)), 3.6))
    ax = axes[0]
    ax.semilogy([h["step"] for h in result.history], [h["loss"] for h in result.history])
    ax.set_xlabel("optimiser step")
    ax.set_ylabel("loss")
    ax.grid(alpha=0.3)
    for ax, c in zip(axes[1:], comps):
        ax.plot(t, u0[:, c] * 1e3, color="0.6", lw=1, label="start")
        ax.plot(t, u1[:, c] * 1e3, color="C0", lw=1.2, label="fitted")
        for tg in cal.targets:
            if isinstance(tg, Trajectory) and c in tg.components:
                j = tg.components.index(c)
                v = np.asarray(tg.values, float)
                tr = np.asarray(tg.t_ref, float)
                ax.plot(tr, v[:, j] * 1e3, "k.", ms=4, label=f"{tg.name} (reference)")
                for edge in tg.window:
                    if edge is not None:
                        ax.axvline(edge, color="k", lw=0.6, ls=":")
            if isinstance(tg, StaticDeflection) and tg.component == c:
                ax.axhline(tg.value * 1e3, color="k", ls="--", lw=0.8, label="reference")
        for label, tc, uc in extra_curves:
            ax.plot(tc, uc[:, c] * 1e3, lw=1, ls="--", label=label)
        ax.set_xlabel("t [s]")
        ax.set_ylabel(f"{component_names[c]} [mm]")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
