"""Fixed SPH boundary particles (W5, K5 method 1) and their pressure.

With ``BoundaryPressure.FIXED`` the boundary particles keep the ρ and P they were built
with; with ``EXTRAPOLATED`` (Adami, Hu & Adams 2012) their pressure is interpolated from
the fluid around them every step, with the hydrostatic (and wall-acceleration) correction,
so a wall pushes back exactly as hard as the fluid presses on it. The same rule gives the
structure discs their pressure in the ``extrapolated`` fluid–structure coupling.
"""
from __future__ import annotations

import jax.numpy as jnp

from .pairs import FAR, gather, norm2, safe_sqrt, sum_neighbours


def extrapolated_pressure(n_fluid, kern, gravity, x, h, rho, p, idx_b,
                                   acc_b=None, first=None):
    """Boundary pressure from the fluid (Adami, Hu & Adams 2012, Eq. 27):
    P_b = (Σ_f P_f W_bf + (g − a_b)·Σ_f ρ_f x_bf W_bf) / Σ_f W_bf, clamped at P ≥ 0 so a
    wall never pulls the fluid (the caller takes ρ_b from the inverted EOS, eos.density). Rows without fluid get P = 0.
    ``x, h, rho, p`` cover all particles; ``idx_b`` is the (n_b, K) list of boundary rows,
    which start at particle ``first`` (default: right after the n_fluid fluid rows);
    ``acc_b`` the wall particles' acceleration (moving walls, e.g. structure discs)."""
    nb = idx_b.shape[0]
    first = n_fluid if first is None else first
    xb, hb = x[first:first + nb], h[first:first + nb]
    nbr = gather(jnp.concatenate([x, h[:, None], rho[:, None], p[:, None]], axis=1), idx_b,
                 fill=FAR)
    dx = xb[:, None, :] - nbr[..., 0:2]
    r = safe_sqrt(norm2(dx))
    w = jnp.where(idx_b < n_fluid, kern.w(r, 0.5 * (hb[:, None] + nbr[..., 2])), 0.0)
    ab = jnp.zeros_like(xb) if acc_b is None else acc_b
    g_minus_a = gravity[None, :] - ab
    # the four sums over the slots in one variadic reduction of (n_b, K) terms
    wr = w * nbr[..., 3]
    s_p, s_x, s_y, den = sum_neighbours(w * nbr[..., 4], wr * dx[..., 0], wr * dx[..., 1], w)
    num = s_p + g_minus_a[:, 0] * s_x + g_minus_a[:, 1] * s_y
    pb = jnp.maximum(jnp.where(den > 0, num / jnp.where(den > 0, den, 1.0), 0.0), 0.0)
    return pb
