"""Fluid–structure coupling (physics.md §Fluid–structure coupling; W6.1, K §5).

Structure discs take part in the SPH sums as boundary-like particles: they are appended to the
SPH neighbour family after the fixed boundary particles, [fluid; boundary; structure], with
the SPH mass m_S = ρ0 V_S (V_S the area a disc stands for in its packing), the fluid's
smoothing length, and the velocity of their disc. The fluid rows see them through the usual
pair terms; what the structure feels is computed *from the same pair terms*, with the
opposite sign (W6.1, Newton's third law):

    F_S = − Σ_{F: S ∈ N(F)} m_F a_{F←S}

so Σ_F m_F a_{F←S} + Σ_S F_S = 0 to round-off whatever the coupling method.

Three methods (K §5), chosen per scene (``Physics.fsi``):

``stationary``              (K method 1) ρ_S = ρ0 and P_S keep their initial values (0 here:
                            the structure is dry when the run starts); fluid–structure pairs
                            use the SPH continuity (K32), pressure (K34) and viscous (K36)
                            terms with the structure's velocity.
``pressure_gradient``       (K40) the pressure pair term is F_{F←S} = −(m_F m_S/(ρ_F ρ_S)) P_F
                            ∇W(x_F − x_S): only the fluid's own pressure, over the structure
                            particle's volume m_S/ρ_S. K found it the least noisy.
``pressure_approximation``  (K41) P_S = Σ_F P_F W_SF m_F/ρ_F (not normalised, as K writes it),
                            ρ_S from the inverted Tait EOS, then the ordinary pressure term.

A fourth method is ours, not K's:

``extrapolated``            the structure particles get the pressure the tank walls get
                            (Adami, Hu & Adams 2012): P_S = (Σ_F P_F W_SF + (g − a_S)·Σ_F ρ_F
                            x_SF W_SF)/Σ_F W_SF, clamped at P ≥ 0, ρ_S from the inverted EOS,
                            then the ordinary pressure term. K40 and K41 give a wall about half
                            the pressure it should (K41 is not normalised; K40 drops P_S), so
                            a fluid column compresses into the structure until the near-wall
                            pressure has doubled, and it leaks through a 5 mm plate at the
                            seeds' resolution (docs/design.md).

In all of them the continuity equation and the Morris viscosity include the fluid–structure
pairs (the structure is a moving wall for the fluid); anti-clump, XSPH and δ-SPH stay
fluid–fluid. SPH boundary particles and DEM walls never interact with the discs.
"""
from __future__ import annotations

import jax.numpy as jnp

from .pairs import FAR, gather, norm2, safe_sqrt


def structure_mask(idx, first, n_structure):
    """Pairs whose neighbour is a structure particle: ``first`` ≤ idx < first + n_structure
    (the padding index is first + n_structure)."""
    return (idx >= first) & (idx < first + n_structure)


def pressure_gradient_bracket(coef, p_i, inv_rho_i, inv_rho_j, idx, first, n_structure):
    """The pressure bracket ``coef`` (K34: P_i/ρ_i² + P_j/ρ_j²) with the fluid–structure pairs
    (neighbour index in [first, first + n_structure)) of the pressure-gradient method replaced
    by P_F/(ρ_F ρ_S) (K40); the densities are given as 1/ρ."""
    is_structure = structure_mask(idx, first, n_structure)
    return jnp.where(is_structure, (p_i * inv_rho_i)[:, None] * inv_rho_j, coef)


def approximate_pressure(kern, n_fluid, x, h, rho, p, mass, idx_s):
    """K41: P_S = Σ_F P_F W_SF m_F/ρ_F over the fluid neighbours of each structure row, (the
    caller takes ρ_S = ρ0 (1 + P_S/B)^(1/γ) from the inverted Tait EOS, eos.density). ``x, h, rho, p, mass`` cover all
    SPH particles; ``idx_s`` is the (n_s, K) list of the structure rows, which are the last
    n_s particles."""
    ns = idx_s.shape[0]
    xs, hs = x[-ns:], h[-ns:]
    nbr = gather(jnp.concatenate([x, h[:, None], rho[:, None], p[:, None], mass[:, None]],
                                     axis=1), idx_s, fill=FAR)
    dx = xs[:, None, :] - nbr[..., 0:2]
    r = safe_sqrt(norm2(dx))
    w = jnp.where(idx_s < n_fluid, kern.w(r, 0.5 * (hs[:, None] + nbr[..., 2])), 0.0)
    ps = jnp.sum(w * nbr[..., 4] * nbr[..., 5] / nbr[..., 3], axis=1)
    return ps


def reaction(acc_pairs, mass_f, found):
    """Force of the fluid on each structure particle S: F_S = −Σ_F m_F a_{F←S} over its
    fluid neighbours F (W6.1). ``acc_pairs`` (n_s, K, 2) is the acceleration the momentum
    pair law gives F from S, computed as F's own row computes it (solver.stages
    .structure_reaction), ``mass_f`` (n_s, K) m_F, ``found`` (n_s, K) the slots that hold a
    fluid neighbour. Every fluid–structure pair term is counted once, so Σ_S F_S is minus
    the structure's share of Σ_F m_F a_F up to the order of additions."""
    return -jnp.sum(jnp.where(found[..., None], mass_f[..., None] * acc_pairs, 0.0), axis=1)
