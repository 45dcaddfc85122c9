"""The settling disc of W6.2.1 as one ordinary differential equation: the grain alone under
the same quasi-steady drag law the simulator uses, with and without its added mass, in a
fluid that rises at a fixed fraction κ of the grain's speed (the mean return flow the SPH
fluid resolves at the grain: ū ≈ 0.1 |v_p| at the seed's resolution).

    (m_p + C_a ρ_f V_p) dv/dt = −(ρ_p − ρ_f) V_p g + F_drag(ε, ū − v) [+ F_H]

It shows what the law itself gives against Zhang et al. 2019's y(t), apart from the SPH
fluid: RMS(y − y_ref)/fall and the settling velocity over 0.2–0.6 s, as
``fpsi validate sedimentation`` measures them. The rows with ``history`` add a
Basset-type force with the short-time kernel of a cylinder (not in the simulator): the
Stokes layer's wall shear μ U_t/√(πν(t − τ)) under the potential-flow slip U_t = 2U sin θ,
summed over the perimeter, F_H = −2√π a √(ρ_f μ) ∫ (dU/dτ)/√(t − τ) dτ per unit length,
U the slip. It holds while the layer is thinner than the disc, √(νt) < a (t < 0.16 s
here). The rows with ``history`` 'cutoff' put Mei & Adrian's (1992) finite-Reynolds kernel
on the same short-time coefficient: K(t) = [(4πνt/d²)^(1/2c₁) + (π t² |U|³/(d ν f_H³))^(1/c₁)]^(−c₁),
c₁ = 2, f_H = 0.75 + 0.105 Re (fitted by them for a sphere: no 2D kernel at finite Re is
published that we know of), so the force dies off after the advective time d/|U| instead
of as 1/√t.

    .venv/bin/python experiments/sedimentation_ode.py     # -> results/sedimentation_ode.csv
"""
from __future__ import annotations

import numpy as np

from fpsi_jax.cases.registry import load_csv
from fpsi_jax.cases.sedimentation import SEDIMENTATION_REFERENCE, sedimentation_metrics
from fpsi_jax.model.options import Drag
from fpsi_jax.physics import fpi

from _table import write_rows

D, RHO_P, RHO_F, MU, G, Y0 = 0.0025, 1250.0, 1000.0, 0.01, 9.81, 0.04
EPS = 0.98          # the grain's voidage in the simulator at h = 2d


def history_kernel(tau, slip, history):
    """1/√τ (the short-time kernel) or Mei & Adrian's cut-off form scaled to match it at
    small τ, for the ages ``tau`` of the slip increments and the current slip speed."""
    if history != "cutoff":
        return 1.0 / np.sqrt(tau)
    nu = MU / RHO_F
    f_h = 0.75 + 0.105 * slip * D / nu
    k = ((4 * np.pi * nu * tau / D ** 2) ** 0.25
         + (np.pi * tau ** 2 * slip ** 3 / (D * nu * f_h ** 3)) ** 0.5) ** -2.0
    return k * np.sqrt(4 * np.pi * nu) / D


def fall(c_a, kappa, history=False, law=Drag.CYLINDER, dt=1.0e-4, t_end=0.8):
    """(t, y) of the grain released from rest at y0 (semi-implicit Euler; it rests at y = d/2).
    ``history``: False, True (the 1/√t kernel) or 'cutoff' (Mei & Adrian's)."""
    vol = np.pi * D * D / 4
    eps = np.array([EPS])
    k_h = 2.0 * np.sqrt(np.pi) * (D / 2) * np.sqrt(RHO_F * MU) if history else 0.0
    y, v, ts, ys, d_slip = Y0, 0.0, [], [], []
    for i in range(int(round(t_end / dt))):
        t = (i + 1) * dt
        f = float(fpi.drag_force(eps, np.array([[0.0, -kappa * v]]), np.array([[0.0, v]]),
                                 np.array([vol]), RHO_F, D, MU, law)[0, 1])
        if history and d_slip:
            t_j = (np.arange(len(d_slip)) + 0.5) * dt
            kern = history_kernel(t - t_j, abs((1.0 + kappa) * v), history)
            f -= k_h * float(np.sum(np.asarray(d_slip) * kern))
        v_new = v + dt * (f - (RHO_P - RHO_F) * vol * G) / ((RHO_P + c_a * RHO_F) * vol)
        d_slip.append((1.0 + kappa) * (v_new - v))
        v = v_new
        y += dt * v
        if y < D / 2:
            y, v = D / 2, 0.0
        ts.append((i + 1) * dt)
        ys.append(y)
    return np.array(ts), np.array(ys)


def main():
    ref = load_csv(SEDIMENTATION_REFERENCE)
    ref = ref[np.argsort(ref[:, 0])]
    rows = []
    for c_a, kappa, history in ((0.0, 0.0, False), (0.0, 0.1, False), (1.0, 0.0, False),
                                (1.0, 0.1, False), (1.0, 0.1, True), (1.0, 0.1, "cutoff")):
        t, y = fall(c_a, kappa, history, dt=2.0e-4 if history else 1.0e-4)
        rms, v, v_ref = sedimentation_metrics(t, y, ref, Y0)
        ahead = float(np.interp(0.2, t, y) - np.interp(0.2, ref[:, 0], ref[:, 1]))
        row = dict(c_a=c_a, kappa=kappa, history=history, rms_over_fall=rms, v_settle=v,
                   v_ref=v_ref, v_error=(v - v_ref) / v_ref,
                   y_minus_ref_at_0_2s_mm=1e3 * ahead)
        rows.append(row)
        print(row, flush=True)
    write_rows("experiments/results/sedimentation_ode.csv", rows)


if __name__ == "__main__":
    main()
