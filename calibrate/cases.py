"""Ready-made calibration problems (``fpsi calibrate <case>``): each builds the scene, the
differentiable problem, the fitted quantities and the targets, from physical keyword
arguments.

    cantilever_synthetic  a reference run with known stiffness and damping; the fit starts
                          from stiffness ×2 and damping ×3 and must recover both
    cantilever_static     stiffness so the static tip deflection is Euler–Bernoulli's
                          PL³/(3EI) (1.6 mm for K6.3.3's strip)
    cantilever_damping    viscous damping so the free vibration decays with a prescribed
                          damping ratio
    elastic_gate          stiffness scale (E) and damping of the gate against the Antoci
                          et al. (2007) experiment, fitted on t ≤ t_fit
"""
from __future__ import annotations

import dataclasses
import math

import jax
import numpy as np

from fpsi_jax.cases import build
from fpsi_jax.cases.cantilever import euler_bernoulli_f1, tip_deflection
from fpsi_jax.cases.elastic_gate import GATE_COARSE  # noqa: F401  (cases.GATE_COARSE)
from fpsi_jax.model.errors import ParameterError
from fpsi_jax.run import observers

from . import space as sp
from .fit import Calibration
from .rollout import prepare
from .targets import FreeVibration, StaticDeflection, Trajectory


def tracker(scene, idx):
    """observe(state) = mean displacement of the discs ``idx`` from their start (2,)."""
    return observers.mean_displacement(scene.solid.x, np.asarray(idx, int))


def cantilever_tip(scene) -> np.ndarray:
    """The discs of the cantilever's free end (largest x)."""
    x = np.asarray(scene.solid.x)
    return np.nonzero(x[:, 0] >= x[:, 0].max() - 1e-9)[0]


@dataclasses.dataclass
class Case:
    """A calibration ready to fit, with what its report needs."""

    calibration: Calibration
    meta: dict
    truth: dict | None = None
    jacobian: str = "ad"          # the Jacobian its LM fit uses ('fd': a secant)


def _cantilever(variant, d, periods, damping, stiff_bounds, **kw):
    scene = build("cantilever", variant=variant, d=d, damping=damping,
                  **{k: v for k, v in kw.items() if k not in ("variant", "damping", "t_end")})
    bk = scene.builder_kwargs
    f1 = euler_bernoulli_f1(bk["E"], bk["rho"], bk["height"], bk["length"])
    return scene, f1


def cantilever_synthetic(*, d=0.0025, periods=2.25, damping=4.0, stiffness_start=2.0,
                         damping_start_factor=3.0, stiff_bounds=(0.4, 2.5),
                         damping_bounds=(0.1, 100.0), chunk=None, **scene_kw) -> Case:
    """Free vibration of K6.3.3's strip (discs ``d``; 2.5 mm by default, 2 rows, for speed)
    over ``periods`` Euler–Bernoulli periods. Truth: the scene's stiffness (scale 1) and
    ``damping`` c [1/s]; the reference is the truth run's own frequency and damping ratio
    (measured as :class:`~calibrate.targets.FreeVibration` does). The fit starts from
    stiffness × ``stiffness_start`` and damping × ``damping_start_factor``. Other keywords
    go to the cantilever builder (e.g. ``length``)."""
    scene, f1 = _cantilever("free", d, periods, damping, stiff_bounds, **scene_kw)
    fitted = [sp.stiffness(*stiff_bounds), sp.param("dem.damping", *damping_bounds)]
    space0 = sp.ParamSpace(scene.params, fitted)
    problem = prepare(scene, periods / f1, tracker(scene, cantilever_tip(scene)),
                      stiffest=space0.extreme("hi"), chunk=chunk)
    truth = {"stiffness": 1.0, "dem.damping": float(damping)}
    space = sp.ParamSpace(problem.params, fitted,
                          start={"stiffness": stiffness_start,
                                 "dem.damping": damping_start_factor * damping})
    probe = Calibration(problem, space, [FreeVibration(frequency=1.0, damping_ratio=1.0)])
    u = probe.observe(space.z_of(truth))
    target = FreeVibration.from_signal(problem.times, u)
    cal = Calibration(problem, space, [target])
    meta = {"case": "cantilever_synthetic", "d": d, "periods": periods, "f1_eb_hz": f1,
            "n_steps": problem.n_steps, "dt": problem.dt, "n_discs": scene.solid.n,
            "reference": {"frequency_hz": target.frequency,
                          "damping_ratio": target.damping_ratio}}
    return Case(cal, meta, truth)


def cantilever_static(*, d=0.00125, deflection=None, load=1.0, stiffness_start=1.0,
                      cycles=1.5, stiff_bounds=(0.5, 2.0), chunk=None, **scene_kw) -> Case:
    """Tip-loaded strip (K6.3.3: ``load`` 1 N, 1.6 mm Euler–Bernoulli deflection): fit the
    stiffness scale so the static tip deflection equals ``deflection`` (default
    PL³/(3EI)). The run is viscously damped at the first mode's critical rate
    c = 4π f1 (f1 of Euler–Bernoulli), the load ramps up over half a period, and the run
    lasts ``cycles`` periods more (the transient is then below e^(−2π·cycles)); the static
    value is the mean over the last 10 % of the run."""
    scene, _ = _cantilever("tip", d, None, 0.0, stiff_bounds, load=load, alpha=0.0,
                           **scene_kw)
    bk = scene.builder_kwargs
    f1 = euler_bernoulli_f1(bk["E"], bk["rho"], bk["height"], bk["length"])
    ref = tip_deflection(load, bk["length"], bk["E"], bk["height"]) if deflection is None \
        else deflection
    scene.params = scene.params.replace(
        dem=scene.params.dem.replace(damping=4 * math.pi * f1, load_ramp=0.5 / f1))
    fitted = [sp.stiffness(*stiff_bounds)]
    space0 = sp.ParamSpace(scene.params, fitted)
    problem = prepare(scene, (0.5 + cycles) / f1, tracker(scene, cantilever_tip(scene)),
                      stiffest=space0.extreme("hi"), chunk=chunk)
    space = sp.ParamSpace(problem.params, fitted, start={"stiffness": stiffness_start})
    target = StaticDeflection(value=-ref, component=1)
    meta = {"case": "cantilever_static", "d": d, "reference_m": ref, "E": bk["E"],
            "n_steps": problem.n_steps, "dt": problem.dt, "n_discs": scene.solid.n}
    return Case(Calibration(problem, space, [target]), meta)


def cantilever_damping(*, d=0.00125, zeta=0.05, periods=2.25, damping_start=2.0,
                       damping_bounds=(0.1, 100.0), chunk=None, **scene_kw) -> Case:
    """Free vibration of the strip: fit the viscous damping c so the first mode decays with
    damping ratio ``zeta`` (the analytic value is c = 4π f1 ζ, f1 the model's frequency)."""
    scene, f1 = _cantilever("free", d, periods, damping_start, None, **scene_kw)
    fitted = [sp.param("dem.damping", *damping_bounds)]
    problem = prepare(scene, periods / f1, tracker(scene, cantilever_tip(scene)),
                      chunk=chunk)
    space = sp.ParamSpace(problem.params, fitted)
    target = FreeVibration(damping_ratio=zeta)
    meta = {"case": "cantilever_damping", "d": d, "zeta": zeta, "f1_eb_hz": f1,
            "n_steps": problem.n_steps, "dt": problem.dt, "n_discs": scene.solid.n}
    return Case(Calibration(problem, space, [target]), meta)


SCENE_OF = {"cantilever_synthetic": "cantilever", "cantilever_static": "cantilever",
            "cantilever_damping": "cantilever", "elastic_gate": "elastic_gate"}

CASES = {"cantilever_synthetic": cantilever_synthetic,
         "cantilever_static": cantilever_static,
         "cantilever_damping": cantilever_damping}


def get(name: str):
    if name not in CASES:
        raise ParameterError(f"unknown calibration case {name!r}; known: {', '.join(CASES)}")
    return CASES[name]




def gate_reference():
    """(t, ux, uy) of the Antoci et al. (2007) experiment (consensus of two digitisations,
    fpsi_jax/data, provenance in its README)."""
    from fpsi_jax.cases.registry import load_csv
    from fpsi_jax.cases.elastic_gate import GATE_EXPERIMENT
    ref = load_csv(GATE_EXPERIMENT)
    return ref[:, 0], ref[:, 1], ref[:, 3]


def gate_target(t_fit=0.2, t0=0.0):
    t, ux, uy = gate_reference()
    return Trajectory(t_ref=tuple(t), values=tuple(map(tuple, np.stack([ux, uy], 1))),
                      components=(0, 1), window=(t0, t_fit), name="antoci2007")


def elastic_gate(*, resolution="coarse", t_fit=0.2, damping_start=0.5, stiffness_start=1.0,
                 stiff_bounds=(0.5, 2.0), damping_bounds=(0.01, 200.0), chunk=None,
                 remat_step=True, **scene_kw) -> Case:
    """The elastic gate (the scene's defaults, uncalibrated: E = 10 MPa, ν = 0.4 plane strain,
    no damping) fitted on its tip u_x, u_y against the experiment for t ≤ ``t_fit``:
    the stiffness scale (E_fit = scale × E) and the viscous damping c [1/s] (start
    ``damping_start``, ~0.3 % of critical in the first dry mode, practically the
    undamped default). ``resolution`` 'coarse' (fluid 3.5 mm, discs 2.5 mm) or 'seed'
    (1.75 / 1.25 mm); other keywords go to the scene builder. ``remat_step`` checkpoints
    every step inside the √n chunks (XLA's temporary memory of the full 0.4 s seed-resolution
    gradient: 0.55 GB instead of 13.7 GB; experiments/calibration_cost.py)."""
    from fpsi_jax.cases.elastic_gate import gate_tip
    if resolution not in ("coarse", "seed"):
        raise ParameterError(f"resolution = {resolution!r}; allowed 'coarse', 'seed'")
    kw = {**(GATE_COARSE if resolution == "coarse" else {}), **scene_kw}
    scene = build("elastic_gate", damping=damping_start, **kw)
    fitted = [sp.stiffness(*stiff_bounds), sp.param("dem.damping", *damping_bounds)]
    space0 = sp.ParamSpace(scene.params, fitted)
    observe = tracker(scene, gate_tip(scene))
    problem = prepare(scene, t_fit, observe, stiffest=space0.extreme("hi"), chunk=chunk,
                      remat_step=remat_step)
    space = sp.ParamSpace(problem.params, fitted, start={"stiffness": stiffness_start})
    cal = Calibration(problem, space, [gate_target(t_fit)])
    bk = scene.builder_kwargs
    meta = {"case": "elastic_gate", "resolution": resolution, "t_fit": t_fit,
            "E": bk["E"], "nu": bk["nu"], "plane_strain": bk["plane_strain"],
            "n_steps": problem.n_steps, "dt": problem.dt,
            "dem_substeps": problem.phys.dem_substeps, "n_fluid": scene.fluid.n,
            "n_boundary": scene.boundary.n, "n_discs": scene.solid.n}
    return Case(cal, meta, jacobian="fd")   # docs/design.md: the gate's secant Jacobian


CASES["elastic_gate"] = elastic_gate


def params_with(base, values: dict, space: sp.ParamSpace):
    """Host Params: ``base`` with the fitted quantities set to ``values`` (by name)."""
    p = space.params(space.z_of(values), base=base)
    return jax.tree_util.tree_map(lambda a: np.asarray(a).item() if np.ndim(a) == 0
                                  else np.asarray(a), p)


def evaluate(case: Case, values: dict | None, t_end: float, progress=False, params=None):
    """Forward run of the case's scene with the fitted quantities at ``values`` (or with
    ``params`` as given) to ``t_end`` (host driver, same dt and sub-steps as the fit):
    (t, u (n, 2), Result)."""
    from fpsi_jax.run.driver import simulate
    pr = case.calibration.problem
    space = case.calibration.space
    if params is None:
        params = params_with(pr.scene.params.replace(dt=pr.dt), values, space)
    params = params.replace(dt=pr.dt)
    opts = {"dem_substeps": pr.phys.dem_substeps} if (pr.phys.has_fluid and
                                                       pr.phys.has_solid) else {}
    res = simulate(pr.scene, t_end=t_end, params=params, dt=pr.dt, observe=pr.observe,
                   progress=progress, every=min(t_end, 0.02), **opts)
    u = np.asarray(res.observations, float)
    t = (np.arange(u.shape[0]) + 1) * pr.dt
    return t, u, res
