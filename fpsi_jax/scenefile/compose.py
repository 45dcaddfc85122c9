"""A checked scene file (:func:`.reader.read`) → :class:`~fpsi_jax.model.scene.Scene` and
probes, through the public builders of :mod:`fpsi_jax.build` (the same calls the shipped
scenes make, so a file and a builder with the same numbers give the same arrays).

Discs are numbered by group kind, then by order in the file: ``[[discs]]``, ``[[grains]]``,
``[[structure]]``, ``[[kinematic]]``. Fixed SPH particles: the tank, then the obstacles.
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass, field

import numpy as np

from ..build import (boundary_block, boundary_layers, box_walls, dam_speed, disc_block,
                     fit_spacing, fluid_among_grains, hydrostatic_fluid, in_region,
                     inside_polygon, k42_mapping, lattice, merge, move, packing,
                     polygon_lattice, sound_speed, domain, span_spacing, sph_params,
                     strip_ends, tank_walls, touching_pairs)
from ..model import motion
from ..model.config import NeighborConfig
from ..model.params import BondParams, DemParams, FpiParams, Params
from ..model.scene import BondBlock, FluidBlock, Scene, WallBlock
from ..run import probes as P
from . import data
from .reader import FileError, fail

GROUPS = ("discs", "grains", "structure", "kinematic")


@dataclass
class SceneFile:
    """A scene file made ready to run.

    scene       the Scene
    probes      the [[probe]] tables as :class:`~fpsi_jax.run.probes.Probe` (file order)
    bodies      body name → indices of its discs in ``scene.solid``
    materials   structure name → its material (E, nu, ... and the Params leaves E sets)
    references  probe name → reference CSV path
    output      the [output] table (``file`` resolved against the file's folder)
    calibration the [calibration] table (paths resolved), or {}
    spec        the whole checked file;  path  the file
    """

    scene: Scene
    probes: list
    bodies: dict
    materials: dict
    references: dict
    output: dict
    calibration: dict
    spec: dict
    path: str
    physics: dict = field(default_factory=dict)

    def probe(self, name):
        for p in self.probes:
            if p.name == name:
                return p
        return None


# --- geometry -------------------------------------------------------------------------------
def _shape(path, tname, item, i, allowed):
    given = [k for k in allowed if item.get(k) is not None]
    if len(given) != 1:
        fail(path, tname, f"give exactly one of {', '.join(allowed)} (got "
             f"{', '.join(given) or 'none'})", item, i)
    return given[0]


def _top_bottom(item):
    if item.get("box") is not None:
        return item["box"][3], item["box"][1]
    ys = [p[1] for p in item["polygon"]]
    return max(ys), min(ys)


def _spacing_key(e, key) -> str:
    """A builder's "spacing … m is larger than the block" named as the key that set the
    spacing (``d`` of a body, ``dx`` of the fluid), which is what the user got wrong."""
    msg = str(e)
    if msg.startswith("spacing "):
        value, rest = msg[len("spacing "):].split(" m ", 1)
        return f"key {key!r} = {value} m {rest}"
    return msg


def _fill(item, dx):
    if item.get("box") is not None:
        x0, y0, x1, y1 = item["box"]
        return lattice(x0, y0, x1 - x0, y1 - y0, dx)
    return polygon_lattice(item["polygon"], dx)


def _outline(item):
    """DEM wall segments (a, b) along a box, polygon or polyline."""
    if item.get("box") is not None:
        x0, y0, x1, y1 = item["box"]
        v = [(x0, y0), (x1, y0), (x1, y1), (x0, y1)]
        closed = True
    elif item.get("polygon") is not None:
        v, closed = item["polygon"], True
    else:
        v, closed = item["polyline"], False
    v = np.asarray(v, float)
    b = np.roll(v, -1, axis=0) if closed else v[1:]
    a = v if closed else v[:-1]
    return a, b


def _outward(a, b) -> float:
    """The side (WallBlock convention: +1 the left of a → b) that faces out of a closed
    outline a[k] → b[k] (a box or polygon): −1 if it runs counter-clockwise (the inside on
    the left), +1 if clockwise."""
    area = 0.5 * float(np.sum(a[:, 0] * b[:, 1] - b[:, 0] * a[:, 1]))
    return -1.0 if area > 0 else 1.0


def polyline_particles(vertices, dx, layers):
    """Fixed particles along an open polyline: on each segment, points every dx (centred on
    the segment) in ``layers`` rows at (k + ½) dx on its right-hand side."""
    v = np.asarray(vertices, float)
    pts = []
    for a, b in zip(v[:-1], v[1:]):
        seg = b - a
        length = float(np.hypot(*seg))
        if length <= 0:
            continue
        t = seg / length
        n = np.array([t[1], -t[0]])            # right-hand normal
        m = max(1, int(round(length / dx)))
        s = (np.arange(m) + 0.5) * (length / m)
        for k in range(layers):
            pts.append(a + s[:, None] * t + (k + 0.5) * dx * n)
    return np.concatenate(pts)


# --- the parts ------------------------------------------------------------------------------
def _fluid(path, spec, g):
    fl = spec["fluid"]
    regions = spec.get("fluid.region") or []
    if not regions:
        fail(path, "fluid", "has no [[fluid.region]]: add at least one body of water")
    for i, r in enumerate(regions):
        _shape(path, "fluid.region", r, i, ("box", "polygon"))
    dx = fl["dx"] if fl["fit_width"] is None else fit_spacing(fl["fit_width"], fl["dx"])
    h = 1.25 * dx if fl["h"] is None else fl["h"]
    tops, bottoms = zip(*(_top_bottom(r) for r in regions))
    v_max = spec["scene"]["v_max"]
    if v_max is None:
        v_max = dam_speed(max(tops) - min(bottoms), g)
    c0 = fl["sound_speed"] or sound_speed(v_max, fl["sound_speed_factor"])
    if not c0 > 0:
        fail(path, "fluid", "without gravity the flow's speed scale is 0: give [fluid] "
             "sound_speed or [scene] v_max")
    sp = sph_params(fl["density"], c0, fl["viscosity"], dx, fl["r_clump"], fl["eps_xsph"],
                    fl["delta"], gamma=fl["gamma"], alpha=fl["alpha"])
    blocks = []
    for i, r in enumerate(regions):
        try:
            x = _fill(r, dx)
        except Exception as e:
            shape = 'box' if r.get('box') else 'polygon'
            if str(e).startswith("spacing "):
                fail(path, "fluid", f"{_spacing_key(e, 'dx')} ([[fluid.region]] "
                     f"#{i + 1}'s {shape})")
            fail(path, "fluid.region", f"key {shape!r}: {e}", r, i)
        surface = _top_bottom(r)[0] if r["surface"] is None else r["surface"]
        b = hydrostatic_fluid(x, sp.rho0, c0, sp.gamma, surface, g=g, dx=dx, h=h)
        b.v = np.broadcast_to(np.asarray(r["velocity"], float), b.x.shape).copy()
        blocks.append(b)
    cat = lambda k: np.concatenate([getattr(b, k) for b in blocks])
    fluid = FluidBlock(x=cat("x"), v=cat("v"), rho=cat("rho"), mass=cat("mass"), h=cat("h"))
    return fluid, sp, v_max, h


def _positions(path, tname, item, i):
    how = _shape(path, tname, item, i, ("box", "polygon", "points"))
    if how == "points":
        R = item["radius"] if item["radius"] is not None else (
            item["d"] / 2 if item["d"] is not None else None)
        if R is None:
            fail(path, tname, "key 'radius' (or 'd') is required with 'points'", item, i)
        x = np.asarray(item["points"], float)
        if isinstance(R, tuple):
            if tname == "structure":
                fail(path, tname, "key 'radius' takes one number for a structure (its bond "
                     "material has one disc size)", item, i)
            if len(R) != len(x):
                fail(path, tname, f"key 'radius' has {len(R)} radii for {len(x)} points",
                     item, i)
            R = np.asarray(R, float)
        return x, R, None
    d = item["d"]
    if d is None:
        fail(path, tname, f"key 'd' is required with {how!r} (disc diameter, m)", item, i)
    kind = item["packing"] or ("hex" if tname == "grains" else "square")
    try:
        if how == "box":
            x0, y0, x1, y1 = item["box"]
            x = packing(x0, y0, x1 - x0, y1 - y0, d, kind, stretch=_stretch(item))
        else:
            if _stretch(item):
                raise ValueError("stretch needs a box")
            v = np.asarray(item["polygon"], float)
            lo, hi = v.min(0), v.max(0)
            x = packing(lo[0], lo[1], hi[0] - lo[0], hi[1] - lo[1], d, kind)
            x = x[inside_polygon(x, v)]
            if x.shape[0] == 0:
                raise ValueError(f"the polygon holds no disc of diameter {d}")
    except Exception as e:
        if str(e).startswith("spacing "):
            fail(path, tname, f"{_spacing_key(e, 'd')} (its {how})", item, i)
        fail(path, tname, f"key {how!r}: {e}", item, i)
    if tname == "grains" and item["n"] is not None:
        if item["n"] > x.shape[0]:
            fail(path, tname, f"key 'n' = {item['n']} is out of range; allowed [1, "
                 f"{x.shape[0]}] for this bed", item, i)
        x = x[:item["n"]]
    return x, d / 2, kind


def _stretch(item) -> bool:
    return bool(item.get("stretch"))


def _spacing(item):
    """The column spacing of a stretched box (``stretch = true``), else None."""
    if not _stretch(item) or item.get("box") is None:
        return None
    x0, _, x1, _ = item["box"]
    return span_spacing(x1 - x0, item["d"])


def _group(path, tname, item, i):
    """(SolidBlock, BondBlock or None) of one disc group."""
    x, R, kind = _positions(path, tname, item, i)
    n = x.shape[0]
    vel = np.asarray(item["velocity"], float)
    if vel.ndim == 2 and vel.shape[0] != n:
        fail(path, tname, f"key 'velocity' has {vel.shape[0]} vectors for {n} discs", item, i)
    v = np.broadcast_to(vel, (n, 2)).copy()
    s = _spacing(item)
    blk = disc_block(x, R, item["rho"], mass_model=item["mass_model"],
                     packing=kind or "square", thickness=item["thickness"], v=v,
                     column_spacing=s)
    if s is not None:
        blk = strip_ends(blk, item["box"][0], item["box"][2])
    if tname == "structure":
        blk.sph_volume = np.full(n, (np.sqrt(3) / 2 if kind == "hex" else 1.0) * 4 * R * R)
    if tname in ("structure", "kinematic"):
        blk.structure = np.full(n, bool(item["coupled"]))
    else:
        blk.structure = np.zeros(n, bool)
    blk.grain = np.full(n, tname == "grains" or bool(item.get("grain")))
    if tname == "kinematic":
        blk.sph_volume = np.full(n, (np.sqrt(3) / 2 if kind == "hex" else 1.0) * 4 * R * R)
        move(blk, lambda p: np.ones(len(p), bool), vel if vel.ndim == 1 else (0.0, 0.0))
        if vel.ndim == 2:
            blk.v = v
    if item.get("clamp") is not None:
        sel = _region_mask(blk.x, item["clamp"])
        if not sel.any():
            fail(path, tname, "key 'clamp': the region holds none of its discs", item, i)
        move(blk, lambda p, sel=sel: sel, (0.0, 0.0))
    if item.get("move") is not None:
        sel = _region_mask(blk.x, item["move"]["region"])
        if not sel.any():
            fail(path, tname, "key 'move': the region holds none of its discs", item, i)
        move(blk, lambda p, sel=sel: sel, item["move"]["velocity"])
    if item.get("load") is not None:
        sel = _region_mask(blk.x, item["load"]["region"])
        if not sel.any():
            fail(path, tname, "key 'load': the region holds none of its discs", item, i)
        f = np.asarray(item["load"]["force"], float)
        blk.f_ext = np.where(sel[:, None], f[None, :] / sel.sum(), blk.f_ext)
    bonds = None
    if tname == "structure" or item.get("bonds") == "touching":
        bonds = touching_pairs(blk.x, R, gap=0.0 if s is None else s - 2 * R)
        if bonds.n == 0:
            fail(path, tname, "no two discs touch: nothing to bond", item, i)
    return blk, bonds


def _region_mask(x, region):
    if isinstance(region, dict):
        m = np.zeros(len(x), bool)
        for r in region["union"]:
            m |= in_region(x, r)
        return m
    if isinstance(region, np.ndarray) and region.dtype == bool:
        return region
    return in_region(x, region)


def _material(path, items):
    """The bond material of the structures: (k42 dict, sigma_c, tau_c, structure → record);
    every structure with E must give the same constants (Params hold one bond material)."""
    out, first, recs = None, None, {}
    for i, s in enumerate(items):
        if s["E"] is None:
            continue
        d = 2 * (s["radius"] if s["points"] is not None and s["radius"] is not None
                 else s["d"] / 2)
        sp = _spacing(s)
        k = k42_mapping(s["E"], s["nu"], d / 2, contact_fraction=s["contact_fraction"],
                        plane_strain=s["plane_strain"],
                        touching=sp is None or sp <= d * (1 + 1e-9))
        f = s["shear_factor"]
        k = {**k, "bond_ks": k["bond_ks"] * f, "ks": k["ks"] * f}
        key = (k["bond_kn"], k["bond_ks"], k["kn"], k["ks"], s["sigma_c"], s["tau_c"])
        if first is None:
            out, first = (k, s["sigma_c"], s["tau_c"]), (s["name"], key)
        elif key != first[1]:
            fail(path, "structure", f"its material (E, nu, d, strengths) differs from "
                 f"structure {first[0]!r}: one bond material per scene is supported "
                 "(Params hold one set of bond and contact constants)", s, i)
        recs[s["name"]] = {"E": s["E"], "nu": s["nu"], "plane_strain": s["plane_strain"],
                           "sigma_c": s["sigma_c"], "tau_c": s["tau_c"], "d": d}
    return out, recs


def _touching(A, ra, B, rb, tol=1e-6) -> bool:
    """Whether any disc of A (radii ra) overlaps one of B by more than ``tol`` of the
    smaller radius (:func:`_deepest_overlap`)."""
    return _deepest_overlap(A, ra, B, rb)[0] > tol


def _discs_in_obstacle(ob, x, radius, depth=0.5) -> np.ndarray:
    """Indices of the discs (centres ``x``, radii) that overlap obstacle ``ob``: centre
    inside its box or polygon, or nearer than R(1 − depth) to its outline (a polyline: to
    the line). A contact's own overlap stays allowed: a disc placed at rest on a floor
    sits m g/kn into it (the `rolling` scene: 0.8 % of R)."""
    x = np.asarray(x, float)
    r = np.broadcast_to(np.asarray(radius, float), (len(x),))
    a, b = _outline(ob)
    ab = b - a
    t = np.clip(np.einsum("nwk,wk->nw", x[:, None, :] - a[None], ab)
                / np.maximum(np.sum(ab * ab, axis=1), 1e-300), 0.0, 1.0)
    d = np.linalg.norm(x[:, None, :] - (a[None] + t[..., None] * ab[None]), axis=2).min(1)
    hit = d < r * (1 - depth)
    if ob.get("polyline") is None:
        hit |= in_region(x, ob["box"] if ob.get("box") is not None else ob["polygon"])
    return np.flatnonzero(hit)


#: the deepest overlap of two discs a scene file accepts, as a share of the smaller radius
#: (a packing settled in an earlier run holds contacts about 1 % deep)
OVERLAP_ALLOWED = 0.02


def _deepest_overlap(A, ra, B, rb, same=False):
    """(depth as a share of the smaller radius, i, j) of the deepest overlap between a
    disc i of A and a disc j of B (of A itself with ``same``, i ≠ j), or (0, -1, -1); B in
    chunks, A cut to each chunk's bounding box (no n_A × n_B matrix)."""
    A, B = np.asarray(A, float), np.asarray(B, float)
    ra = np.broadcast_to(np.asarray(ra, float), (len(A),))
    rb = np.broadcast_to(np.asarray(rb, float), (len(B),))
    reach, best = float(ra.max() + rb.max()), (0.0, -1, -1)
    for k in range(0, len(B), 512):
        b, r = B[k:k + 512], rb[k:k + 512]
        near = np.flatnonzero(np.all((A >= b.min(0) - reach) & (A <= b.max(0) + reach),
                                     axis=1))
        if not near.size:
            continue
        d = np.linalg.norm(A[near][:, None, :] - b[None, :, :], axis=2)
        depth = (ra[near][:, None] + r[None, :] - d) / np.minimum(ra[near][:, None],
                                                                   r[None, :])
        if same:
            depth[near[:, None] == np.arange(k, k + len(b))[None, :]] = -np.inf
        i, j = np.unravel_index(np.argmax(depth), depth.shape)
        if depth[i, j] > best[0]:
            best = (float(depth[i, j]), int(near[i]), int(k + j))
    return best


def _read_track(path, item, k):
    """The (t, x, y) rows of a [[kinematic]] body's `track` file, its path taken from the
    scene file's folder."""
    name = os.path.join(os.path.dirname(os.path.abspath(path)), item["track"])
    if not os.path.isfile(name):
        fail(path, "kinematic", f"key 'track': no such file {item['track']!r}", item, k)
    try:
        with open(name) as fh:
            lines = [ln for ln in fh.read().splitlines() if ln.strip()]
        rows = []
        for j, ln in enumerate(lines):
            cells = [c.strip() for c in ln.replace(";", ",").split(",")]
            try:
                rows.append([float(c) for c in cells])
            except ValueError:
                if j == 0:
                    continue                 # a header line
                raise ValueError(f"line {j + 1} is not three numbers: {ln!r}") from None
        a = np.asarray(rows, float)
        if a.ndim != 2 or a.shape[1] != 3 or len(a) < 2:
            raise ValueError("needs two or more rows of three numbers: time [s], x [m], y [m]")
        if not (np.all(np.isfinite(a)) and a[0, 0] >= 0 and np.all(np.diff(a[:, 0]) > 0)):
            raise ValueError("allowed finite numbers, times >= 0 strictly increasing")
    except (ValueError, UnicodeDecodeError) as e:
        fail(path, "kinematic", f"key 'track' ({item['track']}): {e}", item, k)
    return a


def _motion_windows(path, groups, bodies, spec, solid):
    """Physics.kinematic_motion for the [[kinematic]] bodies that do more than move at a
    constant velocity from the start: a start or stop (motion.Window), `oscillate`
    (motion.Oscillation) or `track` (motion.Track). Each body's discs start with the
    motion's velocity at t = 0."""
    out = []
    for t, item, blk, _ in groups:
        osc, track = item.get("oscillate"), item.get("track")
        if t != "kinematic" or (item["start"] == 0.0 and item["stop"] is None
                                and osc is None and track is None):
            continue
        v = np.asarray(item["velocity"], float)
        k = spec[t].index(item)
        if osc is not None and track is not None:
            fail(path, t, "give `oscillate` or `track`, not both", item, k)
        if (osc is not None or track is not None) and np.any(v != 0.0):
            fail(path, t, f"key '{'oscillate' if osc is not None else 'track'}' prescribes "
                 "the motion: leave `velocity` out", item, k)
        if track is not None and (item["start"] != 0.0 or item["stop"] is not None):
            fail(path, t, "key 'track': the file's times say when the body moves; leave "
                 "`start` and `stop` out", item, k)
        if v.ndim != 1:
            fail(path, t, "key 'start'/'stop' moves the body as one: give one `velocity` "
                 "vector", item, k)
        stop = math.inf if item["stop"] is None else item["stop"]
        if stop <= item["start"]:
            fail(path, t, f"key 'stop' = {stop} s must come after 'start' = "
                 f"{item['start']} s", item, k)
        idx = bodies[item["name"]]
        a, b = int(idx[0]), int(idx[-1]) + 1
        if track is not None:
            rows = _read_track(path, item, k)
            m = motion.Track(a, b, tuple(rows[:, 0]), tuple(rows[:, 1]), tuple(rows[:, 2]))
        elif osc is not None:
            m = motion.Oscillation(a, b, float(osc["amplitude"][0]), float(osc["amplitude"][1]),
                                   float(osc["period"]), float(osc.get("phase", 0.0)),
                                   float(osc.get("ramp", 0.0)), float(item["start"]), stop)
        else:
            m = motion.Window(a, b, float(v[0]), float(v[1]), float(item["start"]), stop)
        solid.v[idx] = np.asarray(motion.velocity(m, 0.0))
        out.append(m)
    return tuple(out)


def _overlaps(path, groups, fluid, spacing, spec):
    """Refuse discs of two bodies, or of one body given by points, that overlap by more
    than :data:`OVERLAP_ALLOWED` of the smaller radius, discs inside or deep across an
    obstacle, and water inside a body or an obstacle (a fluid particle stands for a cell
    of side ``spacing``: it may touch a disc, not overlap it)."""
    def check(ta, ia, A, tb, ib, B, same):
        depth, i, j = _deepest_overlap(A.x, A.radius, B.x, B.radius, same)
        if depth > OVERLAP_ALLOWED:
            whose = "two of its discs overlap" if same else f"overlaps {ta} {ia['name']!r}"
            (xi, yi), (xj, yj) = A.x[i], B.x[j]
            fail(path, tb, f"{whose} by {100 * depth:.3g} % of a radius (discs at "
                 f"({xi:.4g}, {yi:.4g}) and ({xj:.4g}, {yj:.4g}) m; allowed "
                 f"{100 * OVERLAP_ALLOWED:g} %, a settled packing's contacts): move them "
                 "apart", ib, spec[tb].index(ib))

    for a in range(len(groups)):
        ta, ia, A, _ = groups[a]
        if ia.get("points") is not None:     # a packing never overlaps itself
            check(ta, ia, A, ta, ia, A, True)
        for b in range(a + 1, len(groups)):
            tb, ib, B, _ = groups[b]
            check(ta, ia, A, tb, ib, B, False)
    for i, ob in enumerate(spec.get("obstacle", [])):
        for t, item, blk, _ in groups:
            k = _discs_in_obstacle(ob, blk.x, blk.radius)
            if k.size:
                x, y = blk.x[k[0]]
                fail(path, t, f"{k.size} of its discs lie inside obstacle "
                     f"{ob['name'] or i!r} (the first at ({x:.4g}, {y:.4g}) m): shrink or "
                     "move the body", item, spec[t].index(item))
    if fluid is None:
        return
    for t, item, blk, _ in groups:
        if t == "grains" or item.get("grain"):
            continue                     # water fills the pores of a grain bed
        if _touching(fluid.x, 0.5 * spacing, blk.x, blk.radius):
            fail(path, "fluid.region", f"water overlaps {t} {item['name']!r}: shrink the "
                 "region or move the body")
    for i, ob in enumerate(spec.get("obstacle", [])):
        if ob.get("polyline") is not None:
            continue
        shape = ob["box"] if ob.get("box") is not None else ob["polygon"]
        if np.any(in_region(fluid.x, shape)):
            fail(path, "obstacle", "water lies inside this obstacle: shrink the fluid region",
                 ob, i)


# --- the scene ------------------------------------------------------------------------------
def compose(spec: dict, path: str) -> SceneFile:
    """The Scene, probes and settings of a checked scene file."""
    sc = spec["scene"]
    g_vec = sc["gravity"]
    g = math.hypot(*g_vec)
    if g_vec[1] > 0:
        fail(path, "scene", f"key 'gravity' = {list(g_vec)} points up: y is up, so gravity "
             f"takes a negative y component, [{g_vec[0]:g}, {-g_vec[1]:g}]")
    name = sc["name"] or os.path.splitext(os.path.basename(path))[0]
    fluid = sp = h = None
    v_max = sc["v_max"]
    if "fluid" in spec:
        fluid, sp, v_max, h = _fluid(path, spec, g)
    elif spec.get("fluid.region"):
        fail(path, "fluid", "is required with [[fluid.region]] (density, dx, ...)")

    # discs
    groups = []                                  # (table, item, block, bonds)
    names = {}
    for t in GROUPS:
        for i, item in enumerate(spec.get(t, [])):
            if item["name"].startswith("tank."):
                fail(path, t, f"name {item['name']!r}: names tank.* are the tank's walls "
                     "(force probes on tank.floor, tank.left, tank.right)", item, i)
            if item["name"] in names:
                fail(path, t, f"name {item['name']!r} is used by another body ({names[item['name']]})",
                     item, i)
            names[item["name"]] = t
            blk, bonds = _group(path, t, item, i)
            groups.append((t, item, blk, bonds))
    solid = bonds = None
    bodies = {}
    if groups:
        solid, _ = merge(*[b for _, _, b, _ in groups])
        ii, jj, off = [], [], 0
        for t, item, blk, bb in groups:
            bodies[item["name"]] = np.arange(off, off + blk.n)
            if bb is not None:
                ii.append(np.asarray(bb.i) + off)
                jj.append(np.asarray(bb.j) + off)
            off += blk.n
        if ii:
            bonds = BondBlock(i=np.concatenate(ii).astype(np.int32),
                              j=np.concatenate(jj).astype(np.int32))
    _overlaps(path, groups, fluid, sp.dp if sp is not None else 0.0, spec)
    windows = _motion_windows(path, groups, bodies, spec, solid)

    # fixed SPH particles and DEM walls
    has_discs = solid is not None
    tank = spec.get("tank")
    if (tank is None and fluid is not None and not spec.get("obstacle") and g > 0
            and spec["scene"]["domain"] is None
            and not any(t in ("structure", "kinematic") for t, _, _, _ in groups)):
        fail(path, "fluid", "the water has nothing to hold it: no [tank], no [[obstacle]] "
             "and no structure or kinematic body; add a [tank] (width, height)")
    xb_parts, dx_parts, wall_a, wall_b, wall_side, image_side = [], [], [], [], [], []
    pad = 0.0
    hb = None
    if tank is not None:
        dxb = tank["dx_boundary"] or (sp.dp if sp is not None else None)
        dxb = None if dxb is None else fit_spacing(tank["width"], dxb)
        hb = tank["h"] or h
        if fluid is not None:
            layers = tank["layers"] or boundary_layers(hb, dxb)
            xb_parts.append(tank_walls(tank["width"], tank["height"], dxb, layers))
            dx_parts.append(dxb)
            pad = layers * dxb + 2 * hb
            if np.any((fluid.x[:, 0] < 0) | (fluid.x[:, 0] > tank["width"]) |
                      (fluid.x[:, 1] < 0)):
                fail(path, "fluid.region", f"water reaches outside the tank [0, "
                     f"{tank['width']}] × [0, {tank['height']}] m")
        elif tank["dx_boundary"] is not None:
            fail(path, "tank", "key 'dx_boundary': boundary particles need a [fluid]")
        _bodies_inside(path, tank, groups)
        dem = has_discs if tank["dem_walls"] is None else tank["dem_walls"]
        if dem:
            w = box_walls(0.0, 0.0, tank["width"], tank["height"], top=tank["lid"])
            wall_a.append(w.a)
            wall_b.append(w.b)
            wall_side.append(w.sides())         # the tank's walls act on the inside
            image_side.append(w.sides())
    obstacles = {}             # name -> (its boundary rows (a, b), its DEM walls (a, b))
    if wall_a and has_discs:   # the tank's walls (box_walls' order): the discs' load on each
        obstacles.update({f"tank.{side}": (None, (k, k + 1))
                          for k, side in enumerate(("floor", "left", "right"))})
    for i, ob in enumerate(spec.get("obstacle", [])):
        how = _shape(path, "obstacle", ob, i, ("box", "polygon", "polyline"))
        if ob["name"] is not None and (ob["name"] in names or ob["name"] in obstacles
                                       or ob["name"].startswith("tank.")):
            fail(path, "obstacle", f"name {ob['name']!r} is used by another body or "
                 "obstacle", ob, i)
        rows = walls_of = None
        if fluid is not None:
            first_row = sum(len(x) for x in xb_parts)
            dxo = ob["dx"] or (tank["dx_boundary"] if tank and tank["dx_boundary"] else sp.dp)
            hb = hb or h
            if how == "polyline":
                layers = ob["layers"] or boundary_layers(hb, dxo)
                xb_parts.append(polyline_particles(ob["polyline"], dxo, layers))
            else:
                try:
                    xb_parts.append(_fill(ob, dxo))
                except Exception as e:
                    fail(path, "obstacle", f"key {how!r}: {e}", ob, i)
            dx_parts.append(dxo)
            if tank is not None and not np.any(_in_tank(tank, xb_parts[-1])):
                fail(path, "obstacle", f"lies wholly outside the tank {_tank_span(tank)}", ob, i)
            rows = (first_row, first_row + len(xb_parts[-1]))
        dem = has_discs if ob["dem_walls"] is None else ob["dem_walls"]
        if dem:
            a, b = _outline(ob)
            first_wall = sum(len(w) for w in wall_a)
            wall_a.append(a)
            wall_b.append(b)
            wall_side.append(np.zeros(len(a)))  # an obstacle's outline acts on both sides
            image_side.append(np.full(len(a), 0.0 if how == "polyline" else _outward(a, b)))
            if has_discs:
                walls_of = (first_wall, first_wall + len(a))
        if ob["name"] is not None and (rows or walls_of):
            obstacles[ob["name"]] = (rows, walls_of)
    boundary = None
    if xb_parts:
        blocks = [boundary_block(x, sp.rho0, d, hb) for x, d in zip(xb_parts, dx_parts)]
        if len(blocks) == 1 or len(set(dx_parts)) == 1:
            boundary = boundary_block(np.concatenate(xb_parts), sp.rho0, dx_parts[0], hb)
        else:
            cat = lambda k: np.concatenate([getattr(b, k) for b in blocks])
            boundary = type(blocks[0])(x=cat("x"), rho=cat("rho"), p=cat("p"),
                                       mass=cat("mass"), h=cat("h"))
    walls = None
    if wall_a and has_discs:
        side, img = np.concatenate(wall_side), np.concatenate(image_side)
        wet = fluid is not None and bool(np.any(solid.grain))    # grains in the fluid
        walls = WallBlock(a=np.concatenate(wall_a), b=np.concatenate(wall_b), side=side,
                          image_side=img if wet and not np.array_equal(img, side) else None)

    # parameters
    structures = spec.get("structure", [])
    mat, materials = _material(path, structures)
    bond_tbl = spec.get("bonds", {})
    cont = spec.get("contacts")
    dem = bond = fpi = None
    if has_discs:
        cont = cont or _defaults("contacts")
        kn = cont["kn"] if cont["kn"] is not None else (mat[0]["kn"] if mat else None)
        if kn is None and np.all(solid.fixed):
            kn = DemParams().kn     # fixed and kinematic discs only: no contact force is read
        if kn is None:
            fail(path, "contacts", "key 'kn' is required: the scene has discs and no "
                 "structure material to derive it from (N/m per unit thickness)")
        ks = cont["ks"] if cont["ks"] is not None else (
            mat[0]["ks"] if mat and cont["kn"] is None else 0.5 * kn)
        dem = DemParams(kn=kn, ks=ks, mu=cont["friction"], beta_n=cont["beta_n"],
                        beta_s=cont["beta_s"], alpha=cont["alpha"], damping=cont["damping"],
                        load_ramp=cont["load_ramp"], mu_roll=cont["rolling_friction"])
    if bonds is not None:
        bt = {**_defaults("bonds"), **{k: v for k, v in bond_tbl.items() if v is not None}}
        kn_b = bt.get("kn") if bt.get("kn") is not None else (mat[0]["bond_kn"] if mat else None)
        ks_b = bt.get("ks") if bt.get("ks") is not None else (mat[0]["bond_ks"] if mat else None)
        if kn_b is None or ks_b is None:
            fail(path, "bonds", "keys 'kn' and 'ks' are required: bonded discs without a "
                 "structure material (E) (Pa/m)")
        bond = BondParams(kn=kn_b, ks=ks_b,
                          sigma_c=bt["sigma_c"] if bt.get("sigma_c") is not None else (
                              mat[1] if mat else 1.0e30),
                          tau_c=bt["tau_c"] if bt.get("tau_c") is not None else (
                              mat[2] if mat else 1.0e30),
                          beta_bar=bt["beta_bar"], lam=bt["lam"], thickness=bt["thickness"])
    elif bond_tbl:
        fail(path, "bonds", "the scene has no bonds (no [[structure]], no [[discs]] with "
             "bonds = 'touching')")

    # physics options
    ph = {**_defaults("physics"), **spec.get("physics", {})}
    options = {"x64": ph["x64"]}
    if ph["capacity_multiplier"] != NeighborConfig.capacity_multiplier:
        options["capacity_multiplier"] = ph["capacity_multiplier"]
    if windows:
        options["kinematic_motion"] = windows
    has_grains = solid is not None and bool(np.any(solid.grain))
    coupled = solid is not None and bool(np.any(solid.structure))
    if fluid is not None:
        options.update(boundary_pressure=ph["boundary_pressure"], kernel=ph["kernel"],
                       xsph=ph["xsph"], shifting=ph["shifting"], variable_h=ph["variable_h"],
                       transport_continuity=ph["transport_continuity"],
                       rho_tolerance=ph["rho_tolerance"],
                       delta_sph=(sp.delta > 0) if ph["delta_sph"] is None else ph["delta_sph"],
                       density_diffusion=ph["density_diffusion"],
                       artificial_viscosity=((sp.alpha > 0) if ph["artificial_viscosity"] is None
                                             else ph["artificial_viscosity"]))
        fsi = ph["coupling"] or ("extrapolated" if coupled else None)
        if fsi not in (None, "none"):
            if not coupled:
                fail(path, "physics", f"key 'coupling' = {fsi!r}: no structure or kinematic "
                     "discs are coupled to the fluid")
            options["fsi"] = fsi
        use_fpi = has_grains if ph["fpi"] is None else ph["fpi"]
        if use_fpi:
            if not has_grains:
                fail(path, "physics", "key 'fpi' = true: the scene has no grains")
            options.update(fpi=True, voidage=ph["voidage"], eps_floor=ph["eps_floor"],
                           drag=ph["drag"], wall_images=ph["wall_images"],
                           lubrication=ph["lubrication"], added_mass=ph["added_mass"],
                           pore_neighbours=ph["pore_neighbours"])
            if ph["fpi_pressure"] is not None:     # else Physics chooses by the packing
                options["fpi_pressure"] = ph["fpi_pressure"]
            fpi_tbl = spec.get("fpi") or _defaults("fpi")
            fpi = FpiParams(lub_gap_min=fpi_tbl["lub_gap_min"], lub_cutoff=fpi_tbl["lub_cutoff"],
                            added_mass=fpi_tbl["added_mass"])
            gi = np.flatnonzero(solid.grain)
            fluid = fluid_among_grains(fluid, solid.x[gi], solid.radius[gi], ph["voidage"],
                                       ph["eps_floor"], walls if ph["wall_images"] else None)
    if bonds is not None:
        options["bond_section"] = ph["bond_section"]
    if ph["dem_substeps"] is not None:
        options["dem_substeps"] = ph["dem_substeps"]
    if ph["dem_list_substeps"]:
        options["dem_list_substeps"] = True
    if ph["structure_acceleration"]:
        options["structure_acceleration"] = True
    params = Params(gravity=g_vec, sph=sp, dem=dem, bond=bond, fpi=fpi)

    # velocity scale and domain
    if v_max is None:
        speeds = np.linalg.norm(solid.v, axis=1) if solid is not None else np.zeros(1)
        v_max = float(speeds.max()) if speeds.max() > 0 else 1.0
    if sc["domain"] is not None:
        lo, hi = sc["domain"][:2], sc["domain"][2:]
    else:
        lo, hi = _auto_domain(tank, pad, sc["headroom"], fluid, boundary, solid, walls)
    scene = Scene(name=name, params=params, domain_lo=tuple(lo), domain_hi=tuple(hi),
                  v_max=v_max, fluid=fluid, boundary=boundary, solid=solid, bonds=bonds,
                  walls=walls, t_end=sc["t_end"], options=options,
                  builder_kwargs={"scene_file": os.path.abspath(path)}, dt=sc["dt"],
                  open_sides=tuple(x for x in sc["open_sides"] if x != "none"))
    try:
        scene.validate()
    except Exception as e:
        fail(path, "scene", str(e))
    probes, refs = _probes(path, spec, scene, bodies, obstacles)
    rows = P.wall_force_rows(probes)
    if rows:                     # the step records the fluid's force on these rows
        scene.options["wall_force"] = rows
    if P.wall_reaction(probes):  # and the discs' force on the DEM walls
        scene.options["wall_reaction"] = True
    if P.held_discs(probes):     # and the free discs' force on held discs
        scene.options["disc_reaction"] = P.held_discs(probes)
    out = dict(spec.get("output") or _defaults("output"))
    folder = os.path.dirname(os.path.abspath(path))
    if out["file"] is not None:
        out["file"] = os.path.join(folder, out["file"])
    cal = dict(spec.get("calibration") or {})
    if cal.get("data"):
        cal["data"] = os.path.join(folder, cal["data"])
    return SceneFile(scene=scene, probes=probes, bodies=bodies, materials=materials,
                     references=refs, output=out, calibration=cal, spec=spec, path=path)


def _defaults(table):
    from .schema import TABLES
    return {k.name: k.default for k in TABLES[table][1]}


def _auto_domain(tank, pad, headroom, fluid, boundary, solid, walls):
    """The tank's domain (:meth:`fpsi_jax.build.Tank.domain`: its boundary layers and the
    kernel's reach around it, ``headroom`` × height above), grown where a body sticks out;
    without a tank, the bounding box of everything with a margin."""
    pts = [b.x for b in (fluid, boundary, solid) if b is not None]
    if walls is not None:
        pts += [walls.a, walls.b]
    allp = np.concatenate(pts)
    r = float(solid.radius.max()) if solid is not None else 0.0
    margin = max(pad, 4 * r)
    lo_need, hi_need = allp.min(0) - r, allp.max(0) + r
    if tank is None:
        margin = max(margin, 1e-3 * float(np.max(hi_need - lo_need)))
        return (tuple(map(float, lo_need - margin)), tuple(map(float, hi_need + margin)))
    p = max(pad, 4 * r)
    lo, hi = domain((0.0, 0.0), (tank["width"], tank["height"]),
                    (p, p, p, headroom * tank["height"]))
    lo = tuple(float(a) if a < b else float(b - margin)
               for a, b in zip(lo, lo_need))
    hi = tuple(float(a) if a > c else float(c + margin) for a, c in zip(hi, hi_need))
    return lo, hi


def _tank_span(tank):
    return f"[0, {tank['width']:.4g}] × [0, {tank['height']:.4g}] m"


def _in_tank(tank, x):
    """(n,) whether points lie between the tank's side walls and above its floor (an open
    top lets water and discs start above the walls' height)."""
    return (x[:, 0] >= 0) & (x[:, 0] <= tank["width"]) & (x[:, 1] >= 0)


def _bodies_inside(path, tank, groups):
    """Refuse a disc group with a centre outside the tank (beyond a side wall or under the
    floor): the DEM walls would throw it in at the first step, or it would never meet the
    flow."""
    seen = {}
    for t, item, blk, _ in groups:
        i = seen[t] = seen.get(t, -1) + 1
        out = ~_in_tank(tank, np.asarray(blk.x))
        if out.any():
            x, y = np.asarray(blk.x)[np.argmax(out)]
            fail(path, t, f"a disc centre at ({x:.4g}, {y:.4g}) m lies outside the tank "
                 f"{_tank_span(tank)}", item, i)


def _probe_inside_domain(path, pr, i, scene, spec):
    """Refuse a probe's point, x or x range outside the scene's domain (it would read
    nothing all run: a point typed in mm, say)."""
    lo, hi = np.asarray(scene.domain_lo, float), np.asarray(scene.domain_hi, float)
    span = f"x {lo[0]:.4g} … {hi[0]:.4g} m, y {lo[1]:.4g} … {hi[1]:.4g} m"
    for key, axes in (("point", (0, 1)), ("x", (0,)), ("x_range", (0,))):
        v = pr.get(key)
        if v is None:
            continue
        vals = np.atleast_1d(np.asarray(v, float))
        pts = vals.reshape(-1, len(axes)) if key == "point" else vals[:, None]
        out = any(not (lo[a] <= p[k] <= hi[a]) for p in pts for k, a in enumerate(axes))
        if out:
            why = ("" if spec.get("tank") is not None or spec["scene"]["domain"] is not None
                   else "; the scene has no [tank], so the domain is its bodies' bounding "
                   "box: add a [tank] (or [scene] domain)")
            fail(path, "probe", f"key {key!r} = {v!r} lies outside the domain ({span}){why}",
                 pr, i)


def _probes(path, spec, scene, bodies, obstacles=None):
    probes, refs = [], {}
    obstacles = obstacles or {}
    folder = os.path.dirname(os.path.abspath(path))
    seen = set()
    for i, pr in enumerate(spec.get("probe", [])):
        name, kind = pr["name"], pr["kind"]
        if name in seen:
            fail(path, "probe", f"name {name!r} is used twice", pr, i)
        seen.add(name)
        idx = None
        if pr["body"] is not None and pr["body"] in obstacles:
            if kind != "force":
                fail(path, "probe", f"key 'body' = {pr['body']!r} names an obstacle: only "
                     f"kind 'force' reads one (kind {kind!r} reads discs)", pr, i)
            if pr["region"] is not None:
                fail(path, "probe", "key 'region' selects discs; a force probe on an "
                     "obstacle sums all its particles", pr, i)
            _probe_inside_domain(path, pr, i, scene, spec)
            rows, walls = obstacles[pr["body"]]
            probes.append(P.obstacle_force(name, scene, rows, pr["about"], walls))
            _reference(path, folder, pr, i, probes[-1], refs)
            continue
        if pr["region"] is not None and pr["body"] is None:
            fail(path, "probe", "key 'region' selects discs of a `body`: name the body", pr, i)
        if pr["body"] is not None:
            if pr["body"] not in bodies:
                known = list(bodies) + [f"{o} (obstacle)" for o in obstacles]
                fail(path, "probe", f"key 'body' = {pr['body']!r} names no body; bodies: "
                     f"{', '.join(known) or 'none'}", pr, i)
            idx = bodies[pr["body"]]
            if pr["region"] is not None:
                sel = _region_mask(scene.solid.x[idx], pr["region"])
                if not sel.any():
                    fail(path, "probe", f"key 'region' holds none of {pr['body']!r}'s discs",
                         pr, i)
                idx = idx[sel]
            if pr["point"] is not None and kind == "displacement":
                d = np.linalg.norm(scene.solid.x[idx] - np.asarray(pr["point"]), axis=1)
                idx = idx[[int(np.argmin(d))]]

        def need(key):
            if pr[key] is None:
                fail(path, "probe", f"key {key!r} is required for kind {kind!r}", pr, i)
            return pr[key]

        _probe_inside_domain(path, pr, i, scene, spec)

        try:
            if kind == "displacement":
                need("body")
                p = P.displacement(name, scene, idx)
            elif kind == "force":
                need("body")
                p = P.force(name, scene, idx, pr["about"])
            elif kind == "pressure":
                p = P.pressure(name, scene, need("point"),
                               kernel=scene.options.get("kernel", "wendland"))
            elif kind == "water_level":
                p = P.water_level(name, scene, need("x"), pr["floor"])
            elif kind == "front":
                p = P.front(name, scene, pr["direction"], idx, pr["above"])
            elif kind == "bed_profile":
                need("body")
                x0, x1 = need("x_range")
                p = P.bed_profile(name, scene, idx, x0, x1, pr["bins"], pr["floor"])
            else:
                p = P.broken_bonds(name, scene, idx)
        except FileError:            # need(): already one line naming the file and key
            raise
        except Exception as e:
            if isinstance(e, SystemExit):
                raise
            msg = str(e).replace(f"probe {name!r}: ", "")
            fail(path, "probe", msg, pr, i)
        probes.append(p)
        _reference(path, folder, pr, i, p, refs)
    return probes, refs


def _reference(path, folder, pr, i, p, refs):
    """Read a probe's ``reference`` curve now, so that a bad curve stops before the run."""
    if pr["reference"] is None:
        return
    ref = os.path.join(folder, pr["reference"])
    if not os.path.exists(ref):
        fail(path, "probe", f"key 'reference' = {pr['reference']!r}: no such file", pr, i)
    try:
        data.match(ref, p)
    except data.DataError as e:
        fail(path, "probe", f"key 'reference': {e}", pr, i)
    refs[p.name] = ref

