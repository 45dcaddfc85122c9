"""Tait equation of state (W46, K35) and its inverse."""
from __future__ import annotations

import jax.numpy as jnp


def pressure(rho, rho0, c0, gamma):
    """Tait equation of state (W46, K35): P = B((ρ/ρ0)^γ − 1), B = c0²ρ0/γ."""
    b = c0 * c0 * rho0 / gamma
    return b * ((rho / rho0) ** gamma - 1.0)


def density(p, rho0, c0, gamma):
    """Inverse of the Tait EOS: ρ = ρ0 (1 + P/B)^(1/γ)."""
    b = c0 * c0 * rho0 / gamma
    return rho0 * jnp.maximum(1.0 + p / b, 1e-6) ** (1.0 / gamma)
