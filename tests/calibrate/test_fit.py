"""calibrate.rollout / fit / cases on a short cantilever (x64): checkpointed rollouts equal
plain ones, reverse-mode gradients through ≥ 2000 steps match central finite differences
within 1 %, and forward- and reverse-mode agree. That a synthetic fit recovers stiffness and
damping is tested in tests/cli/test_calibrate_cli.py; the full-size figures are in
experiments/calibrate_cantilever.py."""
import math
from types import SimpleNamespace

import numpy as np
import pytest

import jax
import jax.numpy as jnp

from calibrate import cases, space as sp
from calibrate.fit import Calibration, gauss_newton_stderr
from calibrate.rollout import checkpointed_rollout, prepare
from calibrate.targets import StaticDeflection, Trajectory, total_residuals
from fpsi_jax.cases import build
from fpsi_jax.solver import forward, init

pytestmark = pytest.mark.usefixtures("float64")

SHORT = dict(d=0.0025, length=0.04)


@pytest.fixture(scope="module")
def tip_problem(float64):
    """Tip-loaded short strip with viscous damping, 2000 steps (~0.27 of a period)."""
    scene = build("cantilever", variant="tip", alpha=0.0, damping=20.0, **SHORT)
    pr = prepare(scene, 2000 * 2.7e-6, cases.tracker(scene, cases.cantilever_tip(scene)),
                 dt=2.7e-6, chunk=50)
    assert pr.n_steps == 2000
    return pr


@pytest.mark.parametrize("remat_step", [False, True])
def test_checkpointed_rollout_equals_plain_rollout(tip_problem, remat_step):
    pr = tip_problem
    s0 = init.refresh_rates(pr.phys, pr.state0, pr.params)
    a, oa = jax.jit(lambda s: forward.rollout(pr.phys, s, pr.params, 107, pr.observe))(s0)
    b, ob = jax.jit(lambda s: checkpointed_rollout(pr.phys, s, pr.params, 107, pr.observe,
                                                   chunk=10, remat_step=remat_step))(s0)
    np.testing.assert_allclose(np.asarray(ob), np.asarray(oa), rtol=0, atol=1e-15)
    np.testing.assert_allclose(np.asarray(b.solid.x), np.asarray(a.solid.x), rtol=0, atol=1e-15)


def _calibration(pr):
    """Loss: the tip trajectory against one with stiffness ×0.8 and damping ×2."""
    space = sp.ParamSpace(pr.params, [sp.stiffness(0.25, 4.0), sp.param("dem.damping",
                                                                          1.0, 1000.0)])
    probe = Calibration(pr, space, [StaticDeflection(value=1.0)])
    u = probe.observe(space.z_of({"stiffness": 0.8, "dem.damping": 40.0}))
    t = pr.times[::100]
    ref = Trajectory(t_ref=tuple(t), values=tuple(map(tuple, u[99::100])), components=(0, 1))
    return Calibration(pr, space, [ref])


def test_gradient_matches_central_differences(tip_problem):
    """d loss/dz for stiffness and damping through 2000 DEM steps (reverse mode through the
    checkpointed scan) against central differences with h = 1e-4 in z: within 1 %."""
    cal = _calibration(tip_problem)
    z = cal.space.z0
    (loss, _), g = cal.value_and_grad(z)
    assert float(loss) > 0
    h = 1e-4
    for k in range(2):
        e = jnp.zeros_like(z).at[k].set(h)
        fd = (float(cal.value(z + e)[0]) - float(cal.value(z - e)[0])) / (2 * h)
        assert float(g[k]) == pytest.approx(fd, rel=0.01), cal.space.names[k]
    # forward mode (the Jacobian of the residuals) gives the same gradient
    J, (u, _) = cal.jacobian(z)
    res = total_residuals(cal.targets, tip_problem.times, u)
    np.testing.assert_allclose(np.asarray(2 * J.T @ res), np.asarray(g), rtol=1e-8)
    # Gauss–Newton standard errors from the same Jacobian
    se = gauss_newton_stderr(cal, z)
    assert set(cal.space.names) <= set(se) and se["s"] > 0
    for n in cal.space.names:
        assert se[n]["std_error"] > 0
    # a Jacobian that overflowed at the fitted point gives a note, not a crash after the fit
    # (numpy's SVD of a NaN JᵀJ raised LinAlgError in the README's calibration of the post)
    def nan_jacobian(zz):
        J, out = cal.jacobian(zz)
        return J.at[0, 0].set(jnp.nan), out
    se = gauss_newton_stderr(cal, z, jac=nan_jacobian)
    assert set(se) == {"note"} and "Jacobian is not finite" in se["note"]
    # a quantity the residuals do not move with (a strength no bond reaches) has an
    # infinite error and a note naming it (the pseudo-inverse gave 0: a fit of a bond
    # strength far from the truth reported ± 0 Pa), the other keeps its finite error
    def blind_jacobian(zz):
        J, out = cal.jacobian(zz)
        return J.at[:, 1].set(0.0), out
    se = gauss_newton_stderr(cal, z, jac=blind_jacobian)
    assert se["dem.damping"]["std_error"] == float("inf")
    assert 0 < se["stiffness"]["std_error"] < float("inf")
    assert "dem.damping: the residuals do not change with it" in se["note"]


@pytest.mark.slow
def test_gate_gradient_matches_central_differences():
    """The coarse elastic gate over 0.05 s (x64, SPH + 20 DEM sub-steps per step): the
    reverse-mode gradient for stiffness and damping within 1 % of central differences
    (experiments/gradient_check.py records the figures)."""
    import importlib.util
    import os
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    path = os.path.join(root, "experiments", "gradient_check.py")
    spec = importlib.util.spec_from_file_location("gradient_check", path)
    gc = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(gc)
    pr = gc.gate_problem(0.05)
    cal = gc.calibration(pr, max(1, int(round(1e-3 / pr.dt))))
    z = cal.space.z0
    _, g = cal.value_and_grad(z)
    h = 1e-4
    for k in range(2):
        e = jnp.zeros_like(z).at[k].set(h)
        fd = (float(cal.value(z + e)[0]) - float(cal.value(z - e)[0])) / (2 * h)
        assert float(g[k]) == pytest.approx(fd, rel=0.01), cal.space.names[k]


class _Line:
    """A stand-in Calibration for the LM loop alone: residual r = z − 1 (one parameter)."""
    dtype = np.float64
    space = SimpleNamespace(names=("a",), values=lambda z: z)


def _lm(monkeypatch, residuals, max_steps=20):
    from calibrate import fit as fit_mod
    from fpsi_jax.model.errors import SimulationError

    def loss_at(cal, z):
        try:
            r = residuals(z)[1]
        except SimulationError:
            return math.inf
        return float(r @ r)

    monkeypatch.setattr(fit_mod, "_residuals_at", lambda jac, cal, z: residuals(z))
    monkeypatch.setattr(fit_mod, "_loss_at", loss_at)
    tr = fit_mod._Tracker(_Line, 1e-12, 100, False, print)
    stopped = fit_mod._levenberg_marquardt(_Line, np.array([3.0]), tr, None, max_steps, 1e-20)
    return stopped, tr


def test_lm_rejects_a_trial_point_where_the_rollout_goes_unstable(monkeypatch):
    """A trial step into an unstable region is rejected (μ × 10, a shorter step), not
    raised: the fit goes on from the last good point and still converges."""
    from fpsi_jax.model.errors import SimulationError

    def residuals(z):
        if float(z[0]) < 2.5:                 # the first, full step lands at z = 2
            if not hasattr(residuals, "blown"):
                residuals.blown = True
                raise SimulationError(1, 1e-4, 0, "solid position is not finite", "solid")
        return np.ones((1, 1)), np.asarray(z, float) - 1.0

    stopped, tr = _lm(monkeypatch, residuals)
    assert residuals.blown                    # the unstable point was tried, not raised
    assert float(tr.best_z[0]) == pytest.approx(1.0, abs=1e-6)
    assert stopped in ("loss_tol", "max_steps")


def test_lm_looks_along_the_gradient_where_gauss_newton_steps_are_too_short(monkeypatch):
    """A Jacobian that overstates the residual's slope 100-fold (as the derivative of an
    oscillating record in a stiffness does far from the fit) makes every Gauss–Newton step
    1 % of the way; from the second such step on the loss is tried along −Jᵀr too
    (fit.SLOW_STEP, LINE_FRACTIONS), and after 20 steps the fit is within 0.02 of z = 1
    (the line's fixed fractions of the step cap, then the short GN steps, close the
    rest). Without the line it is still 1.6 away."""
    from calibrate import fit as fit_mod

    def residuals(z):
        return np.full((1, 1), 100.0), np.asarray(z, float) - 1.0

    stopped, tr = _lm(monkeypatch, residuals)
    assert abs(float(tr.best_z[0]) - 1.0) < 0.02
    assert tr.history[3]["loss"] < 1e-3 * tr.history[0]["loss"]   # two line steps, at 2 and 3
    monkeypatch.setattr(fit_mod, "SLOW_STEP", -math.inf)      # the line never tried
    _, tr = _lm(monkeypatch, residuals)
    assert float(tr.best_z[0]) - 1.0 > 1.5


def test_lm_stops_with_a_clear_reason_on_a_non_finite_jacobian(monkeypatch):
    stopped, tr = _lm(monkeypatch, lambda z: (np.full((1, 1), np.nan),
                                              np.asarray(z, float) - 1.0))
    assert stopped.startswith("non-finite Jacobian at step 0")
    assert len(tr.history) == 1
