"""Weakly compressible SPH fluid (physics.md §SPH: W41–W46, K28–K39).

Pure functions of arrays, one law per function: each ``*_scalar`` (and ``delta_pairs``,
``continuity_pairs``) is one term of one pair of the (rows, K) neighbour table built by
:func:`fpsi_jax.physics.pairs.pairs`, and the two sums the step uses are
:func:`density_rate` and :func:`momentum_rate`. The rows are the *fluid* particles; the
neighbour indices point into [fluid; boundary; structure] and the padding slots at a dummy
particle far away, so every kernel term of a padded slot is exactly zero.

Notation: x_ij = x_i − x_j, v_ij = v_i − v_j, h_ij = (h_i + h_j)/2 (K37: symmetric pairs),
∇_i W_ij = x_ij F_ij with F = (1/r) dW/dr (see ``kernels``). Each pair term is antisymmetric
in (i, j), so the pressure and viscous forces obey Newton's third law and the total momentum
of the fluid is conserved to round-off.
"""
from __future__ import annotations

import jax
import jax.numpy as jnp

from ..model.options import DensityDiffusion
from .pairs import Pairs, dot2, gather, sum_neighbours


def _inv_soft_r2(pr: Pairs):
    """1/(r² + 0.01h²) of every pair, shared by the terms of a pass that divide by it."""
    return 1.0 / (pr.r2 + 0.01 * pr.hij ** 2)


def _inv_mean(rho_i, rho_j):
    """1/ρ̄_ij, ρ̄_ij = (ρ_i + ρ_j)/2."""
    return 2.0 / (rho_i[:, None] + rho_j)


def continuity(rho_i, pr: Pairs):
    """Dρ_i/Dt = ρ_i Σ_j (m_j/ρ_j) v_ij·∇_iW_ij (K32)."""
    return rho_i * jnp.sum(continuity_pairs(pr), axis=1)


def continuity_pairs(pr: Pairs):
    """Pair terms (m_j/ρ_j) v_ij·∇_iW_ij of :func:`continuity` (without the factor ρ_i)."""
    return pr.vol_j * dot2(pr.vij, pr.dx) * pr.f


def delta_pairs(delta, c0, rho_i, pr: Pairs, diffused=None, hydrostatic=None):
    """δ-SPH density diffusion, per pair: δ h_ij c0 ψ_ij·∇_iW_ij V_j, on fluid–fluid pairs
    only (summed over j in :func:`density_rate`).

    Molteni & Colagrossi (2009): ψ_ij = 2(ρ_j − ρ_i) x_ji/(r² + 0.01h²).
    Fourtakas et al. (2019) (``hydrostatic`` = ρ0 g/c0², a vector): the hydrostatic part of
    the difference is left out, ψ_ij = 2(ρ_j − ρ_i − ρ^H_ji) x_ji/(r² + 0.01h²) with
    ρ^H_ji = (ρ0/c0²) g·x_ji, the first-order form of their ρ0[(1 + ρ0 g·x_ji/C_B)^{1/γ} − 1],
    C_B = ρ0c0²/γ (the second-order remainder is (1 − γ) g·x_ji/(2c0²) of the term, below
    1e-3 within the kernel's reach). Near a floor the neighbours all lie above, and the
    Molteni term of a hydrostatic column, Σ_j 2(ρ_j − ρ_i)(−r²F_ij)V_j/(r² + 0.01h²) < 0,
    drains density from the bottom rows: their pressure settles a few per cent below
    ρ0 g d (docs/physics.md, *δ-SPH*). With the hydrostatic part removed the term vanishes
    for a fluid at rest at any depth and still damps the acoustic noise.

    ``diffused`` = (ρ_i, ρ_j) diffuses another density than the one of the volumes m_j/ρ_j
    (with grains: the intrinsic ρ, while the volumes use ερ)."""
    d_i, d_j = (rho_i, pr.rho_j) if diffused is None else diffused
    diff = d_j - d_i[:, None]
    if hydrostatic is not None:
        # ρ_j − ρ_i − ρ^H_ji, ρ^H_ji = (ρ0/c0²) g·x_ji = −(ρ0/c0²) g·x_ij
        diff = diff + (pr.dx[..., 0] * hydrostatic[0] + pr.dx[..., 1] * hydrostatic[1])
    s = (2.0 * diff * (-pr.r2 * pr.f)
         * _inv_soft_r2(pr) * pr.vol_j)
    return delta * c0 * jnp.where(pr.fluid_j, pr.hij * s, 0.0)


def pressure_scalar(m_j, coef, f):
    """Pressure (W43, K34), per pair: the scalar s of the pair term s x_ij =
    −m_j (P_i/ρ_i² + P_j/ρ_j² + R_ij) ∇_iW_ij, i.e. s = −m_j coef F_ij with ``coef`` the
    bracket (anti-clump R_ij included; :func:`voidage_bracket` with grains)."""
    return -(m_j * coef * f)


def voidage_bracket(p_i, inv_rt_i, p_j, inv_rt_j):
    """Pressure bracket with grains, (P_i + P_j)/(ρ̃_i ρ̃_j), ρ̃ = ερ (given as 1/ρ̃): W43's ερ
    in the other symmetric SPH form (still antisymmetric: momentum is conserved). W43 as printed,
    P_i/ρ̃_i² + P_j/ρ̃_j², gives a uniform pressure a net force wherever ε varies,
    ∝ (ε_j/ε_i + ε_i/ε_j − 2) per pair: next to a 2.5 mm grain among 1.5 mm fluid particles
    it pushed still water with up to 0.5 g. This form exerts none for a uniform P on a
    uniform lattice, whatever ε is."""
    return (p_i[:, None] + p_j) * (inv_rt_i[:, None] * inv_rt_j)


def viscous_scalar(mu_i, mu_j, inv_rho_i, inv_rho_j, pr: Pairs):
    """Morris viscosity (K36), per pair: the scalar s of the pair term s v_ij =
    m_j (μ_i + μ_j) v_ij (x_ij·∇_iW_ij)/(ρ_i ρ_j (r² + 0.01h²)); the densities are given
    as 1/ρ."""
    return (pr.m_j * (mu_i + mu_j) * pr.r2 * pr.f * inv_rho_i[:, None] * inv_rho_j
            * _inv_soft_r2(pr))


def artificial_viscosity_scalar(alpha, c0, rho_i, rho_j, pr: Pairs):
    """Monaghan (1992) artificial viscosity, the option DualSPHysics users know (not in the
    seeds; off unless Physics says so), per pair: the scalar s of −m_j Π_ij ∇_iW_ij = s x_ij,
    Π_ij = −α c0 μ_ij/ρ̄_ij for approaching pairs (v_ij·x_ij < 0),
    μ_ij = h_ij v_ij·x_ij/(r² + 0.01h²), so s = −m_j Π_ij F_ij."""
    vx = dot2(pr.vij, pr.dx)
    mu_ij = pr.hij * jnp.minimum(vx, 0.0) * _inv_soft_r2(pr)
    pi_ij = -alpha * c0 * mu_ij * _inv_mean(rho_i, rho_j)
    return -(pr.m_j * pi_ij * pr.f)


def anticlump(r, pr2_i, pr2_j, w, w_dp):
    """R_ij = r (|P_i|/ρ_i² + |P_j|/ρ_j²) (W_ij/W(Δp))⁴ (W45, K38; Monaghan 2000), given
    P/ρ² of the rows (``pr2_i``) and of their neighbours (``pr2_j``)."""
    base = jnp.abs(pr2_i)[:, None] + jnp.abs(pr2_j)
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
    creep through the layers (docs/design.md, "Boundaries"). Written in r² (no root, no
    divide) so it costs little per pair. Conservative, U = β c0²/6 (1 − r²/r0²)³, with stiffness at
    most β c0²/r0²: ``sph_dt`` keeps Δt ≤ r0/(c0 √β), half the leapfrog limit."""
    q = jnp.maximum(1.0 - pr.r2 * (1.0 / (r0 * r0)), 0.0)
    return jnp.where(is_wall, (beta * c0 * c0 / (r0 * r0)) * q * q, 0.0)


def xsph_scalar(eps, rho_i, rho_j, pr: Pairs):
    """XSPH (K39, Monaghan 1989), per pair: the scalar s of the correction
    δv_i = Σ_j s v_ij = −ε Σ_j (m_j/ρ̄_ij) v_ij W_ij, ρ̄_ij = (ρ_i+ρ_j)/2, over fluid
    neighbours only. With the (v = 0) boundary particles in the sum, the transport velocity
    near a wall is pulled towards zero while the momentum is not, and the bottom layer of a
    dam break sinks into the floor (−0.5 mm at t = 0.3 s at dx = 10 mm, through the wall by
    0.35 s at 5 mm; +3 mm, i.e. no penetration, with fluid pairs only)."""
    return -eps * jnp.where(pr.fluid_j, pr.m_j * pr.w * _inv_mean(rho_i, rho_j), 0.0)


def shifting_scalars(vol_j, pr: Pairs):
    """Particle shifting, per pair: the scalars whose neighbour sums are the gradient of the
    particle concentration and the divergence of position,

        ∇C_i = Σ_j V_j ∇_iW_ij = Σ_j (V_j F_ij) x_ij,
        ∇·r_i = −Σ_j V_j x_ij·∇_iW_ij = −Σ_j V_j F_ij |x_ij|²,

    C_i = Σ_j V_j W_ij (Lind et al. 2012, J. Comput. Phys. 231, 1499). ``vol_j``: the
    neighbours' volumes (superficial m/(ερ) with grains), zero on padding slots. Returns
    (s, div) with ∇C_i = Σ_j s x_ij and ∇·r_i = Σ_j div."""
    s = vol_j * pr.f
    return s, -s * pr.r2


def shifting_velocity(a, h, dt, grad_c, div_r, div_min=1.5):
    """δr_i/Δt with δr_i = −A h_i² ∇C_i (Lind et al. 2012's diffusion form, applied each
    step), moved with the position update as the XSPH term is: particles drift from
    crowded to sparse places, which keeps the concentration C uniform in the fluid's
    interior at rest too (forms scaled by the velocity vanish there). Zero where
    ∇·r_i < ``div_min`` (2 in the interior of a 2D fluid, about 1 at a free surface,
    where ∇C points into the fluid and would push the surface particles out; the threshold
    1.5 of DualSPHysics' 2D free-surface test). ``a`` = A (Physics.shifting), ``h``
    (rows,), ``grad_c`` (rows, 2)."""
    k = jnp.where(div_r >= div_min, a * h * h / dt, 0.0)
    return -k[:, None] * grad_c


def smoothing_length_rate(h, rho, drho, n_d=2.0):
    """Dh/Dt = −h/(n_d ρ) Dρ/Dt (K37), n_d = 2 in 2D."""
    return -h / (n_d * rho) * drho


def smoothing_length_among_grains(eta, m, eps, rho, dp, rho0, phi=0.5, variable_h=True):
    """A fluid particle's smoothing length among grains, from its superficial volume
    V = m/(ερ):

        h = η √max(φ V, Δp² ρ0/ρ)     (Δp² when the smoothing length is constant),

    η = h0/Δp of the fluid lattice. The second term is K37 integrated from h0 at ρ0,
    h = h0 √(ρ0/ρ) (a particle that starts at another density takes it at the first step),
    which a clear-water particle (ε = 1, V = Δp² ρ0/ρ) and one born in a bed (m = ε0 ρ0
    Δp², V ≈ Δp² while ε ≈ ε0) keep. Water that runs from clear water into pores of
    voidage ε is spread over V = Δp²/ε: its particles stand Δp/√ε apart and, at a fixed h,
    keep about ε of their neighbours (two or three at ε ≈ 0.13), so its density and
    pressure are no longer kernel averages and the pore water goes unstable
    (docs/physics.md, Packed beds). The first term grows h so that a particle keeps at
    least φ of the lattice's neighbours (their number goes as h²/V). Below that, h stays
    the lattice's: a position-dependent h has no partner term in the shared pressure's
    energy balance, and following every small change of ε (φ = 1) kept a random bed's
    pore water moving at 2–3 % of √(gH); shrinking h where ε rose made a bed unstable.
    Cf. the adaptive h = η (m/ρ)^(1/d) of summation-density SPH (Price 2012, J. Comput.
    Phys. 231, 759–794), here with the superficial density ερ."""
    floor = dp * dp * (rho0 / rho if variable_h else 1.0)
    return eta * jnp.sqrt(jnp.maximum(phi * m / (eps * rho), floor))


def density_rate(phys, sp, rho_i, pr: Pairs, eps=None, rho_intrinsic=None, gravity=None):
    """Dρ/Dt of the fluid rows: continuity (K32) plus δ-SPH diffusion when switched on
    (``phys.density_diffusion``; the Fourtakas form needs ``gravity``).
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
            diffused = (pr.own(rho_intrinsic), gather(rho_intrinsic, pr.idx))
        hydrostatic = None
        if phys.density_diffusion is DensityDiffusion.FOURTAKAS:
            if gravity is None:
                raise ValueError("density_rate: the 'fourtakas' δ-SPH needs the gravity")
            g = (jnp.asarray(sp.rho0 / sp.c0 ** 2) * jnp.asarray(gravity)).astype(pr.dx.dtype)
            hydrostatic = (g[0], g[1])
        # both sums in one variadic reduction over the neighbour axis (a stacked
        # (rows, K, 2) array would be written out first)
        c_sum, d_sum = sum_neighbours(
            cont, delta_pairs(sp.delta, sp.c0, rho_i, pr, diffused, hydrostatic))
        return rho_i * c_sum + (1.0 if eps is None else eps) * d_sum


def momentum_rate(phys, kern, sp, gravity, rho, p, pr: Pairs, with_pairs=False, eps=None,
                  structure_bracket=None, shared=False, h=None, dt=None):
    """dv/dt (pressure with anti-clump, Morris viscosity, gravity; W43, K34–K38; the wall
    backstop :func:`wall_repulsion_scalar` when switched on) and the
    XSPH correction of the fluid rows. ``shared`` (with ``eps``): the pressure force of
    fluid particle i's cell (pressure and anti-clump pair terms, as if the cell were all
    fluid) is shared, ε_i to the fluid particle and 1 − ε_i to the grains in it; the grains'
    part per unit fluid mass is returned as a fourth output (fpi.py, 'shared' pressure).
    ``rho``/``p`` cover all particles (fluid, boundary,
    structure) at the new time level. With grains, ``eps`` is the voidage of every particle
    (1 off the fluid) and the pressure bracket is :func:`voidage_bracket`; the anti-clump
    term (W45) uses ερ too, the viscosity (W44) and XSPH keep ρ.
    ``structure_bracket(coef, p_i, 1/ρ_i, 1/ρ_j, idx)``, when given, replaces the bracket
    of the fluid–structure pairs (the pressure-gradient coupling, K40:
    ``fsi.pressure_gradient_bracket``). With ``Physics.shifting`` = A > 0 the position
    term also carries :func:`shifting_velocity` (``h`` all particles' smoothing lengths,
    ``dt`` the step). Returns (a, δv_XSPH (+ shifting),
    pair accelerations (rows, K, 2) if ``with_pairs`` else None)."""
    # the densities' reciprocals and P/ρ̃² once per particle, gathered with the new ρ and P
    # (second, small gather): a divide per pair costs about ten multiplies
    # (pairs.pair_table)
    inv_rho = 1.0 / rho
    inv_rhp = inv_rho if eps is None else 1.0 / (rho * eps)      # ρ̃ = ερ with grains
    pr2 = p * inv_rhp * inv_rhp
    cols = [rho, p, pr2, inv_rho] + ([] if eps is None else [inv_rhp])
    rp = gather(jnp.stack(cols, axis=1), pr.idx)
    rho_j, p_j, pr2_j, inv_rho_j = rp[..., 0], rp[..., 1], rp[..., 2], rp[..., 3]
    inv_rhp_j = inv_rho_j if eps is None else rp[..., 4]
    rho_i, p_i, pr2_i = pr.own(rho), pr.own(p), pr.own(pr2)
    inv_rho_i, inv_rhp_i = pr.own(inv_rho), pr.own(inv_rhp)
    with jax.named_scope("sph.pressure"):
        if eps is None:
            coef = pr2_i[:, None] + pr2_j
        else:
            coef = voidage_bracket(p_i, inv_rhp_i, p_j, inv_rhp_j)
        if structure_bracket is not None:
            with jax.named_scope("fsi.pressure_bracket"):
                coef = structure_bracket(coef, p_i, inv_rho_i, inv_rho_j, pr.idx)
        if phys.anticlump:
            with jax.named_scope("sph.anticlump"):
                r_ij = anticlump(sp.r_clump, pr2_i, pr2_j, pr.w, kern.w(sp.dp, pr.hij))
                if not phys.anticlump_boundary:
                    r_ij = jnp.where(pr.fluid_j, r_ij, 0.0)
                coef = coef + r_ij
        # every pair term is a scalar times x_ij or v_ij: the four sums are then one
        # variadic reduction over scalars (docs/performance.md)
        s_dx = pressure_scalar(pr.m_j, coef, pr.f)
    solid_share = None
    if shared:
        with jax.named_scope("fpi.shared_pressure"):
            # the cell's pressure force per unit fluid mass is s_dx summed; the fluid keeps
            # ε_i of it, the grains get the rest
            keep = pr.own(eps)
            solid_share = jnp.stack(sum_neighbours(s_dx * pr.dx[..., 0],
                                                   s_dx * pr.dx[..., 1]), axis=1)
            solid_share = (1.0 - keep)[:, None] * solid_share
            s_dx = keep[:, None] * s_dx
    with jax.named_scope("sph.viscosity"):
        s_v = viscous_scalar(sp.mu, sp.mu, inv_rho_i, inv_rho_j, pr)
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
    terms = (ax_, ay_)
    if phys.xsph:
        with jax.named_scope("sph.xsph"):
            s_x = xsph_scalar(sp.eps_xsph, rho_i, rho_j, pr)
            terms += (s_x * vx, s_x * vy)
    if phys.shifting > 0:
        with jax.named_scope("sph.shifting"):
            live = pr.w > 0                  # padding slots carry no volume
            vol_j = jnp.where(live, pr.m_j * inv_rhp_j, 0.0)
            s_c, div = shifting_scalars(vol_j, pr)
            terms += (s_c * dxx, s_c * dxy, div)
    sums = sum_neighbours(*terms)
    acc = jnp.stack(sums[:2], axis=1) + gravity
    xs = jnp.stack(sums[2:4], axis=1) if phys.xsph else jnp.zeros_like(acc)
    if phys.shifting > 0:
        xs = xs + shifting_velocity(phys.shifting, pr.own(h), dt,
                                    jnp.stack(sums[-3:-1], axis=1), sums[-1])
    pair = jnp.stack([ax_, ay_], axis=-1) if with_pairs else None
    if shared:
        return acc, xs, pair, solid_share
    return acc, xs, pair
