"""Point sets and wall outlines (numpy): the geometry every builder starts from.

``lattice`` fills a rectangle with SPH particles, ``hex_packing`` / ``square_packing`` with
disc centres, ``touching_pairs`` finds the nearest-neighbour bonds of a packing,
``tank_walls`` lays the fixed SPH boundary layers of an open tank and ``box_walls`` the DEM
line walls of a box.
"""
from __future__ import annotations

import math

import numpy as np

from ..model.errors import ParameterError, check_positive, fmt
from ..model.scene import BondBlock, WallBlock
from ..model import limits


def _cells(width, height, dx, what="a lattice"):
    """(nx, ny) = round(width/dx), round(height/dx), checked before anything is allocated:
    at least one along each side, and no more than the machine holds (model.limits)."""
    check_positive(width=width, height=height, dx=dx)
    fx, fy = width / dx, height / dx
    limits.check(fx * fy, f"{what} of {fmt(width)} x {fmt(height)} m at spacing {fmt(dx)} m")
    nx, ny = int(round(fx)), int(round(fy))
    if nx < 1 or ny < 1:
        raise ParameterError(f"spacing {fmt(dx)} m is larger than the {fmt(width)} x "
                             f"{fmt(height)} m block it should fill; allowed (0, "
                             f"{fmt(2 * min(width, height))}) m")
    return nx, ny


def lattice(x0, y0, width, height, dx):
    """Cell-centred square lattice filling [x0, x0+width] × [y0, y0+height]."""
    nx, ny = _cells(width, height, dx)
    xs = x0 + (np.arange(nx) + 0.5) * dx
    ys = y0 + (np.arange(ny) + 0.5) * dx
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    return np.stack([X.ravel(), Y.ravel()], axis=1)


def hex_packing(x0, y0, width, height, d, first_row_long=True):
    """Hexagonally packed disc centres (diameter d) in rows along x, filling the rectangle
    [x0, x0+width] × [y0, y0+height] with every disc inside it. Rows are √3/2·d apart;
    odd rows are shifted by d/2 (they hold one disc fewer)."""
    _cells(width, height, d, "a packing")
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


def square_packing(x0, y0, width, height, d, stretch=False):
    """Square-packed disc centres filling [x0, x0+width] × [y0, y0+height], rows and columns
    d apart, every disc inside the rectangle.

    ``stretch=True`` builds a strip of exactly the rectangle's length instead: the columns
    stand on both ends x0 and x0 + width, s = :func:`span_spacing` (width, d) ≥ d apart (a
    79.375 mm strip at d = 1.25 mm: 64 columns 1.2599 mm apart, where d-spaced columns
    would span 78.75 or 80 mm); the rows stay d apart. The bonds across the gaps s − d are
    beam elements of length s (physics/bonds.py); :func:`touching_pairs` (``gap=s − d``)
    finds them."""
    _cells(width, height, d, "a packing")
    ny = int(math.floor(height / d + 1e-9))
    if stretch:
        sx = span_spacing(width, d)
        xs = x0 + sx * np.arange(int(round(width / sx)) + 1)
    else:
        xs = x0 + d / 2 + d * np.arange(int(math.floor(width / d + 1e-9)))
    if xs.size < 1 or ny < 1:
        raise ParameterError(f"a {width} × {height} rectangle holds no disc of diameter {d}")
    X, Y = np.meshgrid(xs, y0 + d / 2 + d * np.arange(ny), indexing="ij")
    return np.stack([X.ravel(), Y.ravel()], axis=1)


def span_spacing(span, d):
    """The spacing s = L/n, n = ⌊L/d⌋, closest to d that puts disc centres exactly L apart
    along a line (s ≥ d, so neighbours never overlap: s − d < d/n). L = 79.375 mm at
    d = 1.25 mm: 63 intervals of 1.2599 mm."""
    n = int(math.floor(span / d + 1e-9))
    if n < 1:
        raise ParameterError(f"span = {span} holds no interval of a disc diameter d = {d}")
    return span / n


def touching_pairs(x, radius, tol=1e-6, gap=0.0):
    """Pairs (i < j) whose discs touch or overlap (|x_i − x_j| ≤ (R_i + R_j + gap)(1 + tol)):
    the nearest-neighbour bonds of a packing (``gap`` > 0: of a stretched packing).
    Cell binning, O(n)."""
    x = np.asarray(x, float)
    r = np.broadcast_to(np.asarray(radius, float), (x.shape[0],)) + 0.5 * gap
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


def fit_spacing(width, dx):
    """The spacing nearest ``dx`` that fills ``width`` with whole columns (a fluid block that
    stops short of a wall by more than dx/2 starts out of balance and sloshes)."""
    return width / max(1, round(width / dx))


def tank_walls(width, height, dxb, layers):
    """Fixed particles outside the open-top box [0, width] × [0, height]: floor + two walls,
    ``layers`` deep, on a dxb lattice (corners filled). ``width`` must be a whole number of
    dxb (:func:`fit_spacing`): then the innermost layer of both side walls sits dxb/2
    outside the wall. (On any other lattice the right wall would stand up to dxb/2 further
    out than the left, and the fluid column beside it would slosh.)"""
    if abs(width / dxb - round(width / dxb)) > 1e-6:
        raise ParameterError(f"tank width {fmt(width)} m is not a whole number of the "
                             f"boundary spacing {fmt(dxb)} m (fit it: fit_spacing)")
    t = layers * dxb
    outer = lattice(-t, -t, width + 2 * t, height + t, dxb)
    inside = (outer[:, 0] > 0) & (outer[:, 0] < width) & (outer[:, 1] > 0)
    return outer[~inside]


def box_walls(x0, y0, x1, y1, top=False):
    """Line walls of an open-top box: floor, left and right (and the lid if ``top``),
    each active on the inside only (WallBlock.side)."""
    a = [(x0, y0), (x0, y0), (x1, y0)]
    b = [(x1, y0), (x0, y1), (x1, y1)]
    side = [1.0, -1.0, 1.0]                # inside: left of the floor and the right wall
    if top:
        a.append((x0, y1))
        b.append((x1, y1))
        side.append(-1.0)
    return WallBlock(a=np.asarray(a, float), b=np.asarray(b, float),
                     side=np.asarray(side))


def inside_polygon(x, vertices) -> np.ndarray:
    """(n,) bool: the points ``x`` (n, 2) that lie inside the closed polygon ``vertices``
    (m, 2), by the even–odd rule (ray casting, vectorised over the points)."""
    x = np.asarray(x, float)
    v = np.asarray(vertices, float)
    if v.ndim != 2 or v.shape[1] != 2 or v.shape[0] < 3:
        raise ParameterError(f"polygon needs at least 3 vertices (m, 2), got {v.shape}")
    px, py = x[:, 0:1], x[:, 1:2]
    ax, ay = v[:, 0][None, :], v[:, 1][None, :]
    bx, by = np.roll(v[:, 0], -1)[None, :], np.roll(v[:, 1], -1)[None, :]
    crosses = (ay > py) != (by > py)
    with np.errstate(divide="ignore", invalid="ignore"):
        x_at = ax + (py - ay) * (bx - ax) / (by - ay)
    return np.sum(crosses & (px < x_at), axis=1) % 2 == 1


def polygon_lattice(vertices, dx):
    """Cell-centred square lattice of spacing ``dx`` filling the polygon ``vertices``: the
    points of :func:`lattice` over its bounding box that lie inside it."""
    v = np.asarray(vertices, float)
    lo, hi = v.min(axis=0), v.max(axis=0)
    pts = lattice(lo[0], lo[1], hi[0] - lo[0], hi[1] - lo[1], dx)
    pts = pts[inside_polygon(pts, v)]
    if pts.shape[0] == 0:
        raise ParameterError(f"the polygon holds no lattice point at spacing dx = {dx}")
    return pts


def in_region(x, region) -> np.ndarray:
    """(n,) bool: the points of ``x`` in ``region``, a rectangle (x0, y0, x1, y1), a polygon
    (m, 2) of vertices, or a function of the (n, 2) positions returning a bool mask."""
    x = np.asarray(x, float)
    if callable(region):
        return np.asarray(region(x), bool)
    r = np.asarray(region, float)
    if r.shape == (4,):
        x0, y0, x1, y1 = r
        return (x[:, 0] >= x0) & (x[:, 0] <= x1) & (x[:, 1] >= y0) & (x[:, 1] <= y1)
    return inside_polygon(x, r)
