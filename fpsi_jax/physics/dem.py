"""DEM contacts between discs and with line-segment walls; local damping
(physics.md §DEM; W10–W17, K5–K16, K25).

Conventions for a pair A–B (A the row particle ``i``, B its neighbour ``j`` or a wall):

    n = (x_B − x_A)/d,  t = (−n_y, n_x),  δ = R_A + R_B − d   (contact while δ > 0)
    lever ℓ = R − δ/2 (contact point in the middle of the overlap; K8 R + U_n/2, K16)
    V_s = (v_B − v_A)·t − ω_B ℓ_B − ω_A ℓ_A                     (W11–W13, K7–K13)
    F_n = k_n δ + 2β_n √(m k_n) δ̇,  δ̇ = −(v_B − v_A)·n         (W10, W15–W17)
    F_s ← F_s − k_s V_s Δt,  |F_s| ≤ μ k_n δ                     (W13, W14)
    shear dashpot −2β_s √(m k_s) V_s while the contact sticks
    force on A: −F_n n − F_s t,  on B the opposite;  torque on A and on B: −F_s ℓ   (K16)

m is the reduced mass m_A m_B/(m_A + m_B) (a disc's own mass against a wall or a clamped
disc). The dashpot force is not clamped: the normal force may pull briefly at the end of a
damped contact, which ends when δ returns to 0, so the restitution coefficient is exactly
exp(−πβ/√(1−β²)) and the contact time π/√(k/m (1−β²)) (tests/physics/test_dem.py).

The shear force is contact history: it is stored per (row particle, neighbour slot) of the
Dense contact list and re-addressed by the *pair* (i, j) whenever the list changes
(:func:`remap_history`), and it is reset to 0 as soon as a contact opens.

Every pair is evaluated from both sides. The scalar F_s and V_s are symmetric under A ↔ B
while n and t change sign, so the two evaluations give equal and opposite forces (to
round-off) and identical torques.
"""
from __future__ import annotations

import functools

import jax.numpy as jnp

from .pairs import perp, sum_neighbours, take_rows


def reduced_mass(m_a, m_b, fixed_a, fixed_b):
    """m_A m_B/(m_A + m_B); a clamped disc counts as infinitely heavy."""
    both = m_a * m_b / (m_a + m_b)
    return jnp.where(fixed_a, m_b, jnp.where(fixed_b, m_a, both))


def linear_contact(kn, ks, mu, beta_n, beta_s, delta, vn, vs, shear, m, dt):
    """The linear spring–dashpot–slider law for one contact (arrays broadcast).

    delta  overlap δ (> 0 in contact)      vn  (v_B − v_A)·n (opening rate, = −δ̇)
    vs     V_s                             shear  F_s of the previous step
    Returns (F_n, F_s total, F_s history): zero where δ ≤ 0 (the history resets)."""
    touch = delta > 0
    fn_spring = kn * delta
    fn = fn_spring - 2.0 * beta_n * jnp.sqrt(m * kn) * vn
    trial = shear - ks * vs * dt
    limit = mu * fn_spring
    slip = jnp.abs(trial) > limit
    fs = jnp.where(slip, jnp.sign(trial) * limit, trial)
    damp = jnp.where(slip, 0.0, -2.0 * beta_s * jnp.sqrt(m * ks) * vs)
    zero = jnp.zeros_like(fn)
    return (jnp.where(touch, fn, zero), jnp.where(touch, fs + damp, zero),
            jnp.where(touch, fs, zero))


def pair_geometry(dx, valid, ra, rb):
    """(n, δ) of pairs A–B from dx = x_B − x_A: the unit normal A → B and the overlap
    δ = R_A + R_B − |dx| (−1 where ``valid`` is False or the centres coincide)."""
    nx, ny, delta = _pair_geometry_xy(dx[..., 0], dx[..., 1], valid, ra, rb)
    return jnp.stack([nx, ny], axis=-1), delta


def _pair_geometry_xy(dxx, dxy, valid, ra, rb):
    """:func:`pair_geometry` on the components: (n_x, n_y, δ)."""
    r2 = dxx * dxx + dxy * dxy
    ok = r2 > 0
    d = jnp.where(ok, jnp.sqrt(jnp.where(ok, r2, 1.0)), 0.0)
    inv = 1.0 / jnp.where(ok, d, 1.0)
    return dxx * inv, dxy * inv, jnp.where(valid & ok, ra + rb - d, -1.0)


def rolling_torque(mu_roll, fn, ra, rb, omega_a, omega_b):
    """The rolling resistance on A (Ai et al. 2011, model A, the constant directional
    torque): M_r = −μ_r R* max(F_n, 0) sign(ω_A − ω_B), R* = R_A R_B/(R_A + R_B), R_A
    against a wall (``rb`` = 0.0); B takes −M_r. It opposes the discs' relative rolling
    whatever its speed, so a disc at rest under it jitters by sign flips of its ω (Ai et
    al.'s known defect of model A)."""
    r_eff = ra if isinstance(rb, float) and rb == 0.0 else ra * rb / (ra + rb)
    return -mu_roll * r_eff * jnp.maximum(fn, 0.0) * jnp.sign(omega_a - omega_b)


def _contact_pairs(dp, nx, ny, delta, ra, rb, dvx, dvy, omega_a, omega_b, m, shear, dt):
    """The contact law for every (row, slot) pair with normal (n_x, n_y) (A → B) and
    overlap ``delta``: (the force on B, F_n n + F_s t, as its x and y components, the lever
    ℓ_A = R_A − δ/2, the new history, the rolling couple on A, :func:`rolling_torque`, or
    0.0 without ``dp.mu_roll``), each (n, K); the force on A is the opposite, and its
    torque −F_s ℓ_A + M_r.

    (dvx, dvy) = v_B − v_A; every pair quantity is an (n, K) array of one component (XLA:CPU
    emits a sum over a last axis of 2, as a dot product of (n, K, 2) arrays, as a reduction
    of its own; on components the whole law is one loop). ra, rb radii (rb = 0 for a
    wall)."""
    tx, ty = -ny, nx
    la, lb = ra - 0.5 * delta, rb - 0.5 * delta
    vn = dvx * nx + dvy * ny
    vs = dvx * tx + dvy * ty - omega_b * lb - omega_a * la
    fn, fs, hist = linear_contact(dp.kn, dp.ks, dp.mu, dp.beta_n, dp.beta_s, delta, vn, vs,
                                  shear, m, dt)
    roll = (0.0 if dp.mu_roll is None
            else rolling_torque(dp.mu_roll, fn, ra, rb, omega_a, omega_b))
    return fn * nx + fs * tx, fn * ny + fs * ty, fs, la, hist, roll


def _contact_sum(dp, nx, ny, delta, ra, rb, dvx, dvy, omega_a, omega_b, m, shear, dt):
    """:func:`_contact_pairs` summed over slots onto the row body A. Returns (force (n, 2),
    torque (n,), new history (n, K), overlap (n, K))."""
    fbx, fby, fs, la, hist, roll = _contact_pairs(dp, nx, ny, delta, ra, rb, dvx, dvy,
                                                  omega_a, omega_b, m, shear, dt)
    # three (n, K) terms summed over the slot axis in one variadic reduction: a sum of the
    # (n, K, 2) force over its middle axis ran 3× slower on XLA:CPU
    fx, fy, tq = sum_neighbours(fbx, fby, fs * la - roll)
    return -jnp.stack([fx, fy], axis=-1), -tq, hist, delta


def disc_contacts(dp, x, v, omega, radius, mass, fixed, idx, shear, dt, rows=None):
    """Disc–disc contacts over the Dense list ``idx`` (n × K, padding index n).

    ``rows`` (r,): compute only these discs' contacts (``idx`` and ``shear`` are then their
    rows, (r, K)); a disc's row holds the whole force on it, so the other discs' rows can
    be left out when nothing reads their force (kinematic discs).

    Returns (force (n, 2), torque (n,), new shear history (n, K), overlap (n, K)), with r
    rows when ``rows`` is given."""
    n = x.shape[0]
    valid = idx < n
    j = jnp.where(valid, idx, 0)
    own = functools.partial(take_rows, rows=rows)      # this call's rows of an (n, …) array
    m = reduced_mass(own(mass)[:, None], mass[j], own(fixed)[:, None], fixed[j])
    xo, vo = own(x), own(v)

    def rel(a, ao, c):                  # component c of a_B − a_A, (r, K)
        return a[:, c][j] - ao[:, c, None]
    nx, ny, delta = _pair_geometry_xy(rel(x, xo, 0), rel(x, xo, 1), valid,
                                      own(radius)[:, None], radius[j])
    return _contact_sum(dp, nx, ny, delta, own(radius)[:, None], radius[j], rel(v, vo, 0),
                        rel(v, vo, 1), own(omega)[:, None], omega[j], m, shear, dt)


def wall_geometry(x, a, b):
    """Closest points of the segments a→b to the discs: (vector disc→wall (n, W, 2))."""
    ab = b - a
    s = jnp.sum((x[:, None, :] - a[None]) * ab[None], axis=-1) / jnp.sum(ab * ab, axis=-1)
    c = a[None] + jnp.clip(s, 0.0, 1.0)[..., None] * ab[None]
    return c - x[:, None, :]


def inward_normals(a, b, side):
    """(W, 2) unit normals pointing into each wall's active side: side × (−t_y, t_x), t the
    unit vector along a → b (zero for two-sided walls)."""
    t = (b - a) / jnp.linalg.norm(b - a, axis=-1, keepdims=True)
    return side[:, None] * perp(t)


def wall_pair_geometry(x, radius, a, b, side=None):
    """(n, δ) of every disc–wall pair (n, W): the normal disc → wall and the overlap.

    Two-sided walls: the closest point of the segment, δ = R − |c − x|. A one-sided wall
    (``side`` ±1, scene.WallBlock) measures the disc's signed distance s = (x − a)·n_in
    from its line while the centre projects onto the segment: n = −n_in and δ = R − s,
    which keeps growing (R + depth) once the centre has gone past the line, so a disc
    driven through by an impact its contact spring cannot stop is pushed back out; past
    a depth of 2R the disc counts as on the other side (no contact)."""
    nx, ny, delta = _wall_pair_geometry_xy(x, radius, a, b, side)
    return jnp.stack([nx, ny], axis=-1), delta


def _wall_pair_geometry_xy(x, radius, a, b, side=None):
    """:func:`wall_pair_geometry` on the components: (n_x, n_y, δ), each (n, W)."""
    abx, aby = b[:, 0] - a[:, 0], b[:, 1] - a[:, 1]                      # (W,)
    relx, rely = x[:, 0, None] - a[None, :, 0], x[:, 1, None] - a[None, :, 1]
    u = (relx * abx + rely * aby) / (abx * abx + aby * aby)              # along the segment
    uc = jnp.clip(u, 0.0, 1.0)
    r = radius[:, None]
    nx, ny, delta = _pair_geometry_xy(uc * abx - relx, uc * aby - rely, True, r, 0.0)
    if side is None:
        return nx, ny, delta
    inv = side / jnp.sqrt(abx * abx + aby * aby)
    n_inx, n_iny = -aby * inv, abx * inv                                 # inward_normals
    sd = relx * n_inx + rely * n_iny                                     # signed distance
    flat = (side[None] != 0) & (u >= 0.0) & (u <= 1.0) & (sd > -2.0 * r)
    nx = jnp.where(flat, -n_inx, nx)
    ny = jnp.where(flat, -n_iny, ny)
    delta = jnp.where(flat, r - sd, jnp.where(side[None] != 0, jnp.where(sd > 0, delta, -1.0),
                                              delta))
    return nx, ny, delta


def wall_contacts(dp, x, v, omega, radius, mass, a, b, shear, dt, side=None,
                  reaction=None):
    """Disc–wall contacts (W5): the wall is body B, at rest, with zero radius and infinite
    mass; ``side`` the walls' active sides (None: all two-sided; :func:`wall_pair_geometry`).
    Returns (force (n, 2), torque (n,), new history (n, W), overlap (n, W)).

    ``reaction`` (n,) bool, the rows to count: then also the discs' force on each wall and
    its moment about the origin, (W, 3) = Σ_i (F_x, F_y, c × F) over those rows, F the
    opposite of the wall's force on disc i, applied at the contact point c = x_i + ℓ n
    (ℓ = R − δ/2, where the disc's torque −F_s ℓ puts it), so that force and angular
    momentum pass between discs and walls unchanged."""
    shape = shear.shape
    nx, ny, delta = _wall_pair_geometry_xy(x, radius, a, b, side)
    args = (dp, nx, ny, delta, radius[:, None], 0.0, jnp.broadcast_to(-v[:, 0, None], shape),
            jnp.broadcast_to(-v[:, 1, None], shape), omega[:, None], 0.0,
            jnp.broadcast_to(mass[:, None], shape), shear, dt)
    if reaction is None:
        return _contact_sum(*args)
    fbx, fby, fs, la, hist, roll = _contact_pairs(*args)
    fx, fy, tq = sum_neighbours(fbx, fby, fs * la - roll)
    on = reaction[:, None]
    cx, cy = x[:, 0, None] + la * nx, x[:, 1, None] + la * ny
    per_wall = jnp.stack([jnp.sum(jnp.where(on, q, 0.0), axis=0)    # the wall takes −M_r
                          for q in (fbx, fby, cx * fby - cy * fbx - roll)], axis=-1)
    return -jnp.stack([fx, fy], axis=-1), -tq, hist, delta, per_wall


def walls_near(x, radius, a, b, side, margin, held=None):
    """Which discs may touch a wall while every disc stays within ``margin`` of ``x`` (the
    DEM list's skin/2 about its build positions): (n,) bool. Discs where ``held`` (n,) is
    True (clamped or kinematic: their force is never read) count as apart.

    The distance d from a centre to a segment's closest point is 1-Lipschitz in the
    centre. A two-sided wall touches a disc only at d < R. A one-sided wall
    (:func:`wall_pair_geometry`) also touches while the centre projects onto the segment
    at a signed distance −2R < s < R, and there d = |s| < 2R. So a pair stays apart
    while d − R > margin and, for a one-sided wall, either s > R + margin (clear on its
    active side) or d > 2R + margin. Verlet's skin argument, applied to the walls."""
    d = jnp.linalg.norm(wall_geometry(x, a, b), axis=-1)               # (n, W)
    r = radius[:, None]
    apart = d - r > margin
    if side is not None:
        s = jnp.sum((x[:, None, :] - a[None]) * inward_normals(a, b, side)[None], axis=-1)
        apart &= (side[None] == 0) | (s > r + margin) | (d > 2.0 * r + margin)
    if held is not None:
        apart |= held[:, None]
    return ~jnp.all(apart, axis=1)


def remap_history(old_idx, old_hist, new_idx):
    """Shear history re-addressed from the slots of ``old_idx`` to those of ``new_idx`` by the
    pair (i, j): a pair present in both keeps its value, a new pair starts at 0. Works for a
    different capacity K too (after a reallocation)."""
    match = old_idx[:, None, :] == new_idx[:, :, None]          # (n, K_new, K_old)
    return jnp.sum(jnp.where(match, old_hist[:, None, :], 0.0), axis=-1)


def local_damping(alpha, force, velocity):
    """K25: F ← F − α |F| sign(v), per component (also for moments with ω)."""
    return force - alpha * jnp.abs(force) * jnp.sign(velocity)


def viscous_damping(c, mass, velocity):
    """Mass-proportional viscous damping −c m v (per component; with J and ω for moments).
    Smooth, unlike K25, so gradients with respect to c and through the motion are exact."""
    return -c * mass * velocity


def load_factor(load_ramp, t):
    """External loads ramp linearly from 0 to 1 over ``load_ramp`` seconds (0: at once)."""
    return jnp.where(load_ramp > 0, jnp.clip(t / jnp.where(load_ramp > 0, load_ramp, 1.0),
                                             0.0, 1.0), 1.0)


def kinetic_energy(v, omega, mass, inertia):
    """Translational + rotational kinetic energy of the discs."""
    return 0.5 * jnp.sum(mass * jnp.sum(v * v, axis=-1)) + 0.5 * jnp.sum(inertia * omega ** 2)


__all__ = ["perp", "reduced_mass", "linear_contact", "pair_geometry", "disc_contacts",
           "wall_contacts", "wall_geometry", "wall_pair_geometry", "inward_normals", "walls_near",
           "remap_history", "local_damping", "viscous_damping", "load_factor", "kinetic_energy"]
