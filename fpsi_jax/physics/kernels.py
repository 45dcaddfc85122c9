"""SPH smoothing kernels in 2D.

Every kernel is given as three functions of the pair distance and the smoothing length:

* ``w(r, h)``          the kernel value W,
* ``dw_dr(r, h)``      its radial derivative dW/dr,
* ``grad_factor(r2, h)`` F = (1/r) dW/dr, so that ∇_i W_ij = x_ij · F_ij.

The last form is what the SPH sums use: it has no 1/r (it is finite and smooth at r = 0), so
two particles that sit on top of each other give a zero force instead of a NaN.

Wendland C2 (K28, W41), support 2h:
    W(q) = 7/(4πh²) (1 − q/2)⁴ (2q + 1),  dW/dr = 7/(4πh³) (−5q) (1 − q/2)³,  q = r/h.
Cubic spline (Monaghan 1992), support 2h, σ = 10/(7πh²).
"""
from __future__ import annotations

from typing import NamedTuple, Callable

import jax.numpy as jnp

from ..model.errors import ParameterError
from ..model.options import KernelKind
from .pairs import safe_sqrt

SUPPORT = 2.0  # both kernels vanish for q >= 2


def _clip_q(r, h):
    return jnp.minimum(r * (1.0 / h), SUPPORT)


# --- Wendland C2 -------------------------------------------------------------------------
def wendland_w(r, h):
    """Wendland C2 kernel value (K28, W41)."""
    q, ih = _clip_q(r, h), 1.0 / h
    return (7.0 / (4.0 * jnp.pi)) * (ih * ih) * (1.0 - 0.5 * q) ** 4 * (2.0 * q + 1.0)


def wendland_dw_dr(r, h):
    """dW/dr of the Wendland C2 kernel (K28)."""
    q = _clip_q(r, h)
    return 7.0 / (4.0 * jnp.pi * h ** 3) * (-5.0 * q) * (1.0 - 0.5 * q) ** 3


def wendland_grad_factor(r2, h):
    """(1/r) dW/dr for Wendland C2: −35/(4πh⁴) (1 − q/2)³, finite at r = 0."""
    ih = 1.0 / h
    q = jnp.minimum(safe_sqrt(r2) * ih, SUPPORT)
    ih2 = ih * ih
    return (-35.0 / (4.0 * jnp.pi)) * (ih2 * ih2) * (1.0 - 0.5 * q) ** 3


# --- cubic spline ------------------------------------------------------------------------
def cubic_w(r, h):
    """Cubic B-spline kernel value (Monaghan 1992), 2D normalisation 10/(7πh²)."""
    q = _clip_q(r, h)
    s = 10.0 / (7.0 * jnp.pi * h * h)
    inner = 1.0 - 1.5 * q ** 2 + 0.75 * q ** 3
    outer = 0.25 * (2.0 - q) ** 3
    return s * jnp.where(q < 1.0, inner, outer)


def cubic_dw_dr(r, h):
    """dW/dr of the cubic spline."""
    q = _clip_q(r, h)
    s = 10.0 / (7.0 * jnp.pi * h ** 3)
    inner = -3.0 * q + 2.25 * q ** 2
    outer = -0.75 * (2.0 - q) ** 2
    return s * jnp.where(q < 1.0, inner, outer)


def cubic_grad_factor(r2, h):
    """(1/r) dW/dr for the cubic spline, finite at r = 0."""
    r = safe_sqrt(r2)
    q = jnp.minimum(r / h, SUPPORT)
    s = 10.0 / (7.0 * jnp.pi * h ** 4)
    inner = -3.0 + 2.25 * q
    outer = -0.75 * (2.0 - q) ** 2 / jnp.maximum(q, 1.0)
    return s * jnp.where(q < 1.0, inner, outer)


class Kernel(NamedTuple):
    name: str
    w: Callable
    dw_dr: Callable
    grad_factor: Callable


KERNELS = {
    KernelKind.WENDLAND: Kernel("wendland", wendland_w, wendland_dw_dr, wendland_grad_factor),
    KernelKind.CUBIC: Kernel("cubic", cubic_w, cubic_dw_dr, cubic_grad_factor),
}


def get(kind: KernelKind | str) -> Kernel:
    """The kernel of ``kind`` (a :class:`~fpsi_jax.model.options.KernelKind` or its name)."""
    try:
        return KERNELS[KernelKind(kind)]
    except ValueError:
        raise ParameterError(f"kernel = {kind!r} is not a choice; allowed: "
                             f"{', '.join(k.value for k in KernelKind)}") from None
