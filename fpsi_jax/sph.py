"""Weakly compressible SPH fluid (physics.md §SPH: W41–W46, K28–K39).

Pure functions of arrays. The pair sums use jax-md's Dense neighbour format: ``idx`` has one
row per *fluid* particle and holds indices into the concatenation [fluid; boundary]; the
padding index is n_fluid + n_boundary, which points at a dummy particle placed far away so
every kernel term of a padded slot is exactly zero.

Notation: x_ij = x_i − x_j, v_ij = v_i − v_j, h_ij = (h_i + h_j)/2 (K37: symmetric pairs),
∇_i W_ij = x_ij F_ij with F = (1/r) dW/dr (see ``kernels``). Each pair term is antisymmetric
in (i, j), so the pressure and viscous forces obey Newton's third law and the total momentum
of the fluid is conserved to round-off.
"""
from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from . import fsi, kernels

FAR = 1.0e6  # position of the padding particle: farther than any cut-off


def eos_pressure(rho, rho0, c0, gamma):
    """Tait equation of state (W46, K35): P = B((ρ/ρ0)^γ − 1), B = c0²ρ0/γ."""
    b = c0 * c0 * rho0 / gamma
    return b * ((rho / rho0) ** gamma - 1.0)


def eos_density(p, rho0, c0, gamma):
    """Inverse of the Tait EOS: ρ = ρ0 (1 + P/B)^(1/γ)."""
    b = c0 * c0 * rho0 / gamma
    return rho0 * jnp.maximum(1.0 + p / b, 1e-6) ** (1.0 / gamma)


class Pairs(NamedTuple):
    """Geometry and kinematics of the (row, neighbour-slot) pairs of one list, shared by the
    density pass and the momentum pass of a step."""

    idx: jax.Array      # (n_rows, K) neighbour indices, padding = N
    fluid_j: jax.Array  # (n_rows, K) neighbour is a fluid particle
    dx: jax.Array       # x_ij (n_rows, K, 2)
    r2: jax.Array       # |x_ij|²
    hij: jax.Array      # (h_i + h_j)/2
    w: jax.Array        # W_ij
    f: jax.Array        # F_ij = (1/r) dW/dr, so ∇_iW_ij = x_ij F_ij
    vij: jax.Array      # v_ij (n_rows, K, 2)
    m_j: jax.Array      # m_j
    rho_j: jax.Array    # ρ_j at the start of the step (for the volumes m_j/ρ_j)


@jax.custom_jvp
def sum_neighbours(*terms):
    """Σ_j of several (rows, K) pair arrays at once: one variadic reduction over the
    neighbour axis, so XLA evaluates the pair terms in one loop instead of writing a
    stacked (rows, K, c) array first. Returns a tuple of (rows,) arrays.

    Its derivative is the plain per-term sum (the JVP rule below): JAX's own transpose of
    a variadic reduce fails when one output's cotangent is a symbolic zero (e.g. a
    gradient that does not depend on the XSPH sums)."""
    zero = tuple(jnp.zeros((), t.dtype) for t in terms)
    return jax.lax.reduce(tuple(terms), zero,
                          lambda a, b: tuple(x + y for x, y in zip(a, b)), (1,))


@sum_neighbours.defjvp
def _sum_neighbours_jvp(primals, tangents):
    return sum_neighbours(*primals), tuple(jnp.sum(t, axis=1) for t in tangents)


def gather(a, idx, fill=1.0):
    """a[idx] with the padding index N mapped to ``fill`` (a may be (N,) or (N, c))."""
    pad = jnp.full((1,) + a.shape[1:], fill, a.dtype)
    return jnp.concatenate([a, pad], axis=0)[idx]


def pairs(kern, n_fluid, x, v, h, m, rho, idx) -> Pairs:
    """Pair geometry for the rows ``idx`` (the first idx.shape[0] particles of x). One packed
    gather of [x, y, vx, vy, h, m, ρ]; the padding row sits far away so W = F = 0 there."""
    rows = idx.shape[0]
    table = jnp.concatenate([x, v, h[:, None], m[:, None], rho[:, None]], axis=1)
    dummy = jnp.array([FAR, FAR, 0.0, 0.0, 1.0, 1.0, 1.0], dtype=table.dtype)[None]
    nbr = jnp.concatenate([table, dummy], axis=0)[idx]   # (rows, K, 7)
    dx = x[:rows, None, :] - nbr[..., 0:2]
    r2 = jnp.sum(dx * dx, axis=-1)
    hij = 0.5 * (h[:rows, None] + nbr[..., 4])
    w = kern.w(kernels.safe_sqrt(r2), hij)
    f = kern.grad_factor(r2, hij)
    vij = v[:rows, None, :] - nbr[..., 2:4]
    return Pairs(idx, idx < n_fluid, dx, r2, hij, w, f, vij, nbr[..., 5], nbr[..., 6])


def continuity(rho_i, pr: Pairs):
    """Dρ_i/Dt = ρ_i Σ_j (m_j/ρ_j) v_ij·∇_iW_ij (K32)."""
    return rho_i * jnp.sum(continuity_pairs(pr), axis=1)


def continuity_pairs(pr: Pairs):
    """Pair terms (m_j/ρ_j) v_ij·∇_iW_ij of :func:`continuity` (without the factor ρ_i)."""
    return pr.m_j / pr.rho_j * jnp.sum(pr.vij * pr.dx, axis=-1) * pr.f


def delta_diffusion(delta, c0, rho_i, pr: Pairs, diffused=None):
    """δ-SPH (Molteni & Colagrossi 2009): δ h c0 Σ_j ψ_ij·∇_iW_ij V_j,
    ψ_ij = 2(ρ_j − ρ_i) x_ji/(r² + 0.01h²); applied to fluid–fluid pairs only.
    ``diffused`` = (ρ_i, ρ_j) diffuses another density than the one of the volumes m_j/ρ_j
    (with grains: the intrinsic ρ, while the volumes use ερ)."""
    return jnp.sum(delta_pairs(delta, c0, rho_i, pr, diffused), axis=1)


def delta_pairs(delta, c0, rho_i, pr: Pairs, diffused=None):
    """Pair terms of :func:`delta_diffusion`."""
    d_i, d_j = (rho_i, pr.rho_j) if diffused is None else diffused
    s = (2.0 * (d_j - d_i[:, None]) * (-pr.r2 * pr.f)
         / (pr.r2 + 0.01 * pr.hij ** 2) * pr.m_j / pr.rho_j)
    return delta * c0 * jnp.where(pr.fluid_j, pr.hij * s, 0.0)


def pressure_pairs(m_j, coef, dx, f):
    """Pair terms −m_j (P_i/ρ_i² + P_j/ρ_j² + R_ij) ∇_iW_ij (W43, K34); ``coef`` is the bracket."""
    return pressure_scalar(m_j, coef, f)[..., None] * dx


def pressure_scalar(m_j, coef, f):
    """The scalar s of :func:`pressure_pairs` = s x_ij: −m_j coef F_ij."""
    return -(m_j * coef * f)


def voidage_bracket(p_i, rt_i, p_j, rt_j):
    """Pressure bracket with grains, (P_i + P_j)/(ρ̃_i ρ̃_j), ρ̃ = ερ: W43's ερ in the other
    symmetric SPH form (still antisymmetric: momentum is conserved). W43 as printed,
    P_i/ρ̃_i² + P_j/ρ̃_j², gives a uniform pressure a net force wherever ε varies,
    ∝ (ε_j/ε_i + ε_i/ε_j − 2) per pair: next to a 2.5 mm grain among 1.5 mm fluid particles
    it pushed still water with up to 0.5 g. This form exerts none for a uniform P on a
    uniform lattice, whatever ε is."""
    return (p_i[:, None] + p_j) / (rt_i[:, None] * rt_j)


def pressure_acc(m_j, coef, dx, f):
    """−Σ_j m_j (P_i/ρ_i² + P_j/ρ_j² + R_ij) ∇_iW_ij (W43, K34); ``coef`` is the bracket."""
    return jnp.sum(pressure_pairs(m_j, coef, dx, f), axis=1)


def viscous_pairs(mu_i, mu_j, rho_i, rho_j, pr: Pairs):
    """Pair terms of the Morris viscosity (K36), see :func:`viscous_acc`."""
    return viscous_scalar(mu_i, mu_j, rho_i, rho_j, pr)[..., None] * pr.vij


def viscous_scalar(mu_i, mu_j, rho_i, rho_j, pr: Pairs):
    """The scalar s of :func:`viscous_pairs` = s v_ij."""
    return (pr.m_j * (mu_i + mu_j) * pr.r2 * pr.f
            / (rho_i[:, None] * rho_j * (pr.r2 + 0.01 * pr.hij ** 2)))


def viscous_acc(mu_i, mu_j, rho_i, rho_j, pr: Pairs):
    """Morris viscosity (K36): Σ_j m_j (μ_i+μ_j) v_ij (x_ij·∇_iW_ij)/(ρ_iρ_j(r²+0.01h²))."""
    return jnp.sum(viscous_pairs(mu_i, mu_j, rho_i, rho_j, pr), axis=1)


def artificial_viscosity_pairs(alpha, c0, rho_i, rho_j, pr: Pairs):
    """Pair terms of :func:`artificial_viscosity`."""
    return artificial_viscosity_scalar(alpha, c0, rho_i, rho_j, pr)[..., None] * pr.dx


def artificial_viscosity_scalar(alpha, c0, rho_i, rho_j, pr: Pairs):
    """The scalar s of :func:`artificial_viscosity_pairs` = s x_ij: −m_j Π_ij F_ij."""
    vx = pr.vij[..., 0] * pr.dx[..., 0] + pr.vij[..., 1] * pr.dx[..., 1]
    mu_ij = pr.hij * jnp.minimum(vx, 0.0) / (pr.r2 + 0.01 * pr.hij ** 2)
    pi_ij = -alpha * c0 * mu_ij / (0.5 * (rho_i[:, None] + rho_j))
    return -(pr.m_j * pi_ij * pr.f)


def artificial_viscosity(alpha, c0, rho_i, rho_j, pr: Pairs):
    """Monaghan (1992) artificial viscosity, the option DualSPHysics users know:
    −Σ_j m_j Π_ij ∇_iW_ij, Π_ij = −α c0 μ_ij/ρ̄_ij for approaching pairs (v_ij·x_ij < 0),
    μ_ij = h_ij v_ij·x_ij/(r² + 0.01h²). Not in the seeds; off unless Physics says so."""
    return jnp.sum(artificial_viscosity_pairs(alpha, c0, rho_i, rho_j, pr), axis=1)


def anticlump(r, p_i, rho_i, p_j, rho_j, w, w_dp):
    """R_ij = r (|P_i|/ρ_i² + |P_j|/ρ_j²) (W_ij/W(Δp))⁴ (W45, K38; Monaghan 2000)."""
    base = jnp.abs(p_i / rho_i ** 2)[:, None] + jnp.abs(p_j / rho_j ** 2)
    return r * base * (w / w_dp) ** 4


def wall_repulsion_scalar(beta, c0, r0, is_wall, pr: Pairs):
    """The scalar s (a_i = s x_ij) of a short-range wall backstop (not in the seeds):
    a_i = (β c0²/r0²) (1 − r²/r0²)² x_ij for a fixed boundary particle j closer than the
    static range r0 = Physics.wall_range = κ min(Δx_wall, Δp) (κ = scene.WALL_KAPPA = 0.8,
    Δx_wall the finest wall spacing √(m_b/ρ0), Δp the fluid's).

    It is zero at rest (the first fluid layer sits (Δp + Δx_wall)/2 from the first wall
    row) and acts on a particle about to pass between two wall particles (≤ Δx_wall/2 from
    both): the Adami wall pressure takes its value from the fluid around it, so a slow
    particle at the free surface of a corner meets a near-zero wall pressure and could
    creep through the layers (README "Wall backstop"). Written in r² (no root, no divide) so
    it costs little per pair. Conservative, U = β c0²/6 (1 − r²/r0²)³, with stiffness at
    most β c0²/r0²: ``sph_dt`` keeps Δt ≤ r0/(c0 √β), half the leapfrog limit."""
    q = jnp.maximum(1.0 - pr.r2 * (1.0 / (r0 * r0)), 0.0)
    return jnp.where(is_wall, (beta * c0 * c0 / (r0 * r0)) * q * q, 0.0)


def xsph_pairs(eps, rho_i, rho_j, pr: Pairs):
    """Pair terms of XSPH (K39, Monaghan 1989), δv_i = −ε Σ_j (m_j/ρ̄_ij) v_ij W_ij,
    ρ̄_ij = (ρ_i+ρ_j)/2, over fluid neighbours only (summed in :func:`momentum_rate`).
    With the (v = 0) boundary particles in the sum, the transport velocity near a wall is pulled towards zero while the momentum is not, and the bottom
    layer of a dam break sinks into the floor (−0.5 mm at t = 0.3 s at dx = 10 mm, through
    the wall by 0.35 s at 5 mm; +3 mm, i.e. no penetration, with fluid pairs only)."""
    return xsph_scalar(eps, rho_i, rho_j, pr)[..., None] * pr.vij


def xsph_scalar(eps, rho_i, rho_j, pr: Pairs):
    """The scalar s of :func:`xsph_pairs` = s v_ij."""
    return -eps * jnp.where(pr.fluid_j, pr.m_j * pr.w / (0.5 * (rho_i[:, None] + rho_j)), 0.0)


def smoothing_length_rate(h, rho, drho, n_d=2.0):
    """Dh/Dt = −h/(n_d ρ) Dρ/Dt (K37), n_d = 2 in 2D."""
    return -h / (n_d * rho) * drho


def density_rate(phys, sp, rho_i, pr: Pairs, eps=None, rho_intrinsic=None):
    """Dρ/Dt of the fluid rows: continuity (K32) plus δ-SPH diffusion when switched on.
    With grains ``rho_i`` is ερ (W42) and δ-SPH diffuses the intrinsic ρ (``rho_intrinsic``,
    all particles), scaled by ε_i: it damps pressure noise without smearing the voidage."""
    if not phys.delta_sph:
        with jax.named_scope("sph.continuity"):
            return continuity(rho_i, pr)
    with jax.named_scope("sph.continuity"):
        cont = continuity_pairs(pr)
    with jax.named_scope("sph.delta"):
        diffused = None
        if eps is not None:
            rows = rho_i.shape[0]
            diffused = (rho_intrinsic[:rows], gather(rho_intrinsic, pr.idx))
        # both sums in one reduction over the neighbour axis (one loop for XLA)
        both = jnp.sum(jnp.stack([cont, delta_pairs(sp.delta, sp.c0, rho_i, pr, diffused)],
                                 axis=-1), axis=1)
        return rho_i * both[:, 0] + (1.0 if eps is None else eps) * both[:, 1]


def momentum_rate(phys, kern, sp, gravity, rho, p, pr: Pairs, with_pairs=False, eps=None):
    """dv/dt (pressure with anti-clump, Morris viscosity, gravity; W43, K34–K38; the wall
    backstop :func:`wall_repulsion_scalar` when switched on) and the
    XSPH correction of the fluid rows. ``rho``/``p`` cover all particles (fluid, boundary,
    structure) at the new time level. With grains, ``eps`` is the voidage of every particle
    (1 off the fluid) and the pressure bracket is :func:`voidage_bracket`; the anti-clump
    term (W45) uses ερ too, the viscosity (W44) and XSPH keep ρ. With a fluid–structure coupling (``phys.fsi``) the
    fluid–structure pairs use its pressure bracket (see ``fsi``). Returns (a, δv_XSPH,
    pair accelerations (rows, K, 2) if ``with_pairs`` else None)."""
    rows = pr.idx.shape[0]
    rho_i, p_i = rho[:rows], p[:rows]
    rp = gather(jnp.stack([rho, p], axis=1), pr.idx)   # second (small) gather: new ρ, P
    rho_j, p_j = rp[..., 0], rp[..., 1]
    if eps is None:
        rhp_i, rhp_j = rho_i, rho_j
    else:
        rhp_i, rhp_j = rho_i * eps[:rows], rho_j * gather(eps, pr.idx)
    with jax.named_scope("sph.pressure"):
        if eps is None:
            coef = (p_i / rhp_i ** 2)[:, None] + p_j / rhp_j ** 2
        else:
            coef = voidage_bracket(p_i, rhp_i, p_j, rhp_j)
        if phys.fsi == "pressure_gradient":
            is_s = fsi.structure_mask(pr.idx, phys.n_fluid + phys.n_boundary, phys.n_structure)
            with jax.named_scope("fsi.pressure_gradient"):
                coef = fsi.pressure_gradient_bracket(coef, p_i, rho_i, rho_j, is_s)
        if phys.anticlump:
            with jax.named_scope("sph.anticlump"):
                r_ij = anticlump(sp.r_clump, p_i, rhp_i, p_j, rhp_j, pr.w,
                                 kern.w(sp.dp, pr.hij))
                if not phys.anticlump_boundary:
                    r_ij = jnp.where(pr.fluid_j, r_ij, 0.0)
                coef = coef + r_ij
        # every pair term is a scalar times x_ij or v_ij: the four sums are then one
        # variadic reduction over scalars (README "Speed")
        s_dx = pressure_scalar(pr.m_j, coef, pr.f)
    with jax.named_scope("sph.viscosity"):
        s_v = viscous_scalar(sp.mu, sp.mu, rho_i, rho_j, pr)
    if phys.artificial_viscosity:
        with jax.named_scope("sph.artificial_viscosity"):
            s_dx = s_dx + artificial_viscosity_scalar(sp.alpha, sp.c0, rho_i, rho_j, pr)
    if phys.wall_repulsion and phys.wall_range > 0:
        with jax.named_scope("sph.wall_repulsion"):
            # without structure discs every non-fluid slot is a wall particle or padding
            # (far away: q = 0), so the fluid mask the pairs already carry suffices
            is_wall = (~pr.fluid_j if not phys.n_structure else
                       (pr.idx >= phys.n_fluid) & (pr.idx < phys.n_fluid + phys.n_boundary))
            s_dx = s_dx + wall_repulsion_scalar(sp.wall_beta, sp.c0, phys.wall_range,
                                                is_wall, pr)
    dxx, dxy, vx, vy = pr.dx[..., 0], pr.dx[..., 1], pr.vij[..., 0], pr.vij[..., 1]
    ax_, ay_ = s_dx * dxx + s_v * vx, s_dx * dxy + s_v * vy
    if phys.xsph:
        with jax.named_scope("sph.xsph"):
            s_x = xsph_scalar(sp.eps_xsph, rho_i, rho_j, pr)
            ax, ay, xx, xy = sum_neighbours(ax_, ay_, s_x * vx, s_x * vy)
        acc, xs = jnp.stack([ax, ay], axis=1) + gravity, jnp.stack([xx, xy], axis=1)
    else:
        acc = jnp.stack(sum_neighbours(ax_, ay_), axis=1) + gravity
        xs = jnp.zeros_like(acc)
    pair = jnp.stack([ax_, ay_], axis=-1) if with_pairs else None
    return acc, xs, pair


def extrapolated_boundary_pressure(n_fluid, kern, sp, gravity, x, h, rho, p, idx_b,
                                   acc_b=None, first=None):
    """Boundary pressure from the fluid (Adami, Hu & Adams 2012, Eq. 27):
    P_b = (Σ_f P_f W_bf + (g − a_b)·Σ_f ρ_f x_bf W_bf) / Σ_f W_bf, clamped at P ≥ 0 so a
    wall never pulls the fluid; ρ_b from the inverted EOS. Rows without fluid get P = 0.
    ``x, h, rho, p`` cover all particles; ``idx_b`` is the (n_b, K) list of boundary rows,
    which start at particle ``first`` (default: right after the n_fluid fluid rows);
    ``acc_b`` the wall particles' acceleration (moving walls, e.g. structure discs)."""
    nb = idx_b.shape[0]
    first = n_fluid if first is None else first
    xb, hb = x[first:first + nb], h[first:first + nb]
    nbr = gather(jnp.concatenate([x, h[:, None], rho[:, None], p[:, None]], axis=1), idx_b,
                 fill=FAR)
    dx = xb[:, None, :] - nbr[..., 0:2]
    r = kernels.safe_sqrt(jnp.sum(dx * dx, axis=-1))
    w = jnp.where(idx_b < n_fluid, kern.w(r, 0.5 * (hb[:, None] + nbr[..., 2])), 0.0)
    ab = jnp.zeros_like(xb) if acc_b is None else acc_b
    g_minus_a = gravity[None, :] - ab
    num = jnp.sum(w * nbr[..., 4], axis=1) + jnp.sum(
        g_minus_a * jnp.sum((w * nbr[..., 3])[..., None] * dx, axis=1), axis=-1)
    den = jnp.sum(w, axis=1)
    pb = jnp.maximum(jnp.where(den > 0, num / jnp.where(den > 0, den, 1.0), 0.0), 0.0)
    return pb, eos_density(pb, sp.rho0, sp.c0, sp.gamma)
