"""Fluid–particle interaction (physics.md §Fluid–particle coupling; W2.2, W3.1.2–3.1.4, W4.2).

Grains are free DEM discs that do not take part in the SPH sums as particles; they act on the
fluid through the voidage ε (the fluid equations use ερ, W42–W43) and through the reaction of
the pressure and drag forces they feel (W47–W48). They sit at the end of the SPH neighbour family,
so each grain row of the list holds its fluid neighbours; everything here works on those rows
(``idx`` (n_g, K), padding and non-fluid neighbours masked by ``valid``).

Choices the seeds leave open (docs/physics.md, docs/design.md):

* Voidage. In 2D a disc packing's area fraction reaches 0.91 (ε = 0.09), far outside the
  3D packings that Ergun and Wen–Yu were fitted to; a 2D bed of touching discs would even be
  impermeable. The drag closure (β, Re) therefore always sees the voidage mapped to the
  equivalent 3D packing, ε₃ = 1 − 2/√(π√3) (1 − ε₂)^(3/2), which sends the densest
  hexagonal disc packing to the densest sphere packing (0.09 → 0.26). What the fluid
  equations see is Physics.voidage:
  'area' — the area voidage ε₂ = 1 − Σ V_p W. Volumes add up (fluid ε V plus grains
  (1 − ε) V), so a fluid particle at rest beside a grain is in balance and a grain of the
  fluid's density stays put (it drifts 0.03 d in 0.5 s). For isolated grains.
  'mapped' — ε₃ as well. In a packed bed the fluid keeps 26 % of the space instead of 9 %;
  with 'area' the bed's light fluid particles (ε ≈ 0.1) were driven through the floor within
  200 steps. The price: volumes no longer add up (a grain of the fluid's density sinks, 4.6 d
  in 0.5 s for a 2.5 mm grain among 1.5 mm particles). For beds.
* Buoyancy. By default Archimedes' ρ_f V_p |g| (Physics.fpi_pressure = 'archimedes'):
  W25 without its ε_p, the one static force consistent with the fluid equations (a fluid
  particle of mass ερV at rest beside a grain is in balance only if the reaction handed to
  it is its share of ρ_f V_p g; with W25's ε_p a grain of the fluid's density sinks at
  1 − ε_p of its weight). 'gradient' uses −V_p ∇P of the SPH pressure
  (:func:`pressure_force`), which adds the dynamic pressure of the flow. Either way the
  reaction goes to the fluid with the drag, by kernel weights (W47–W48).
* Shared pressure (Physics.fpi_pressure = 'shared'; the packed beds' choice). The SPH
  pressure force on fluid particle f is the force on its whole cell V_f = m_f/(ε_f ρ_f),
  fluid and grains; with 'archimedes' and 'gradient' the fluid particle (mass ε_f ρ_f V_f)
  takes all of it and the grains' buoyancy comes back to it as a reaction, so any error in
  it is amplified 1/ε_f in acceleration (ten times in a packed 2D bed). 'shared' gives the
  fluid ε_f of it (its acceleration is then −∇P/ρ, the fluid phase's) and the grains in its
  support the rest, split by their part of its solid fraction (:func:`cell_share_on_grains`);
  only the drag goes back to the fluid by kernel weights. The pressure force is shared, not
  created: momentum is conserved to round-off. Its partner is the mixture's continuity:
  the intrinsic density follows Dρ_i/Dt = (ρ_i/ε_i) Σ_j V_j (J_i − J_j)·∇_iW_ij with the
  volume flux J = εu + (1 − ε)v̄ of fluid and grains (:func:`mixture_flux`, whose grain
  weights are those of the shared force). The two are discrete adjoints, so the pressure's
  work on fluid and grains equals the change of the fluid's internal energy pair by pair:
  the coupling conserves energy, which is what keeps a packed bed's pore fluid at rest
  (docs/physics.md, Packed beds).
* Walls (Physics.wall_images). The voidage sum gives a grain its whole kernel mass only
  where its support lies in the fluid; next to a wall the part inside the wall is put back
  by the grain's mirror image in each one-sided DEM wall (:func:`wall_images`), which
  enters the solid fraction only (a bed on a floor: the fluid sees its solid to 0.4 %
  instead of 7 % short).
* Added mass (Physics.added_mass, off by default: the seeds have none). A grain that
  accelerates relative to the fluid accelerates the fluid around it:
  F_a = C_a ρ_f V_p (Du/Dt − dv_p/dt), C_a = 1 for a circular cylinder (Lamb 1932): a disc
  of ρ_p = 1.25 ρ_f settling from rest starts at 0.56 of the acceleration it has without.
  The grain takes it as an inertia m_p + m_a in the DEM sub-steps and m_a Du/Dt in the
  held fluid force (:func:`added_mass`, :func:`fluid_acceleration`); what it took over the
  step, :func:`added_mass_force`, goes back to the fluid with the drag. The fluid's side
  is explicit, so m_a is held below what the grain's fluid can exchange stably
  (:func:`added_mass_limit`: binding in a packed bed, not in open water).
* V_p is the disc's area πR² per unit thickness, the same as the disc's mass ρ_p πR². Under
  the seed's law (Physics.drag = 'sphere') the force per unit mass, and with it the terminal
  velocity, is then exactly that of a sphere of diameter d.
* Drag of a disc (Physics.drag = 'cylinder'). A disc in 2D is a cylinder per unit length:
  its drag is ½ρ_f s² d C_D,cyl(Re) per unit length, C_D,cyl the cylinder's (Sucker &
  Brauer 1975, :func:`cylinder_drag_coefficient`), which is F/V_p = (2/π) C_D ρ_f s²/d per
  unit grain volume against the sphere's ¾ C_D,sph ρ_f s²/d. Above ε = 0.8 it takes
  Wen–Yu's form with the cylinder's coefficient, β = (2/π) C_D,cyl ε(1−ε) ρ_f s ε^(−2.65)/d
  (the same voidage function), so that β/(1−ε) s V_p → ½ρ_f s² d C_D,cyl as ε → 1; a
  packed bed (ε ≤ 0.8) keeps Ergun's permeability, as for spheres.
* Kernel against grain. Every sum here is over the grain's kernel support, so an isolated
  grain is averaged only when its kernel is wider than it: with h = 1.2 d the fluid
  particles on a settling grain's path pass through it and its speed moves by ±30 % with
  the fluid spacing; with h = 2d (Robinson, Ramaioli & Luding 2014) within 1.7 points
  over four spacings (docs/physics.md, *The coupling's kernel against the grain*).
"""
from __future__ import annotations

import functools

from typing import NamedTuple

import jax.numpy as jnp

from ..model.options import Drag, Voidage
from .pairs import gather, norm2, safe_sqrt, sum_neighbours, take_rows

ERGUN_LIMIT = 0.8        # W20: Ergun for ε ≤ 0.8, Wen–Yu above
RE_NEWTON = 1000.0       # W22: C_d = 0.44 above
EPS_MIN = 0.08           # floor of the area voidage (hexagonal disc packing: 0.093)
_PACK_3D = 2.0 / (jnp.pi * 3.0 ** 0.5) ** 0.5   # 2/√(π√3)


def _norm(v, eps=1e-30):
    """|v| along the last axis, with a finite gradient at v = 0."""
    return jnp.sqrt(jnp.sum(v * v, axis=-1) + eps)


def to_fluid(values, idx, valid, n_fluid):
    """Σ over the grain rows of ``values`` (n_g, K) or (n_g, K, c) into their fluid
    neighbours ``idx`` (masked by ``valid``): a scatter-add giving (n_f,) or (n_f, c)."""
    target = jnp.where(valid, idx, n_fluid).reshape(-1)
    tail = values.shape[2:]
    out = jnp.zeros((n_fluid + 1,) + tail, values.dtype).at[target].add(
        values.reshape((-1,) + tail))
    return out[:n_fluid]


def solid_fraction(rows, vol_p, n_fluid):
    """1 − ε₂ at each fluid particle, Σ_p V_p W_pf (discrete W2, with the grains' wall
    images: :func:`grain_rows`), and each grain row's terms V_p W_pf (zero where not
    valid): (n_f,), (n_g, K)."""
    w = rows.w if rows.ws is None else rows.ws
    share = jnp.where(rows.valid, w * vol_p[:, None], 0.0)
    return to_fluid(share, rows.idx, rows.valid, n_fluid), share


def voidage_3d(eps2d):
    """Area voidage of a disc packing → the equivalent 3D voidage,
    ε₃ = 1 − 2/√(π√3) (1 − ε₂)^(3/2) (hexagonal discs → face-centred spheres)."""
    return 1.0 - _PACK_3D * jnp.clip(1.0 - eps2d, 0.0, 1.0) ** 1.5


def fluid_voidage(w, vol_p, idx, valid, n_fluid, mode=Voidage.AREA):
    """ε_f = 1 − Σ_p V_p W(x_f − x_p, h_f) (discrete W2), gathered from the grain rows: each
    grain adds V_p W to its fluid neighbours. ``w`` (n_g, K) kernel values, ``vol_p`` (n_g,).
    The area voidage clipped to [EPS_MIN, 1], mapped to 3D when ``mode`` is 'mapped'."""
    solid = to_fluid(jnp.where(valid, w * vol_p[:, None], 0.0), idx, valid, n_fluid)
    eps = jnp.clip(1.0 - solid, EPS_MIN, 1.0)
    return voidage_3d(eps) if mode == Voidage.MAPPED else eps


def cell_share_on_grains(rows, force_f, vol_p, n_fluid):
    """The grains' part of their fluid particles' cell forces (the 'shared' pressure:
    (1 − ε_f) of the pressure force on fluid particle f's cell, ``force_f`` (n_f, 2)), split
    among the grains in f's support by their part of its solid fraction,
    V_p W_pf / Σ_p V_p W_pf. Every fluid particle with ε < 1 has a grain in its support
    (its solid fraction is that sum), so Σ over the grains equals Σ_f force_f to round-off:
    the cell's pressure force is shared, not created. Returns (n_g, 2)."""
    solid, share = solid_fraction(rows, vol_p, n_fluid)
    frac = share / gather(jnp.where(solid > 0, solid, 1.0), rows.idx)
    return jnp.sum(frac[..., None] * gather(force_f, rows.idx, 0.0), axis=1)


def mixture_flux(rows, eps_f, u_f, v_p, vol_p, n_fluid):
    """The mixture's volume flux at each fluid particle, J_f = ε_f u_f + (1 − ε_f) v̄_f, v̄_f
    the grains' velocity weighted by their part of f's solid fraction, V_p W_pf / Σ_p V_p W_pf
    (the same weights as :func:`cell_share_on_grains`, whose force is this flux's
    conjugate). A fluid particle without grains in its support has J = u. (n_f, 2)."""
    solid, share = solid_fraction(rows, vol_p, n_fluid)
    mom = to_fluid(share[..., None] * v_p[:, None, :], rows.idx, rows.valid, n_fluid)
    v_bar = mom / jnp.where(solid > 0, solid, 1.0)[:, None]
    return eps_f[:, None] * u_f + (1.0 - eps_f)[:, None] * v_bar


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


def cylinder_drag_coefficient(re):
    """C_D of a circular cylinder in cross-flow per unit length, Sucker & Brauer (1975,
    Wärme- und Stoffübertragung 8:149), 10⁻⁴ < Re < 2·10⁵:
    C_D = 1.18 + 6.8 Re^(−0.89) + 1.96 Re^(−½) − 4·10⁻⁴ Re/(1 + 3.64·10⁻⁷ Re²)
    (2.08 at Re = 20 against 2.05 of Dennis & Chang's 1970 steady solution)."""
    safe = jnp.maximum(re, 1e-12)
    return (1.18 + 6.8 * safe ** -0.89 + 1.96 * safe ** -0.5
            - 4e-4 * safe / (1.0 + 3.64e-7 * safe * safe))


def interphase_beta(eps, slip, rho_f, d, mu, law=Drag.SPHERE):
    """Momentum-exchange coefficient β (W20): Ergun for ε ≤ 0.8,
    150(1−ε)²μ/(εd²) + 1.75(1−ε)ρ_f|ū−v|/d; Wen & Yu above,
    ¾ C_d ε(1−ε) ρ_f |ū−v| ε^(−2.65)/d (W20 prints 7.5; the published coefficient is 3/4).
    ``law`` 'cylinder': above ε = 0.8, (2/π) C_D,cyl ε(1−ε) ρ_f |ū−v| ε^(−2.65)/d with
    :func:`cylinder_drag_coefficient` (module docstring)."""
    return (1.0 - eps) * beta_per_solid(eps, slip, rho_f, d, mu, law)


def beta_per_solid(eps, slip, rho_f, d, mu, law=Drag.SPHERE):
    """β/(1 − ε), what the drag W19 multiplies V_p (ū − v) by: both branches of β (W20)
    carry the factor (1 − ε), cancelled here rather than divided out, so a grain whose
    fluid neighbours are clear water (ε = 1: one fluid particle at the edge of its kernel,
    as when a wave front reaches a dry grain) gets the finite Wen–Yu limit instead of
    0/0 (in float32 any ε within 6·10⁻⁸ of 1 rounds to 1)."""
    ergun = 150.0 * (1 - eps) * mu / (eps * d * d) + 1.75 * rho_f * slip / d
    re = reynolds(slip, eps, rho_f, d, mu)
    if law == Drag.CYLINDER:
        coef = 2.0 / jnp.pi * cylinder_drag_coefficient(re)
    else:
        coef = 0.75 * drag_coefficient(re)
    wen_yu = coef * eps * rho_f * slip * eps ** (-2.65) / d
    return jnp.where(eps <= ERGUN_LIMIT, ergun, wen_yu)


def drag_force(eps, u_f, v_p, vol_p, rho_f, d, mu, law=Drag.SPHERE):
    """F_d = β/(1 − ε) (ū_f − v_p) V_p (W19) on each grain; ``u_f`` the Shepard fluid
    velocity at the grain, ``eps`` its voidage (≤ 1; :func:`beta_per_solid`)."""
    rel = u_f - v_p
    slip = _norm(rel)
    return (beta_per_solid(eps, slip, rho_f, d, mu, law) * vol_p)[:, None] * rel


def lubrication(x_ij, v_ij, d_mean, mu, gap_min, cutoff):
    """Lubrication between wet grains (W24): F_ij = −3πμ d̄²/(8 s) (v_ij·x_ij/|x_ij|²) x_ij,
    s = |x_ij| − d̄ the gap, regularised as s ← max(s, gap_min) (never divides by zero) and
    zero for s > cutoff. Force on i from j; pairs (n, K, 2)."""
    fx, fy = _lubrication_xy(x_ij[..., 0], x_ij[..., 1], v_ij[..., 0], v_ij[..., 1], d_mean,
                             mu, gap_min, cutoff)
    return jnp.stack([fx, fy], axis=-1)


def _lubrication_xy(xx, xy, vx, vy, d_mean, mu, gap_min, cutoff):
    """:func:`lubrication` on the components of x_ij and v_ij: (F_x, F_y). The (n, K)
    components make the whole law one loop on XLA:CPU, which emits a sum over a last axis
    of 2 as a reduction of its own."""
    r2 = xx * xx + xy * xy
    r = jnp.sqrt(r2 + 1e-300)
    gap = jnp.maximum(r - d_mean, gap_min)
    coef = -3.0 * jnp.pi * mu * d_mean ** 2 / (8.0 * gap) * (vx * xx + vy * xy) / (
        r2 + 1e-300)
    coef = jnp.where(r - d_mean <= cutoff, coef, 0.0)
    return coef * xx, coef * xy


def reaction_weights(w, vol, valid, wall=None):
    """Kernel weights normalised per grain, w_k V_k / (Σ w V + wall) (W47–W48): the fluid
    neighbours' shares of the grain's force. Without ``wall`` they sum to exactly 1 (0 for a
    grain without fluid); ``wall`` (n_g,) is the boundary particles' part of the support
    (:func:`wall_share`), which takes the rest."""
    wv = jnp.where(valid, w * vol, 0.0)
    den = jnp.sum(wv, axis=1, keepdims=True) + (0.0 if wall is None else wall[:, None])
    return wv / jnp.where(den > 0, den, 1.0)


def reaction_on_fluid(force_p, weights, idx, n_fluid):
    """Hand −F_p to the fluid neighbours by ``weights`` (W47–48): a scatter-add into (n_f, 2);
    Σ over the fluid equals −Σ_p F_p to round-off wherever every grain has a fluid
    neighbour."""
    return to_fluid(-weights[..., None] * force_p[:, None, :], idx, weights > 0, n_fluid)


# --- the coupling, on the grain rows of the SPH list --------------------------------------
class GrainRows(NamedTuple):
    """Each grain's fluid neighbours: indices into the fluid (padding n_f), mask, W_pf,
    V_f = m_f/(ε_f ρ_f) (the particle's share of the mixture volume), x_pf = x_p − x_f,
    F_pf = (1/r) dW/dr (so ∇_p W_pf = x_pf F_pf) and ``ws``, the weight of the grain in
    the fluid's solid fraction: W_pf plus the kernel values of its wall images
    (:func:`wall_images`; W_pf where there are none)."""

    idx: object
    valid: object
    w: object
    vol: object
    dx: object
    f: object
    ws: object = None


class WallImages(NamedTuple):
    """The grains' mirror images in the walls (:func:`wall_images`): ``x`` (n_g, W, 2),
    ``on`` (n_g, W) whether grain p has an image in wall k, and each wall's line, a point
    ``a`` (W, 2) and the unit normal ``n_in`` (W, 2) into the fluid's side."""
    x: object
    on: object
    a: object
    n_in: object


def wall_images(x_p, a, b, side) -> WallImages:
    """Mirror images of the grains in the one-sided DEM walls a[k] → b[k] (``side`` ±1, the
    fluid's side; scene.WallBlock): x'_pk = x_p − 2 s_pk n_k, with n_k the wall's inward
    normal and s_pk = (x_p − a_k)·n_k > 0 the grain's distance from the wall's line, for the
    walls whose segment the grain projects onto; two-sided walls (side 0) have none. An
    image counts only for fluid on the wall's fluid side (:func:`grain_rows`): water behind
    a thin obstacle, or beyond one far from the grain, never sees it.

    Why: the voidage sum 1 − ε_f = Σ_p V_p W(x_f − x_p) gives each grain its whole kernel
    mass only where its support lies in the fluid. Next to a wall part of it lies inside
    the wall, where no fluid particle is, so the fluid sees less solid than the bed holds
    (a bed on a floor: 6.8 %) and the pore fluid under the bottom row sees half a bed.
    The image puts that part back on the fluid's side (the reflection of a kernel's
    outside part is its image's inside part), as ghost particles do for a wall in SPH:
    Σ_f V_f (W_pf + W_p'f) = 1 for a grain on a floor in a uniform fluid. The images
    only enter the solid fraction (the voidage, and the weights of the 'shared'
    pressure force and of J in :func:`cell_share_on_grains`, :func:`mixture_flux`), so the
    force that goes to an image is the real grain's, unreflected: the image carries the
    grain's share of the pressure field continued into the wall (hydrostatic: the same
    ρ g on both sides), and force and flux weights stay each other's adjoints. A grain in
    a corner gets the two wall images but not the corner's double reflection."""
    dtype = x_p.dtype
    a, b, side = jnp.asarray(a, dtype), jnp.asarray(b, dtype), jnp.asarray(side, dtype)
    ab = b - a
    t = ab / jnp.linalg.norm(ab, axis=-1, keepdims=True)
    n_in = side[:, None] * jnp.stack([-t[:, 1], t[:, 0]], axis=-1)       # (W, 2)
    rel = x_p[:, None, :] - a[None]
    along = jnp.sum(rel * ab[None], axis=-1) / jnp.sum(ab * ab, axis=-1)
    dist = jnp.sum(rel * n_in[None], axis=-1)                             # (n_g, W)
    on = (side[None] != 0) & (along >= 0.0) & (along <= 1.0) & (dist > 0.0)
    return WallImages(x_p[:, None, :] - 2.0 * dist[..., None] * n_in[None], on, a, n_in)


def grain_rows(kern, x_f, h_f, vol_f, x_p, idx_g, n_fluid, images=None) -> GrainRows:
    """Kernel values W(|x_p − x_f|, h_f) (the fluid particle's h) of the grain rows ``idx_g``,
    whose entries below n_fluid are fluid neighbours. ``images`` (:func:`wall_images`) add
    their kernel values W(|x'_pk − x_f|, h_f) to ``ws`` for the fluid on wall k's fluid
    side: an image is farther from every such fluid particle than its grain, so the
    grain's row holds all of its image's neighbours."""
    valid = idx_g < n_fluid
    j = jnp.where(valid, idx_g, n_fluid)
    nbr = gather(jnp.concatenate([x_f, h_f[:, None], vol_f[:, None]], axis=1), j)
    dx = x_p[:, None, :] - nbr[..., 0:2]
    r2 = norm2(dx)
    w = jnp.where(valid, kern.w(safe_sqrt(r2), nbr[..., 2]), 0.0)
    f = jnp.where(valid, kern.grad_factor(r2, nbr[..., 2]), 0.0)
    ws = w
    if images is not None:
        for k in range(images.x.shape[1]):
            r_k = safe_sqrt(norm2(images.x[:, None, k, :] - nbr[..., 0:2]))
            front = jnp.sum((nbr[..., 0:2] - images.a[k]) * images.n_in[k], axis=-1) > 0.0
            ws = ws + jnp.where(valid & images.on[:, k:k + 1] & front,
                                kern.w(r_k, nbr[..., 2]), 0.0)
    return GrainRows(j, valid, w, jnp.where(valid, nbr[..., 3], 0.0), dx, f, ws)


def pressure_gradient(rows: GrainRows, p_f):
    """∇P at each grain from its fluid neighbours by a kernel-weighted linear least-squares
    fit P ≈ P_0 + ∇P·(x_f − x_p), weights V_f W_pf: exact for a linear pressure field even
    where the kernel is cut by a wall or the free surface (a plain SPH gradient loses a third
    of ρg there). Lengths are scaled by the weighted neighbour distance and a 1e-9 ridge
    keeps a grain with too few neighbours finite."""
    wv = jnp.where(rows.valid, rows.w * rows.vol, 0.0)
    r = -rows.dx                                                     # x_f − x_p
    scale = jnp.sqrt(jnp.sum(wv * jnp.sum(r * r, -1), 1) / jnp.maximum(jnp.sum(wv, 1), 1e-30)
                     + 1e-30)
    basis = jnp.concatenate([jnp.ones_like(r[..., :1]), r / scale[:, None, None]], -1)
    m = jnp.einsum("pk,pki,pkj->pij", wv, basis, basis) + 1e-9 * jnp.eye(3)
    rhs = jnp.einsum("pk,pk,pki->pi", wv, gather(p_f, rows.idx, 0.0), basis)
    coef = jnp.linalg.solve(m, rhs[..., None])[..., 0]
    return coef[:, 1:] / scale[:, None]


def pressure_force(rows: GrainRows, p_f, vol_p):
    """−V_p ∇P at each grain (the 'gradient' buoyancy; :func:`pressure_gradient`)."""
    return -vol_p[:, None] * pressure_gradient(rows, p_f)


def grain_drag(rows: GrainRows, eps_f, v_f, v_p, vol_p, d_p, rho_f, mu, voidage_mode=Voidage.AREA,
               law=Drag.SPHERE):
    """Grain voidage ε_p (W18), fluid velocity ū_f (W21), wetness Σ V_f W and the drag on
    each grain (W19–W23). ε_p is the Shepard average of the fluid's voidage, mapped to 3D
    for the closure when the fluid's is the area voidage (``voidage_mode`` 'area'). A grain
    without fluid neighbours is dry: no drag. Returns (ε_p as the closure sees it, ū_f,
    wet, drag)."""
    eps_p, wet = shepard(gather(eps_f, rows.idx), rows.w, rows.vol, rows.valid)
    u_f, _ = shepard(gather(v_f, rows.idx, 0.0), rows.w, rows.vol, rows.valid)
    is_wet = wet > 0
    if voidage_mode == Voidage.AREA:
        eps_p = voidage_3d(eps_p)
    eps_p = jnp.where(is_wet, jnp.clip(eps_p, EPS_MIN, 1.0), 1.0)
    drag = drag_force(eps_p, u_f, v_p, vol_p, rho_f, d_p, mu, law)
    return eps_p, u_f, wet, jnp.where(is_wet[:, None], drag, 0.0)


def fluid_acceleration(rows: GrainRows, acc_f):
    """Du/Dt at each grain: the Shepard average of its fluid neighbours' accelerations
    ``acc_f`` (the weights of ū_f, W21); 0 for a dry grain. The step passes the fluid's
    acceleration under its own pressure, viscous and gravity forces with the grains'
    buoyancy handed back, not their drag (the grain's own disturbance)."""
    du, wet = shepard(gather(acc_f, rows.idx, 0.0), rows.w, rows.vol, rows.valid)
    return jnp.where((wet > 0)[:, None], du, 0.0)


def added_mass(c_a, rho_f, vol_p, wet):
    """m_a = C_a ρ_f V_p of each wet grain (0 for a dry one): the fluid a grain drags along
    when it accelerates relative to the fluid. For a circular cylinder in potential flow
    C_a = 1 (Lamb 1932, §68: the fluid's kinetic energy about a cylinder moving at U is
    ½ ρ_f π R² U² per unit length), so a disc released from rest in still fluid starts at
    (ρ_p − ρ_f) g/(ρ_p + C_a ρ_f) instead of (ρ_p − ρ_f) g/ρ_p: 0.56 of it for the
    settling disc of W6.2.1 (ρ_p = 1.25 ρ_f)."""
    return jnp.where(wet > 0, c_a * rho_f * vol_p, 0.0)


def added_mass_limit(rows: GrainRows, m_f):
    """The largest added mass each grain can exchange with its fluid explicitly and stay
    stable: ½ / Σ_f s_pf L_f / m_f, s_pf the Shepard weights Du/Dt is read with, L_f =
    Σ_q r_qf the reaction shares fluid particle f takes from all grains (W47–W48 weights).

    The fluid takes the added-mass force a step late, so a grain and the fluid it reads
    Du/Dt from form a loop whose gain per step is about m_a m_p/((m_p + m_a) M), M the
    fluid's mass seen through the two sets of weights, shared between the grains it
    serves: above 1 the exchange grows from step to step (the added-mass instability of
    partitioned schemes). An isolated grain in open water has M ≫ m_a and keeps C_a ρ_f V_p
    (the settling disc at h = 2d: 8.6 times m_a); a grain in a packed bed, whose few
    light pore particles serve several grains, is held to half the stable value (without
    it the two-phase dam break's bed blew up at its 28th step)."""
    n_f = m_f.shape[0]
    r = jnp.where(rows.valid, reaction_weights(rows.w, rows.vol, rows.valid), 0.0)
    load = jnp.zeros(n_f + 1, r.dtype).at[rows.idx].add(r)[:n_f]
    wv = jnp.where(rows.valid, rows.w * rows.vol, 0.0)
    den = jnp.sum(wv, axis=1)
    gain = jnp.sum(wv * gather(load / m_f, rows.idx, 0.0), axis=1) / jnp.where(den > 0, den, 1.0)
    return 0.5 / jnp.maximum(gain, 1e-30)


def added_mass_force(m_a, du_f, dv_p, dt):
    """The added-mass force a grain took over a step, m_a (Du/Dt − Δv_p/Δt), with Δv_p the
    grain's velocity change over the step (Maxey & Riley 1983's C_a ρ_f V_p (Du/Dt − dv/dt)
    averaged over the step). The grain takes it implicitly, its translational inertia m_p +
    m_a against its other forces plus m_a Du/Dt, which keeps the sub-steps explicit and
    stable; the fluid takes −1 times it by the reaction's weights, so momentum is exchanged,
    not created."""
    return m_a[:, None] * (du_f - dv_p / dt)


def wall_share(kern, x_b, h_b, vol_b, x_p, idx_g, n_fluid):
    """Σ_b V_b W(|x_p − x_b|, h_b) over the SPH boundary particles among each grain's
    neighbours (entries n_fluid … n_fluid + n_b − 1 of ``idx_g``): the wall's part of the
    kernel support, which takes its share of the reaction (see
    :func:`reaction_acceleration`)."""
    nb = x_b.shape[0]
    k = idx_g - n_fluid
    valid = (k >= 0) & (k < nb)
    nbr = gather(jnp.concatenate([x_b, h_b[:, None], vol_b[:, None]], axis=1),
                     jnp.where(valid, k, nb))
    r = safe_sqrt(norm2(x_p[:, None, :] - nbr[..., 0:2]))
    return jnp.sum(jnp.where(valid, kern.w(r, nbr[..., 2]) * nbr[..., 3], 0.0), axis=1)


def reaction_acceleration(rows: GrainRows, force_p, m_f, wall=None):
    """The fluid's acceleration from handing −F_p out by kernel weights (W47–W48):
    fluid particle f gets the share V_f W_pf / (Σ_f V_f W_pf + wall_p). ``wall`` (n_g,), the
    boundary particles' Σ V_b W_pb (:func:`wall_share`), lets a wall next to a grain take
    its part, as the floor carries the pressure that buoys a grain lying on it. Without it
    (W48's Shepard normalisation) the few fluid particles between a grain and the floor
    took the whole buoyancy: in a grain bed they were driven through the floor at
    250 m/s². Away from walls the shares sum to one and Σ reaction = −Σ F_p exactly."""
    w = reaction_weights(rows.w, rows.vol, rows.valid, wall)
    return reaction_on_fluid(force_p, w, rows.idx, m_f.shape[0]) / m_f[:, None]


def lubrication_on_discs(x, v, radius, wet, idx, mu, gap_min, cutoff, rows=None):
    """Σ_j of W24 over the DEM contact list for every disc: pairs of wet grains only (``wet``
    (n,) bool: a grain with fluid neighbours), gaps regularised and cut off relative to
    d̄ = R_i + R_j (``gap_min``, ``cutoff`` are fractions of d̄). Antisymmetric pair terms:
    Σ over discs is zero (Newton's third law). ``rows`` (r,): only these discs' rows
    (``idx`` is then theirs, (r, K); dem.disc_contacts)."""
    n = x.shape[0]
    valid = idx < n
    own = functools.partial(take_rows, rows=rows)      # this call's rows of an (n, …) array
    tab = jnp.concatenate([x, v, radius[:, None], wet[:, None].astype(x.dtype)], axis=1)
    nbr = gather(tab, idx, 0.0)
    d_mean = own(radius)[:, None] + nbr[..., 4]
    xo, vo = own(x), own(v)
    fx, fy = _lubrication_xy(xo[:, 0, None] - nbr[..., 0], xo[:, 1, None] - nbr[..., 1],
                             vo[:, 0, None] - nbr[..., 2], vo[:, 1, None] - nbr[..., 3],
                             d_mean, mu, gap_min * d_mean, cutoff * d_mean)
    pair = valid & own(wet)[:, None] & (nbr[..., 5] > 0)
    fx, fy = sum_neighbours(jnp.where(pair, fx, 0.0), jnp.where(pair, fy, 0.0))
    return jnp.stack([fx, fy], axis=-1)


def voidage_at(kern, x_f, h_f, x_p, vol_p, mode=Voidage.AREA, walls=None):
    """The fluid voidage at ``x_f`` for grains at ``x_p`` by brute force over all pairs, with
    the same kernel sums as the step (for scene builders: fluid particles among grains get
    mass ε ρ0 Δx², so that their volume m/(ερ) is their lattice cell). ``walls`` (a, b,
    side) of the DEM walls: the grains' wall images count (:func:`wall_images`)."""
    x_f, h_f, x_p = jnp.asarray(x_f), jnp.asarray(h_f), jnp.asarray(x_p)
    n_f = x_f.shape[0]
    idx = jnp.broadcast_to(jnp.arange(n_f), (x_p.shape[0], n_f))
    images = None if walls is None else wall_images(x_p, *walls)
    rows = grain_rows(kern, x_f, h_f, jnp.ones(n_f, x_f.dtype), x_p, idx, n_f, images)
    return fluid_voidage(rows.ws, jnp.asarray(vol_p), rows.idx, rows.valid, n_f, mode)
