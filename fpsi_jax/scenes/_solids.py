"""Host-side builders for DEM discs, bonded structures and walls (numpy only)."""
from __future__ import annotations

import math

import numpy as np

from ..params import ParameterError
from ..scene import BondBlock, SolidBlock, WallBlock

MASS_MODELS = ("disc", "lattice", "sphere")


def hex_packing(x0, y0, width, height, d, first_row_long=True):
    """Hexagonally packed disc centres (diameter d) in rows along x, filling the rectangle
    [x0, x0+width] × [y0, y0+height] with every disc inside it. Rows are √3/2·d apart;
    odd rows are shifted by d/2 (they hold one disc fewer)."""
    s = math.sqrt(3.0) / 2.0 * d
    n_rows = int(math.floor((height - d) / s + 1e-9)) + 1
    n_long = int(math.floor(width / d + 1e-9))
    if n_rows < 1 or n_long < 1:
        raise ParameterError(f"a {width} × {height} rectangle holds no disc of diameter {d}")
    pts = []
    for r in range(n_rows):
        shifted = (r % 2 == 1) == first_row_long
        n = n_long - 1 if shifted else n_long
        xs = x0 + d / 2 + (d / 2 if shifted else 0.0) + d * np.arange(n)
        pts.append(np.stack([xs, np.full(n, y0 + d / 2 + r * s)], axis=1))
    return np.concatenate(pts)


def square_packing(x0, y0, width, height, d):
    """Square-packed disc centres filling [x0, x0+width] × [y0, y0+height]."""
    nx, ny = int(math.floor(width / d + 1e-9)), int(math.floor(height / d + 1e-9))
    if nx < 1 or ny < 1:
        raise ParameterError(f"a {width} × {height} rectangle holds no disc of diameter {d}")
    X, Y = np.meshgrid(x0 + d / 2 + d * np.arange(nx), y0 + d / 2 + d * np.arange(ny),
                       indexing="ij")
    return np.stack([X.ravel(), Y.ravel()], axis=1)


def touching_pairs(x, radius, tol=1e-6):
    """Pairs (i < j) whose discs touch or overlap (|x_i − x_j| ≤ (R_i + R_j)(1 + tol)):
    the nearest-neighbour bonds of a packing. Cell binning, O(n)."""
    x = np.asarray(x, float)
    r = np.broadcast_to(np.asarray(radius, float), (x.shape[0],))
    cell = 2.0 * r.max() * (1 + tol)
    key = np.floor((x - x.min(0)) / cell).astype(np.int64)
    cells: dict = {}
    for k, c in enumerate(map(tuple, key)):
        cells.setdefault(c, []).append(k)
    ii, jj = [], []
    for (cx, cy), members in cells.items():
        cand = [m for dx in (-1, 0, 1) for dy in (-1, 0, 1)
                for m in cells.get((cx + dx, cy + dy), ())]
        cand = np.asarray(cand)
        for a in members:
            b = cand[cand > a]
            if b.size == 0:
                continue
            dist = np.linalg.norm(x[b] - x[a], axis=1)
            ok = dist <= (r[a] + r[b]) * (1 + tol)
            ii += [a] * int(ok.sum())
            jj += list(b[ok])
    order = np.lexsort((jj, ii))
    return BondBlock(i=np.asarray(ii, np.int32)[order], j=np.asarray(jj, np.int32)[order])


def disc_block(x, radius, rho, mass_model="disc", d_lattice=None, packing="hex",
               thickness=1.0, fixed=None, f_ext=None, v=None):
    """SolidBlock for discs at ``x``.

    mass_model  'disc':    m = ρπR²t, J = ½mR² (PFC2D default, physics.md §Conventions)
                'lattice': m = ρ·(cell area)·t with the cell of the packing, (√3/2)d²
                           (hex) or d² (square): the structure's mass per area is exactly ρ;
                           J = ½mR²
                'sphere':  m = ρ(4/3)πR³, J = (2/5)mR² (K6.1: "particles considered
                           spherical")
    """
    x = np.asarray(x, float)
    n = x.shape[0]
    R = np.broadcast_to(np.asarray(radius, float), (n,)).copy()
    if mass_model not in MASS_MODELS:
        raise ParameterError(f"mass_model must be one of {MASS_MODELS}, got {mass_model!r}")
    if mass_model == "disc":
        m = rho * np.pi * R ** 2 * thickness
        J = 0.5 * m * R ** 2
    elif mass_model == "lattice":
        d = 2 * R if d_lattice is None else np.full(n, d_lattice)
        cell = (np.sqrt(3) / 2 if packing == "hex" else 1.0) * d ** 2
        m = rho * cell * thickness
        J = 0.5 * m * R ** 2
    else:
        m = rho * 4.0 / 3.0 * np.pi * R ** 3
        J = 0.4 * m * R ** 2
    return SolidBlock(
        x=x, v=np.zeros((n, 2)) if v is None else np.asarray(v, float), omega=np.zeros(n),
        radius=R, mass=m, inertia=J,
        fixed=np.zeros(n, bool) if fixed is None else np.asarray(fixed, bool),
        f_ext=np.zeros((n, 2)) if f_ext is None else np.asarray(f_ext, float))


def box_walls(x0, y0, x1, y1, top=False):
    """Line walls of an open-top box: floor, left and right (and the lid if ``top``)."""
    a = [(x0, y0), (x0, y0), (x1, y0)]
    b = [(x1, y0), (x0, y1), (x1, y1)]
    if top:
        a.append((x0, y1))
        b.append((x1, y1))
    return WallBlock(a=np.asarray(a, float), b=np.asarray(b, float))
