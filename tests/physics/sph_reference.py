"""The hand-placed SPH configuration and the formulas of physics.md in plain Python, shared
by the unit tests of the SPH terms (test_sph.py), the pair geometry (test_pairs.py) and the
boundary pressure (test_boundary.py)."""
import math

import jax.numpy as jnp
import numpy as np

from fpsi_jax.model.config import NeighborConfig, Physics
from fpsi_jax.model.params import SphParams
from fpsi_jax.physics import kernels, pairs, sph

RTOL = 1e-10
KERN = kernels.get("wendland")


# --- the formulas of physics.md, in plain Python -----------------------------------------
def W(r, h):
    q = r / h
    return 7.0 / (4.0 * math.pi * h * h) * (1 - q / 2) ** 4 * (2 * q + 1) if q < 2 else 0.0


def F(r, h):
    """(1/r) dW/dr of Wendland C2."""
    q = r / h
    return -35.0 / (4.0 * math.pi * h ** 4) * (1 - q / 2) ** 3 if q < 2 else 0.0


def tait(rho, rho0, c0, gamma):
    return c0 * c0 * rho0 / gamma * ((rho / rho0) ** gamma - 1.0)


class Pair:
    """Everything about the pair (i, j) that the formulas need."""

    def __init__(self, i, j, x, v, h):
        self.i, self.j = i, j
        self.xij = np.array(x[i], float) - np.array(x[j], float)
        self.vij = np.array(v[i], float) - np.array(v[j], float)
        self.r2 = float(self.xij @ self.xij)
        self.r = math.sqrt(self.r2)
        self.h = 0.5 * (h[i] + h[j])
        self.w = W(self.r, self.h)
        self.f = F(self.r, self.h)
        self.gradw = self.xij * self.f          # ∇_i W_ij


def ref_terms(i, nbrs, x, v, h, m, rho_old, rho, p, n_fluid, sp, anticlump_boundary=False,
              gravity=None):
    """Every SPH term of fluid particle i, summed over the neighbour list ``nbrs``; with
    ``gravity`` δ-SPH in Fourtakas' form (the hydrostatic difference left out)."""
    out = dict(cont=0.0, delta=0.0, pres=np.zeros(2), clump=np.zeros(2), visc=np.zeros(2),
               av=np.zeros(2), xsph=np.zeros(2))
    for j in nbrs:
        pr = Pair(i, j, x, v, h)
        fluid_j = j < n_fluid
        # continuity (K32), volumes from the densities at the start of the step
        out["cont"] += rho_old[i] * m[j] / rho_old[j] * float(pr.vij @ pr.gradw)
        # δ-SPH (Molteni & Colagrossi): δ h c0 Σ 2(ρj−ρi) x_ji·∇W/(r²+0.01h²) V_j, fluid only
        if fluid_j:
            d_rho = rho_old[j] - rho_old[i]
            if gravity is not None:   # ρ^H_ji = (ρ0/c0²) g·x_ji (Fourtakas et al. 2019)
                d_rho -= sp["rho0"] / sp["c0"] ** 2 * float(np.asarray(gravity) @ -pr.xij)
            psi_dot = 2 * d_rho * float(-pr.xij @ pr.gradw) / (
                pr.r2 + 0.01 * pr.h ** 2)
            out["delta"] += sp["delta"] * pr.h * sp["c0"] * psi_dot * m[j] / rho_old[j]
        # pressure (W43, K34)
        out["pres"] += -m[j] * (p[i] / rho[i] ** 2 + p[j] / rho[j] ** 2) * pr.gradw
        # anti-clump (W45, K38): R_ij = r (|Pi|/ρi² + |Pj|/ρj²)(W/W(Δp))⁴
        if fluid_j or anticlump_boundary:
            R = sp["r_clump"] * (abs(p[i]) / rho[i] ** 2 + abs(p[j]) / rho[j] ** 2) * (
                pr.w / W(sp["dp"], pr.h)) ** 4
            out["clump"] += -m[j] * R * pr.gradw
        # Morris viscosity (K36)
        out["visc"] += (m[j] * 2 * sp["mu"] * float(pr.xij @ pr.gradw)
                        / (rho[i] * rho[j] * (pr.r2 + 0.01 * pr.h ** 2)) * pr.vij)
        # Monaghan artificial viscosity
        vx = float(pr.vij @ pr.xij)
        if vx < 0:
            mu_ij = pr.h * vx / (pr.r2 + 0.01 * pr.h ** 2)
            Pi = -sp["alpha"] * sp["c0"] * mu_ij / (0.5 * (rho[i] + rho[j]))
            out["av"] += -m[j] * Pi * pr.gradw
        # XSPH (K39, Monaghan 1989), over fluid neighbours only (sph.xsph_scalar: the
        # v = 0 boundary particles would pull the transport velocity to zero at a wall)
        if fluid_j:
            out["xsph"] += -sp["eps_xsph"] * m[j] / (0.5 * (rho[i] + rho[j])) * pr.w * pr.vij
    return out


# --- the hand-placed configuration -------------------------------------------------------
# fluid 0, fluid 1, boundary 2; N = 3 so the padding index is 3
X = [[0.0, 0.0], [0.006, 0.002], [0.001, -0.005]]
V = [[0.3, -0.1], [-0.2, 0.4], [0.0, 0.0]]
Hs = [0.005, 0.006, 0.0045]
M = [0.025, 0.027, 0.020]
RHO_OLD = [1003.0, 997.0, 1000.0]    # densities at the start of the step (pair volumes)
RHO = [1004.0, 995.0, 1001.0]        # densities at the new level (momentum)
P = [300.0, -150.0, 500.0]           # pressures at the new level (P_1 < 0: |P| matters)
NF = 2
NBRS = {0: [1, 2], 1: [0, 2]}
IDX = [[1, 2, 3], [0, 2, 3]]         # Dense rows of the fluid, one padded slot each
SP = dict(rho0=1000.0, c0=20.0, gamma=7.0, mu=0.02, r_clump=0.01, dp=0.004,
          eps_xsph=0.5, delta=0.1, alpha=0.3)
G = np.array([0.0, -9.81])


def _phys(n_fluid=NF, n_boundary=1, **flags):
    nb = NeighborConfig(r_cut=0.02, skin=0.0, origin=(0.0, 0.0), box=(1.0, 1.0))
    return Physics(n_fluid=n_fluid, n_boundary=n_boundary, neighbors=nb, **flags)


def _sp(**kw):
    return SphParams(**{k: jnp.float64(v) for k, v in {**SP, **kw}.items()})


def _a(v, dtype=jnp.float64):
    return jnp.asarray(np.asarray(v), dtype=dtype)


def _pairs(idx=IDX, v=V):
    return pairs.pairs(KERN, NF, _a(X), _a(v), _a(Hs), _a(M), _a(RHO_OLD),
                       jnp.asarray(idx, jnp.int32))


def _ref(i, sp=SP, **kw):
    return ref_terms(i, NBRS[i], X, V, Hs, M, RHO_OLD, RHO, P, NF, sp, **kw)


def _momentum(phys, sp=None, gravity=(0.0, 0.0), idx=IDX, p=P):
    sp = _sp() if sp is None else sp
    return sph.momentum_rate(phys, KERN, sp, _a(gravity), _a(RHO), _a(p), _pairs(idx))[:2]


# switches off the optional momentum terms, to test one term at a time
OFF = dict(anticlump=False, artificial_viscosity=False, xsph=False)


def _random_blob(n_x=10, n_y=5, seed=0):
    rng = np.random.default_rng(seed)
    dp = 0.005
    gx, gy = np.meshgrid(np.arange(n_x), np.arange(n_y), indexing="ij")
    x = np.stack([gx.ravel(), gy.ravel()], 1) * dp + rng.uniform(-0.3, 0.3, (n_x * n_y, 2)) * dp
    n = x.shape[0]
    h = 1.3 * dp * rng.uniform(0.9, 1.1, n)
    v = rng.normal(0.0, 0.5, (n, 2))
    m = 1000.0 * dp * dp * rng.uniform(0.9, 1.1, n)
    rho_old = 1000.0 * rng.uniform(0.99, 1.01, n)
    rho = 1000.0 * rng.uniform(0.99, 1.01, n)
    # brute-force Dense list: all j ≠ i within 2 max(h), padded with N
    d = np.linalg.norm(x[:, None] - x[None], axis=-1)
    near = (d < 2.0 * h.max()) & ~np.eye(n, dtype=bool)
    k = int(near.sum(1).max())
    idx = np.full((n, k + 2), n, np.int32)
    for i in range(n):
        js = rng.permutation(np.flatnonzero(near[i]))
        idx[i, :len(js)] = js
    return dict(x=x, v=v, h=h, m=m, rho_old=rho_old, rho=rho, idx=idx, dp=dp)


ALL_ON = dict(anticlump=True, artificial_viscosity=True, xsph=True, delta_sph=True)
