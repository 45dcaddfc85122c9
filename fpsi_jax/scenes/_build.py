"""Host-side geometry helpers shared by the scene builders (numpy only)."""
from __future__ import annotations

import math

import numpy as np

from ..params import ParameterError, Params, SphParams
from ..scene import BoundaryBlock, FluidBlock
from ..sph import eos_density, eos_pressure

G = 9.81


def check_positive(**kw):
    for k, v in kw.items():
        if not (np.isfinite(v) and v > 0):
            raise ParameterError(f"{k} = {v!r} out of range; allowed (0, inf)")


def lattice(x0, y0, width, height, dx):
    """Cell-centred square lattice filling [x0, x0+width] × [y0, y0+height]."""
    nx = max(1, int(round(width / dx)))
    ny = max(1, int(round(height / dx)))
    xs = x0 + (np.arange(nx) + 0.5) * dx
    ys = y0 + (np.arange(ny) + 0.5) * dx
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    return np.stack([X.ravel(), Y.ravel()], axis=1)


def boundary_layers(h: float, dxb: float, min_layers: int = 2) -> int:
    """Layers so the boundary covers the kernel support 2h (at least ``min_layers``)."""
    return max(min_layers, int(math.ceil(2.0 * h / dxb)))


def tank_walls(width, height, dxb, layers):
    """Fixed particles outside the open-top box [0, width] × [0, height]: floor + two walls,
    ``layers`` deep, on a dxb lattice (corners filled)."""
    t = layers * dxb
    outer = lattice(-t, -t, width + 2 * t, height + t, dxb)
    inside = (outer[:, 0] > 0) & (outer[:, 0] < width) & (outer[:, 1] > 0)
    return outer[~inside]


def hydrostatic_fluid(x, rho0, c0, gamma, surface_y, g=G, dx=None, h=None):
    """Fluid block at rest with hydrostatic density ρ(P = ρ0 g (H − y)) and mass ρ0 dx²."""
    p = rho0 * g * np.maximum(surface_y - x[:, 1], 0.0)
    rho = np.array(eos_density(p, rho0, c0, gamma))
    n = x.shape[0]
    return FluidBlock(x=x, v=np.zeros_like(x), rho=rho, mass=np.full(n, rho0 * dx * dx),
                      h=np.full(n, h))


def boundary_block(xb, rho0, dxb, h, p=None, c0=None, gamma=7.0):
    """Boundary block: mass ρ0 dxb², pressure ``p`` (default 0) and the matching density."""
    n = xb.shape[0]
    p = np.zeros(n) if p is None else np.asarray(p, float)
    rho = np.full(n, rho0) if c0 is None else np.array(eos_density(p, rho0, c0, gamma))
    return BoundaryBlock(x=xb, rho=rho, p=p, mass=np.full(n, rho0 * dxb * dxb),
                         h=np.full(n, h))


def sph_params(rho0, c0, mu, dx, r_clump, eps_xsph, delta, gamma=7.0, alpha=0.0):
    return SphParams(rho0=rho0, c0=c0, gamma=gamma, mu=mu, r_clump=r_clump, dp=dx,
                     eps_xsph=eps_xsph, delta=delta, alpha=alpha)
