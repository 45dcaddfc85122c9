"""Fixed SPH boundary particles and the domain around a scene.

A wall of fixed particles must cover the kernel support 2h (:func:`boundary_layers`);
:func:`boundary_block` gives them mass ρ0 Δx_b² and a pressure (0, or hydrostatic for
the extrapolated mode's first step). :func:`domain` pads a scene's extent so every particle,
walls included, sits inside the neighbour grid with room for the kernel support.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..model.errors import check_positive
from ..model.scene import BoundaryBlock, WallBlock
from ..physics.eos import density
from .fluid import in_float64
from .geometry import box_walls, fit_spacing, tank_walls


def boundary_layers(h: float, dxb: float, min_layers: int = 2) -> int:
    """Layers so the boundary covers the kernel support 2h (at least ``min_layers``)."""
    return max(min_layers, int(math.ceil(2.0 * h / dxb)))


def boundary_block(xb, rho0, dxb, h, p=None, c0=None, gamma=7.0):
    """Boundary block: mass ρ0 dxb², pressure ``p`` (default 0) and the matching density."""
    n = xb.shape[0]
    p = np.zeros(n) if p is None else np.asarray(p, float)
    rho = np.full(n, rho0) if c0 is None else in_float64(density, p, rho0, c0, gamma)
    return BoundaryBlock(x=xb, rho=rho, p=p, mass=np.full(n, rho0 * dxb * dxb),
                         h=np.full(n, h))


def domain(lo, hi, pad):
    """(domain_lo, domain_hi) of the rectangle [lo, hi] grown by ``pad`` on every side
    (a scalar or (left, bottom, right, top))."""
    pl, pb, pr, pt = (pad,) * 4 if np.ndim(pad) == 0 else tuple(pad)
    return (lo[0] - pl, lo[1] - pb), (hi[0] + pr, hi[1] + pt)


@dataclass
class Tank:
    """An open-top tank [0, width] × [0, height]: fixed SPH boundary particles for the fluid
    (``boundary``, ``layers`` deep outside the walls) and, when asked, DEM line walls on the
    same outline for the discs (``walls``; the two never interact, so discs need their own
    walls). :meth:`domain` is the neighbour grid around it."""

    width: float
    height: float
    boundary: BoundaryBlock
    walls: WallBlock | None
    layers: int
    pad: float

    def domain(self, headroom: float = 0.5):
        """(domain_lo, domain_hi): the tank and its boundary layers with room for the kernel
        (``pad`` = layers·Δx_b + 2h) and ``headroom`` × height above the walls for splashes."""
        return domain((0.0, 0.0), (self.width, self.height),
                      (self.pad, self.pad, self.pad, headroom * self.height))


def tank(width, height, dx_boundary, h, rho0, *, dem_walls=False, lid=False) -> Tank:
    """A tank of fixed boundary particles on a ``dx_boundary`` lattice (fitted to the width,
    :func:`fit_spacing`, so that both side walls stand dx/2 outside the box), deep enough
    to cover the kernel support 2h (:func:`boundary_layers`), with mass ρ0 Δx_b² and P = 0;
    with ``dem_walls`` also DEM line walls on the floor and the side walls (and the lid)."""
    check_positive(width=width, height=height, dx_boundary=dx_boundary, h=h, rho0=rho0)
    dx_boundary = fit_spacing(width, dx_boundary)
    layers = boundary_layers(h, dx_boundary)
    xb = tank_walls(width, height, dx_boundary, layers)
    return Tank(width=float(width), height=float(height),
                boundary=boundary_block(xb, rho0, dx_boundary, h),
                walls=box_walls(0.0, 0.0, width, height, top=lid) if dem_walls else None,
                layers=layers, pad=layers * dx_boundary + 2 * h)
