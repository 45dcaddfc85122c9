"""Probes: named measurements recorded every step inside the compiled rollout.

A :class:`Probe` is a pure function ``state -> (k,) array`` with a name, component names and
units. ``simulate(scene, probes=[...])`` records each one after every step (not from the
output frames), returns them in ``Result.probes`` (name → (n_steps, k) array), writes
them to the HDF5 file under ``/probes/<name>`` and to ``<output>_probes.csv``.

    tip = probes.displacement("tip", scene, idx)       # mean displacement of discs idx
    res = simulate(scene, probes=[tip, probes.front("front", scene)])
    res.probes["tip"][:, 0]                            # u_x after every step [m]

Index sets are resolved on the host when the probe is made (from the scene's start
positions); the functions only gather and reduce, so they run on any device. Forces and
moments are per metre of out-of-plane thickness (the 2D model's unit depth).

Kinds (the scene file's ``[[probe]] kind``):

==============  ========================================================  ==============
kind            what                                                      components
==============  ========================================================  ==============
displacement    mean displacement of a set of discs from its start        ux, uy [m]
force           the fluid's force on a set of structure discs, or the     Fx, Fy [N/m],
                fluid's and the discs' force on an obstacle, and its      M [N m/m]
                moment about a point (Σ (x_i − c) × F_i)
pressure        fluid pressure at a point: Shepard interpolation          p [Pa]
                Σ P_j W_j V_j / Σ W_j V_j, V_j = m_j/ρ_j (0 when dry)
water_level     free-surface height at x: the highest fluid particle      level [m]
                within Δp/2 of x, plus Δp/2 (``floor`` when dry)
front           the fluid's leading edge along ±x: max (min) x ± Δp/2      x [m]
bed_profile     top of a grain bed in ``bins`` columns between x0 and     z_0 … [m]
                x1: max (y + R) of the grains in each (``floor``: empty)
broken_bonds    number of broken bonds (of a set of discs, or all)        n [-]
==============  ========================================================  ==============
"""
from __future__ import annotations

import csv
import json
import os
from dataclasses import dataclass, field
from typing import Callable

import jax.numpy as jnp
import numpy as np

from ..model.errors import ParameterError
from ..physics import eos, kernels
from . import observers

KINDS = ("displacement", "force", "pressure", "water_level", "front", "bed_profile",
         "broken_bonds")


@dataclass(frozen=True, eq=False)
class Probe:
    """A named measurement: ``fn(state) -> (k,)`` with ``components`` and their ``units``;
    ``spec`` describes it for the output files (kind and resolved settings)."""

    name: str
    kind: str
    fn: Callable
    components: tuple
    units: tuple
    spec: dict = field(default_factory=dict)

    def __call__(self, state):
        return jnp.atleast_1d(self.fn(state))

    def columns(self) -> list[str]:
        """CSV column headers, ``<name>.<component> [<unit>]``."""
        return [f"{self.name}.{c} [{u}]" for c, u in zip(self.components, self.units)]


def _indices(idx, n, what) -> np.ndarray:
    idx = np.asarray(idx)
    idx = np.flatnonzero(idx) if idx.dtype == bool else idx.astype(int).ravel()
    if idx.size == 0:
        raise ParameterError(f"{what}: the probe selects no particle")
    if idx.min() < 0 or idx.max() >= n:
        raise ParameterError(f"{what}: index out of range; allowed [0, {n - 1}]")
    return idx.astype(np.int32)      # int32 whatever JAX's x64 flag is when the probe is made


def _need(scene, phase, name):
    if getattr(scene, phase) is None:
        raise ParameterError(f"probe {name!r}: the scene has no {phase} particles")


def displacement(name: str, scene, idx) -> Probe:
    """Mean displacement (ux, uy) of the discs ``idx`` from their mean start position."""
    _need(scene, "solid", name)
    ii = _indices(idx, scene.solid.n, f"probe {name!r}")
    x0 = np.asarray(scene.solid.x, float)[ii].mean(axis=0)
    jj = jnp.asarray(ii)

    def fn(s):
        x = s.solid.x
        return jnp.mean(x[jj], axis=0) - jnp.asarray(x0, x.dtype)

    return Probe(name, "displacement", fn, ("ux", "uy"), ("m", "m"),
                 {"discs": int(ii.size), "start": x0.tolist()})


def force(name: str, scene, idx, about=None) -> Probe:
    """The force on the discs ``idx`` and its moment about ``about`` (default: their start
    centroid), anticlockwise positive.

    On discs that move under their forces it is the fluid's force (Σ F_i of the FSI
    coupling, W6.1), the hydrodynamic load on a structure; on grains in the fluid, the
    fluid's force on them, buoyancy and drag (W19, ``FpiState.force``), at their centres.
    On discs that are all held (clamped or kinematic: a support, a platen, a gate driven
    at a given speed) it is
    everything the rest of the model puts on them: the fluid's force where they are
    coupled to it, plus the free discs' contacts and the bonds to free discs
    (SolidState.reaction, the mean over the step's DEM sub-steps), the force a support
    must hold against or a drive must overcome, with the sign of a load on the body. The
    run computes the second part only when a probe asks (``spec['held_discs']``, passed on
    as ``Physics.disc_reaction``, as :func:`~fpsi_jax.run.driver.simulate` arranges)."""
    _need(scene, "solid", name)
    ii = _indices(idx, scene.solid.n, f"probe {name!r}")
    held = bool(np.all(np.asarray(scene.solid.fixed, bool)[ii]))
    structure = (scene.solid.structure_indices() if scene.fluid is not None
                 and scene.options.get("fsi") is not None else np.zeros(0))
    rows = np.flatnonzero(np.isin(structure, ii))
    grains = (scene.solid.grain_indices() if scene.fluid is not None
              and scene.options.get("fpi") else np.zeros(0))
    grain_rows = np.flatnonzero(np.isin(grains, ii))
    if not held:
        if scene.fluid is None:
            raise ParameterError(f"probe {name!r}: a force probe on discs that move is the "
                                 "fluid's force on them, and the scene has no fluid; the "
                                 "discs' force on a fixed body is a force probe on held "
                                 "(clamped or kinematic) discs or on an obstacle")
        if rows.size == 0 and grain_rows.size == 0:
            raise ParameterError(f"probe {name!r}: none of its discs is a fluid-coupled "
                                 "structure disc or a grain in the fluid")
    c = (np.asarray(scene.solid.x, float)[ii].mean(axis=0) if about is None
         else np.asarray(about, float))
    rr = jnp.asarray(rows, jnp.int32)
    gr = jnp.asarray(grain_rows, jnp.int32)
    spec = {"discs": int(ii.size), "about": c.tolist()}
    if held:
        spec["held_discs"] = sorted(int(i) for i in ii)

    def fn(s):
        dtype = s.solid.x.dtype
        cc = jnp.asarray(c, dtype)
        out = jnp.zeros(3, dtype)
        for part, r in (("fsi", rr), ("fpi", gr)):
            if r.size:                       # the fluid's force, at the discs' centres
                coupled = getattr(s, part)
                if coupled is None:
                    raise ParameterError(f"probe {name!r} reads the fluid's force on its "
                                         f"discs, and the run has no {part} coupling (an "
                                         f"option set off?)")
                f = coupled.force[r]
                x = s.solid.x[coupled.idx[r]] - cc
                m = jnp.sum(x[:, 0] * f[:, 1] - x[:, 1] * f[:, 0])
                out = out + jnp.concatenate([jnp.sum(f, axis=0), m[None]])
        if held:
            if s.solid.reaction is None:
                raise ParameterError(f"probe {name!r} reads held discs' reactions: run with "
                                     f"Physics.disc_reaction = {spec['held_discs']} "
                                     "(simulate arranges it)")
            r = jnp.sum(s.solid.reaction[jnp.asarray(ii)], axis=0)
            out = out + jnp.stack([r[0], r[1], r[2] - (cc[0] * r[1] - cc[1] * r[0])])
        return out

    return Probe(name, "force", fn, ("Fx", "Fy", "M"), ("N/m", "N/m", "N m/m"), spec)


def obstacle_force(name: str, scene, rows=None, about=None, walls=None) -> Probe:
    """The force of the water and of the discs on a fixed obstacle, and its moment about
    ``about`` (default: the centroid of its boundary particles, or of its walls' ends),
    anticlockwise positive.

    ``rows`` = (a, b): its boundary particles a … b − 1 of ``scene.boundary`` (the scene
    file's ``[[obstacle]]`` blocks follow the tank's walls). Each fluid–boundary pair's
    momentum term counts once, F_B = −Σ_F m_F a_{F←B}, as for a structure (what
    DualSPHysics' ComputeForces sums on boundary particles), at the step's SPH evaluation.

    ``walls`` = (a, b): its DEM walls a … b − 1 of ``scene.walls``, through which grains and
    structures press on it: the opposite of the walls' contact forces on the discs, applied
    at the contact points, the mean over the step's DEM sub-steps (WallState.reaction).

    The run computes these only when a probe asks: the boundary rows
    (``spec['boundary_rows']``, passed on as ``Physics.wall_force``) and the walls
    (``spec['dem_walls']``, ``Physics.wall_reaction``), as
    :func:`~fpsi_jax.run.driver.simulate` arranges."""
    if rows is None and walls is None:
        raise ParameterError(f"probe {name!r}: the obstacle has neither boundary particles "
                             "nor DEM walls")
    spec, pts = {}, []
    if rows is not None:
        _need(scene, "boundary", name)
        a, b = (int(r) for r in rows)
        if not 0 <= a < b <= scene.boundary.n:
            raise ParameterError(f"probe {name!r}: boundary rows ({a}, {b}) out of range; "
                                 f"allowed 0 <= a < b <= {scene.boundary.n}")
        xb = np.asarray(scene.boundary.x, float)[a:b]
        spec["boundary_rows"], pts = [a, b], [xb]
    if walls is not None:
        if scene.walls is None:
            raise ParameterError(f"probe {name!r}: the scene has no DEM walls")
        wa, wb = (int(r) for r in walls)
        if not 0 <= wa < wb <= scene.walls.n:
            raise ParameterError(f"probe {name!r}: DEM walls ({wa}, {wb}) out of range; "
                                 f"allowed 0 <= a < b <= {scene.walls.n}")
        spec["dem_walls"] = [wa, wb]
        if rows is None:
            pts = [np.asarray(scene.walls.a, float)[wa:wb],
                   np.asarray(scene.walls.b, float)[wa:wb]]
    c = np.concatenate(pts).mean(axis=0) if about is None else np.asarray(about, float)
    spec["about"] = c.tolist()

    def fn(s):
        dtype = (s.walls.reaction if rows is None else s.boundary.force).dtype
        cc = jnp.asarray(c, dtype)
        total = jnp.zeros(3, dtype)
        if rows is not None:
            f = s.boundary.force[a:b]
            x = jnp.asarray(xb, dtype) - cc
            m = jnp.sum(x[:, 0] * f[:, 1] - x[:, 1] * f[:, 0])
            total = total + jnp.concatenate([jnp.sum(f, axis=0), m[None]])
        if walls is not None:
            r = jnp.sum(s.walls.reaction[wa:wb], axis=0)     # moment about the origin
            total = total + r.at[2].add(-(cc[0] * r[1] - cc[1] * r[0]))
        return total

    return Probe(name, "force", fn, ("Fx", "Fy", "M"), ("N/m", "N/m", "N m/m"), spec)


def wall_reaction(probes) -> bool:
    """Whether any probe of ``probes`` reads the discs' force on DEM walls
    (Physics.wall_reaction)."""
    return any("dem_walls" in p.spec for p in probes or ())


def held_discs(probes) -> tuple:
    """The held discs every force probe on held discs of ``probes`` reads, sorted
    (Physics.disc_reaction), or () when none asks for any."""
    return tuple(sorted({i for p in probes or () for i in p.spec.get("held_discs", ())}))


def wall_force_rows(probes) -> tuple:
    """The boundary rows (a, b) that cover every obstacle force probe of ``probes``
    (Physics.wall_force), or () when none asks for any."""
    spans = [p.spec["boundary_rows"] for p in probes or () if "boundary_rows" in p.spec]
    if not spans:
        return ()
    return (min(a for a, _ in spans), max(b for _, b in spans))


def pressure(name: str, scene, point, kernel="wendland") -> Probe:
    """Fluid pressure at ``point`` by Shepard interpolation over the fluid particles within
    the kernel support: P = Σ P_j W_j V_j / Σ W_j V_j with V_j = m_j/ρ_j and P_j from the
    Tait EOS (the scene's ρ0, c0, γ); 0 when no fluid particle reaches the point."""
    _need(scene, "fluid", name)
    sp = scene.params.sph
    rho0, c0, gamma = float(sp.rho0), float(sp.c0), float(sp.gamma)
    w = kernels.get(kernel).w
    p0 = np.asarray(point, float)

    def fn(s):
        f = s.fluid
        r = jnp.linalg.norm(f.x - jnp.asarray(p0, f.x.dtype), axis=1)
        wv = jnp.where(r < kernels.SUPPORT * f.h, w(r, f.h), 0.0) * f.mass / f.rho
        p = eos.pressure(f.rho, rho0, c0, gamma)
        den = jnp.sum(wv)
        return jnp.sum(p * wv) / jnp.where(den > 0, den, 1.0)

    return Probe(name, "pressure", fn, ("p",), ("Pa",), {"point": p0.tolist()})


def water_level(name: str, scene, x: float, floor: float = 0.0) -> Probe:
    """Height of the free surface at ``x``: the highest fluid particle whose centre lies
    within Δp of x (Δp the initial spacing), plus Δp/2; ``floor`` when none does. The
    window is two spacings wide so that a column of particles always lies in it: one
    spacing wide, a probe between two columns read still water one spacing low whenever
    both top particles jittered out of it. At a surface of slope s it reads up to s·Δp
    high."""
    _need(scene, "fluid", name)
    half = 0.5 * float(scene.params.sph.dp)

    def fn(s):
        xf = s.fluid.x
        near = (jnp.abs(xf[:, 0] - x) <= 2 * half) & observers.in_computation(s.fluid)
        top = jnp.max(jnp.where(near, xf[:, 1] + half, floor))
        return jnp.maximum(top, floor)

    return Probe(name, "water_level", fn, ("level",), ("m",), {"x": float(x),
                                                               "floor": float(floor)})


def front(name: str, scene, direction: str = "+x", idx=None, above=None) -> Probe:
    """The leading edge along +x or −x: of the fluid (max x + Δp/2, or min x − Δp/2), or
    of the discs ``idx`` (max x + R: how far grains were carried). ``above``: only what
    lies higher than this y counts (a bore running over still tailwater: the farthest
    water above the tailwater's level). 0 while nothing counts."""
    if direction not in ("+x", "-x"):
        raise ParameterError(f"probe {name!r}: direction = {direction!r}; allowed '+x', '-x'")
    sign = 1.0 if direction == "+x" else -1.0
    if idx is None:
        _need(scene, "fluid", name)
        half = 0.5 * float(scene.params.sph.dp)
        ii = None
    else:
        _need(scene, "solid", name)
        ii = jnp.asarray(_indices(idx, scene.solid.n, f"probe {name!r}"))

    def fn(s):
        block = s.fluid if ii is None else s.solid
        x, inside, reach = block.x, observers.in_computation(block), None
        if ii is None:
            reach = half
        else:
            x, inside, reach = x[ii], inside[ii], block.radius[ii]
        if above is not None:
            inside = inside & (x[:, 1] > above)
        edge = jnp.max(jnp.where(inside, sign * x[:, 0] + reach, -jnp.inf))
        return jnp.where(jnp.any(inside), sign * edge, 0.0)

    spec = {"direction": direction}
    if idx is not None:
        spec["discs"] = int(ii.size)
    if above is not None:
        spec["above"] = float(above)
    return Probe(name, "front", fn, ("x",), ("m",), spec)


def bed_profile(name: str, scene, idx, x0: float, x1: float, bins: int,
                floor: float = 0.0) -> Probe:
    """Top of the grains ``idx`` in ``bins`` equal columns between ``x0`` and ``x1``: the
    largest y + R of the grains whose centre lies in each column (``floor`` if none)."""
    _need(scene, "solid", name)
    if not (bins >= 1 and x1 > x0):
        raise ParameterError(f"probe {name!r}: needs bins >= 1 and x1 > x0")
    ii = jnp.asarray(_indices(idx, scene.solid.n, f"probe {name!r}"))
    edges = np.linspace(x0, x1, bins + 1)

    def fn(s):
        x, r = s.solid.x[ii], s.solid.radius[ii]
        k = jnp.floor((x[:, 0] - x0) / (x1 - x0) * bins).astype(jnp.int32)
        inside = (k >= 0) & (k < bins)
        top = jnp.where(inside, x[:, 1] + r, floor)
        col = jnp.arange(bins)[:, None] == k[None, :]
        return jnp.max(jnp.where(col, top[None, :], floor), axis=1)

    centres = 0.5 * (edges[1:] + edges[:-1])
    return Probe(name, "bed_profile", fn, tuple(f"z{k}" for k in range(bins)),
                 ("m",) * bins, {"x_centres": centres.tolist(), "floor": float(floor)})


def broken_bonds(name: str, scene, idx=None) -> Probe:
    """Number of broken bonds; with ``idx``, only bonds with both discs in that set."""
    if scene.bonds is None:
        raise ParameterError(f"probe {name!r}: the scene has no bonds")
    bi, bj = np.asarray(scene.bonds.i), np.asarray(scene.bonds.j)
    if idx is None:
        sel = np.ones(bi.size, bool)
    else:
        ii = _indices(idx, scene.solid.n, f"probe {name!r}")
        sel = np.isin(bi, ii) & np.isin(bj, ii)
    mask = jnp.asarray(sel)
    fn = lambda s: jnp.sum(mask & ~s.bonds.intact).astype(s.solid.x.dtype)
    return Probe(name, "broken_bonds", fn, ("n",), ("-",), {"bonds": int(sel.sum())})


# --- recording and output ----------------------------------------------------------------
def check_names(probes) -> list:
    """``probes`` as a list with unique names (ParameterError otherwise)."""
    probes = list(probes or [])
    names = [p.name for p in probes]
    dup = {n for n in names if names.count(n) > 1}
    if dup:
        raise ParameterError(f"probe name {sorted(dup)[0]!r} used twice")
    return probes


def observer(probes):
    """observe(state) = {name: (k,) value} for the probes."""
    return lambda s: {p.name: p(s) for p in probes}


def csv_path(output: str) -> str:
    """``<output stem>_probes.csv`` beside the HDF5 file."""
    return os.path.splitext(output)[0] + "_probes.csv"


def write_csv(path: str, probes, times, values: dict) -> str:
    """One CSV: ``t [s]`` then every probe's components, one row per step."""
    os.makedirs(os.path.dirname(os.path.abspath(path)) or ".", exist_ok=True)
    cols = [np.asarray(times, float)[:, None]]
    header = ["t [s]"]
    for p in probes:
        cols.append(np.asarray(values[p.name], float).reshape(len(times), len(p.components)))
        header += p.columns()
    table = np.concatenate(cols, axis=1)
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        for row in table:
            w.writerow([repr(float(v)) for v in row])
    return path


def describe(probes) -> str:
    """JSON of every probe's kind, components, units and settings (HDF5 attribute)."""
    return json.dumps({p.name: {"kind": p.kind, "components": list(p.components),
                                "units": list(p.units), **p.spec} for p in probes})
