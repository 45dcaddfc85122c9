"""Parallel bonds: force–moment law and fracture (physics.md §Parallel bonds; K17–K22,
W26–W38).

A bond between discs A = ``i`` and B = ``j`` is a cement beam of radius R̄ = λ(R_A + R_B)/2
with section A and second moment I:

    slab (2D, thickness t):  A = 2R̄t,  I = (2/3) t R̄³
    circular (K6.1):         A = πR̄²,  I = πR̄⁴/4

**Which law.** This is the *co-rotational total-displacement* form of the incremental law
K17–K20 / W35–W36 (physics.md allows it): instead of summing increments,

    F̄_n = k̄_n c A (d − d0)                                 (tension positive)
    U_s = d0 Δφ − ℓ_A Δθ_A − ℓ_B Δθ_B,  F̄_s = −k̄_s c A U_s
    M̄  = −k̄_n c I (Δθ_B − Δθ_A),        c = (R_A + R_B)/d0

with Δφ the rotation of the bond axis since it was made and Δθ the discs' rotations since
then, ℓ_A = d0 R_A/(R_A + R_B) (= R_A for touching discs). Differentiating in time gives
back exactly the increments of K17–K20 (ΔU_n = (v_B − v_A)·n Δt, ΔU_s = V_s Δt,
Δθ = (ω_B − ω_A)Δt) to first order in the deformation, but the total form neither drifts
with round-off nor produces forces under a rigid rotation (U_s = 0 when Δφ = Δθ_A = Δθ_B),
and it needs no force history, which keeps gradients short.

**Bonds across a gap.** K42 maps k̄_n = E/(R_A + R_B) for touching discs, the stiffness
per area of a bar of length R_A + R_B; the factor c makes a bond between discs a rest length
d0 apart the bar (and beam element) of *that* length: axial stiffness EA/d0, bending EI/d0,
shear GA/d0. c = 1 for touching discs (every packing's nearest neighbours), so the factor
only acts where a builder stretches a lattice to fit a span (``square_packing(stretch=…)``:
a cantilever of 79.375 mm at d = 1.25 mm has columns 1.2599 mm apart).

Forces and moments: on B −F̄_n n + F̄_s (d0/d) t and M̄ − F̄_s ℓ_B; on A the opposite force
and −M̄ − F̄_s ℓ_A (the shear force acts at the contact point, as for contacts). These are
minus the gradient of the bond's energy ½F̄_n²/(k̄_n cA) + ½F̄_s²/(k̄_s cA) + ½M̄²/(k̄_n cI)
in the discs' positions and rotations: U_s turns with the axis at d0/d per unit of B's
sideways motion, so the shear force on the discs is F̄_s d0/d, and then the pair carries
no moment, x_A × F_A + τ_A + x_B × F_B + τ_B = 0 (with F̄_s t it would be F̄_s (d − d0)).
The factor differs from 1 by the bond's strain.

Fracture (K21–K22, W37–W38): tension when F̄_n/A + β̄ |M̄| R̄/I ≥ σ̄_c, else shear when
|F̄_s|/A ≥ τ̄_c. A broken bond never heals; the pair then meets through the contact law only.
"""
from __future__ import annotations

import jax.numpy as jnp

from ..model.options import BondSection
from .pairs import perp


def section(kind: str, r_bar, thickness):
    """(A, I) of the bond section: 'slab' (2D per thickness t) or 'circular'."""
    if kind == BondSection.SLAB:
        return 2.0 * r_bar * thickness, (2.0 / 3.0) * thickness * r_bar ** 3
    if kind == BondSection.CIRCULAR:
        return jnp.pi * r_bar ** 2, 0.25 * jnp.pi * r_bar ** 4
    raise ValueError(f"unknown bond section {kind!r}")


def bond_radius(bp, r_a, r_b):
    """R̄ = λ (R_A + R_B)/2."""
    return bp.lam * 0.5 * (r_a + r_b)


def rest_geometry(x, i, j):
    """Rest length d0 and unit direction e0 of each bond at positions ``x`` (bond creation)."""
    dx = x[j] - x[i]
    d0 = jnp.sqrt(jnp.sum(dx * dx, axis=-1))
    return d0, dx / d0[:, None]


def bond_axis(u, i, j, d0, e0):
    """The axis x_B − x_A of each bond from its rest vector d0 e0 and the discs'
    displacements ``u`` since the bond was made: d0 e0 + (u_B − u_A). Never from the
    discs' positions: in float32 a coordinate of 0.6 m is held to 6·10⁻⁸ m, more than a
    stiff bond stretches under its structure's weight, while the axis built this way is
    held to the bond length's precision (10⁻⁹ m for 10 mm; model.state.SolidState).

    (The stretch written without the cancellation of d − d0, (2 d0 e0·Δu + Δu·Δu)/(d +
    d0), is exact to float32 round-off at any stretch, but a standing float32 wall
    vibrated more with it: 1.11 against 0.60 kPa of largest bond tension in
    tests/solver/test_displacement.py, 0.22 kPa in float64; docs/design.md.)"""
    return d0[:, None] * e0 + (u[j] - u[i])


def bond_loads(bp, kind, u, theta, radius, i, j, d0, e0):
    """Bond forces of every bond as if intact: (F̄_n, F̄_s, M̄, n, ℓ_A, ℓ_B, A, I, R̄).
    ``u`` (n, 2): the discs' displacements since the bonds were made (:func:`bond_axis`)."""
    dx = bond_axis(u, i, j, d0, e0)
    d = jnp.sqrt(jnp.sum(dx * dx, axis=-1))
    n = dx / d[:, None]
    ra, rb = radius[i], radius[j]
    r_bar = bond_radius(bp, ra, rb)
    area, inertia = section(kind, r_bar, bp.thickness)
    # the axis rotation Δφ is the angle from e0 to n, but atan2 lives in (−π, π] and the
    # discs' rotations do not: take it on the branch nearest the discs' mean rotation θ̄,
    # Δφ = θ̄ + ∠(R(θ̄) e0, n), so a tumbling bonded pair stays unloaded (one atan2)
    mean = 0.5 * (theta[i] + theta[j])
    c, s = jnp.cos(mean), jnp.sin(mean)
    ex, ey = c * e0[:, 0] - s * e0[:, 1], s * e0[:, 0] + c * e0[:, 1]
    dphi = mean + jnp.arctan2(ex * n[:, 1] - ey * n[:, 0], ex * n[:, 0] + ey * n[:, 1])
    la, lb = d0 * ra / (ra + rb), d0 * rb / (ra + rb)
    us = d0 * dphi - lb * theta[j] - la * theta[i]
    c = (ra + rb) / d0
    fn = bp.kn * c * area * (d - d0)
    fs = -bp.ks * c * area * us
    m = -bp.kn * c * inertia * (theta[j] - theta[i])
    return fn, fs, m, n, la, lb, area, inertia, r_bar


def bond_stresses(bp, fn, fs, m, area, inertia, r_bar):
    """(σ, τ) compared with the strengths: σ = F̄_n/A + β̄|M̄|R̄/I (K21), τ = |F̄_s|/A (K22)."""
    return fn / area + bp.beta_bar * jnp.abs(m) * r_bar / inertia, jnp.abs(fs) / area


def fracture(bp, sigma, tau, intact):
    """Bonds that break now and how: (still intact, mode 0/1 tension/2 shear)."""
    tension = intact & (sigma >= bp.sigma_c)
    shear = intact & ~tension & (tau >= bp.tau_c)
    mode = jnp.where(tension, 1, jnp.where(shear, 2, 0)).astype(jnp.int32)
    return intact & ~tension & ~shear, mode


def bond_forces(bp, kind, n_solid, u, theta, radius, i, j, d0, e0, intact):
    """Forces and torques of the intact bonds on the discs, with fracture; ``u`` the
    discs' displacements since the bonds were made (:func:`bond_axis`).

    Returns (force (n, 2), torque (n,), intact', mode of new breaks, F̄_n, F̄_s, M̄), the
    last three zero for broken bonds. A bond that breaks in this evaluation exerts nothing."""
    fn, fs, m, n, la, lb, area, inertia, r_bar = bond_loads(bp, kind, u, theta, radius, i, j,
                                                            d0, e0)
    sigma, tau = bond_stresses(bp, fn, fs, m, area, inertia, r_bar)
    alive, mode = fracture(bp, sigma, tau, intact)
    w = alive.astype(u.dtype)
    fn, fs, m = fn * w, fs * w, m * w
    # the shear force on the discs is F̄_s d0/d (module docstring: the energy's gradient)
    t = perp(n) * (d0 / jnp.sqrt(jnp.sum(bond_axis(u, i, j, d0, e0) ** 2, axis=-1)))[:, None]
    f_b = -fn[:, None] * n + fs[:, None] * t
    force = jnp.zeros((n_solid, 2), u.dtype).at[j].add(f_b).at[i].add(-f_b)
    torque = (jnp.zeros((n_solid,), u.dtype).at[j].add(m - fs * lb)
              .at[i].add(-m - fs * la))
    return force, torque, alive, mode, fn, fs, m
