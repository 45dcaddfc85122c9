"""fpsi-jax calibration: fit Params to reference data with gradients through rollouts.

    from calibrate import cases, fit
    case = cases.cantilever_synthetic()
    res = fit.fit(case.calibration, max_steps=100)

Modules: ``space`` (which parameters, transformed space), ``targets`` (reference data →
residuals), ``rollout`` (checkpointed differentiable rollouts), ``fit`` (Levenberg–
Marquardt or an optax optimiser, Gauss–Newton errors, JSON, plot), ``batch`` (parameter sweeps in one compiled call,
sharded over devices), ``cases`` (ready-made problems), ``cli`` (``fpsi calibrate``).
"""
