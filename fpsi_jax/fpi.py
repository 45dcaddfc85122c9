"""Fluid–particle interaction (physics.md §Fluid–particle coupling; W2.2, W3.1.2–3.1.4, W4.2).

Pure functions of arrays. Grain rows carry Dense lists of their *fluid* neighbours (padding
masked by ``valid``); W and the volumes V_f = m_f/ρ_f are gathered by the caller.

Status (issue 5, first part): the closure laws and the weights are here and unit-tested; the
wiring into ``integrate.step`` (ερ in the fluid equations, the grain phase in the SPH
family) is the rest of the issue.
"""
from __future__ import annotations

import jax.numpy as jnp

ERGUN_LIMIT = 0.8        # W20: Ergun for ε ≤ 0.8, Wen–Yu above
RE_NEWTON = 1000.0       # W22: C_d = 0.44 above


def _norm(v, eps=1e-30):
    """|v| along the last axis, with a finite gradient at v = 0."""
    return jnp.sqrt(jnp.sum(v * v, axis=-1) + eps)


def fluid_voidage(w_fp, v_p, valid):
    """ε_i = 1 − Σ_p V_p W(x_i − x_p, h) over the grain neighbours of each fluid row (discrete
    W2), clipped to [0, 1]. ``w_fp`` (n_f, K) kernel values, ``v_p`` (n_f, K) grain volumes."""
    return jnp.clip(1.0 - jnp.sum(jnp.where(valid, w_fp * v_p, 0.0), axis=1), 0.0, 1.0)


def shepard(values, w, vol, valid):
    """Σ_f a_f V_f W_pf / Σ_f V_f W_pf (W18, W21) for each grain row; ``values`` (n_p, K) or
    (n_p, K, c). Rows without fluid neighbours get 0 and weight 0."""
    wv = jnp.where(valid, w * vol, 0.0)
    den = jnp.sum(wv, axis=1)
    safe = jnp.where(den > 0, den, 1.0)
    if values.ndim == 3:
        return jnp.sum(wv[..., None] * values, axis=1) / safe[:, None], den
    return jnp.sum(wv * values, axis=1) / safe, den


def reynolds(slip, eps, rho_f, d, mu):
    """Re = |ū − v| ε ρ_f d / μ (W23)."""
    return slip * eps * rho_f * d / mu


def drag_coefficient(re):
    """C_d = 24/Re (1 + 0.15 Re^0.687) for Re ≤ 1000, 0.44 above (W22, Schiller–Naumann)."""
    safe = jnp.maximum(re, 1e-12)
    return jnp.where(re <= RE_NEWTON, 24.0 / safe * (1.0 + 0.15 * safe ** 0.687), 0.44)


def interphase_beta(eps, slip, rho_f, d, mu):
    """Momentum-exchange coefficient β (W20): Ergun for ε ≤ 0.8,
    150(1−ε)²μ/(εd²) + 1.75(1−ε)ρ_f|ū−v|/d; Wen & Yu above,
    ¾ C_d ε(1−ε) ρ_f |ū−v| ε^(−2.65)/d (W20 prints 7.5; the published coefficient is 3/4)."""
    ergun = 150.0 * (1 - eps) ** 2 * mu / (eps * d * d) + 1.75 * (1 - eps) * rho_f * slip / d
    cd = drag_coefficient(reynolds(slip, eps, rho_f, d, mu))
    wen_yu = 0.75 * cd * eps * (1 - eps) * rho_f * slip * eps ** (-2.65) / d
    return jnp.where(eps <= ERGUN_LIMIT, ergun, wen_yu)


def drag_force(eps, u_f, v_p, vol_p, rho_f, d, mu):
    """F_d = β/(1 − ε) (ū_f − v_p) V_p (W19) on each grain; ``u_f`` the Shepard fluid
    velocity at the grain, ``eps`` its voidage (< 1)."""
    rel = u_f - v_p
    slip = _norm(rel)
    beta = interphase_beta(eps, slip, rho_f, d, mu)
    return (beta / (1.0 - eps) * vol_p)[:, None] * rel


def buoyancy(eps, vol_p, rho_f, gravity):
    """F_b = −ε ρ_f V_p g (W25): upward, magnitude ε ρ_f V_p |g|."""
    return -(eps * rho_f * vol_p)[:, None] * jnp.asarray(gravity)[None, :]


def lubrication(x_ij, v_ij, d_mean, mu, gap_min, cutoff):
    """Lubrication between wet grains (W24): F_ij = −3πμ d̄²/(8 s) (v_ij·x_ij/|x_ij|²) x_ij,
    s = |x_ij| − d̄ the gap, regularised as s ← max(s, gap_min) (never divides by zero) and
    zero for s > cutoff. Force on i from j; pairs (n, K, 2)."""
    r2 = jnp.sum(x_ij * x_ij, axis=-1)
    r = jnp.sqrt(r2 + 1e-300)
    gap = jnp.maximum(r - d_mean, gap_min)
    coef = -3.0 * jnp.pi * mu * d_mean ** 2 / (8.0 * gap) * jnp.sum(v_ij * x_ij, axis=-1) / (
        r2 + 1e-300)
    return jnp.where((r - d_mean <= cutoff)[..., None], coef[..., None] * x_ij, 0.0)


def reaction_weights(w, vol, valid):
    """Kernel weights normalised per grain, w_k V_k / Σ w V (W47–48): the fluid neighbours'
    shares of the grain's force, summing to exactly 1 (0 for a grain without fluid)."""
    wv = jnp.where(valid, w * vol, 0.0)
    den = jnp.sum(wv, axis=1, keepdims=True)
    return wv / jnp.where(den > 0, den, 1.0)


def reaction_on_fluid(force_p, weights, idx, n_fluid):
    """Hand −F_p to the fluid neighbours by ``weights`` (W47–48): a scatter-add into (n_f, 2);
    Σ over the fluid equals −Σ_p F_p to round-off wherever every grain has a fluid
    neighbour."""
    share = -weights[..., None] * force_p[:, None, :]
    target = jnp.where(weights > 0, idx, n_fluid)
    out = jnp.zeros((n_fluid + 1, 2), force_p.dtype).at[target.reshape(-1)].add(
        share.reshape(-1, 2))
    return out[:n_fluid]
