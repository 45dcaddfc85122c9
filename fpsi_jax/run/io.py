"""Output: HDF5 frames (h5py) with an XDMF sidecar so ParaView opens the run.

Layout of a file::

    /time (T,)  /step (T,)                     one entry per written frame
    /fluid/{x (T,n,2), v (T,n,2), rho (T,n), p (T,n), h (T,n)}
    /boundary/{x (n,2), rho (n,), p (T,n)}     positions are fixed, pressure may not be
    /solid/{x (T,n,2), v (T,n,2), omega (T,n), theta (T,n), radius (n,), fixed (n,)}
    /bonds/{i (b,), j (b,), intact (T,b), fn (T,b), fs (T,b), m (T,b)}
    /bonds/breaks/{bond, time, mode}            every break so far (mode 1 tension, 2 shear)
    /walls/{a (w,2), b (w,2)}
    /fsi/{idx (s,), force (T,s,2), p (T,s)}   structure discs in the SPH sums: disc index,
                                               the fluid's force on each and their pressure
    /fluid/eps (T,n)                           fluid voidage, with grains (fpi)
    /fpi/{idx (g,), force (T,g,2), eps_p (T,g)}  grains: disc index, the fluid's force on
                                               each (buoyancy + drag) and their voidage
    /probes/{time (S,), <name> (S,k)}           every probe after every step (run.probes);
                                               attrs: components and units per probe
    attrs: scene, physics, params (JSON), fpsi_version, status

Datasets are extendible along the time axis and the file is flushed after every frame, so
a run that stops (or crashes) leaves a valid file up to its last good frame. Nothing
non-finite is ever written: the driver checks a frame before handing it over. The XDMF
sidecar is rewritten when the frame count reaches a power of two and on close (O(T) in all).
"""
from __future__ import annotations

import json
import os
from dataclasses import dataclass

import h5py
import numpy as np

from .. import __version__
from ..physics import eos

FLUID_FIELDS = ("x", "v", "rho", "p", "h")


class Writer:
    """Append frames of a run to an HDF5 file and keep its XDMF sidecar up to date."""

    def __init__(self, path, scene, phys, params, probes=()):
        os.makedirs(os.path.dirname(os.path.abspath(path)) or ".", exist_ok=True)
        self.path = str(path)
        self.f = h5py.File(self.path, "w")
        self.f.attrs["scene"] = scene.to_json()
        self.f.attrs["physics"] = phys.to_json()
        self.f.attrs["params"] = json.dumps(params.to_json())
        self.f.attrs["fpsi_version"] = __version__
        self.f.attrs["status"] = "running"
        self.n_fluid, self.n_boundary = phys.n_fluid, phys.n_boundary
        self.n_solid, self.n_bonds = phys.n_solid, phys.n_bonds
        self._make("time", (), np.float64)
        self._make("step", (), np.int64)
        self.probes = list(probes or ())
        if self.probes:
            from .probes import describe
            g = self.f.create_group("probes")
            g.attrs["probes"] = describe(self.probes)
            g.create_dataset("time", shape=(0,), maxshape=(None,), dtype=np.float64,
                             chunks=(4096,))
            for pr in self.probes:
                k = len(pr.components)
                d = g.create_dataset(pr.name, shape=(0, k), maxshape=(None, k),
                                     dtype=np.float64, chunks=(4096, k))
                d.attrs["components"] = json.dumps(list(pr.components))
                d.attrs["units"] = json.dumps(list(pr.units))
        nf = self.n_fluid
        if nf:
            for k, shape in (("x", (nf, 2)), ("v", (nf, 2)), ("rho", (nf,)), ("p", (nf,)),
                             ("h", (nf,))):
                self._make(f"fluid/{k}", shape, np.float32)
        if self.n_boundary:
            self.f.create_dataset("boundary/x", data=np.asarray(scene.boundary.x, np.float32))
            self.f.create_dataset("boundary/rho", data=np.asarray(scene.boundary.rho,
                                                                  np.float32))
            self._make("boundary/p", (self.n_boundary,), np.float32)
        ns = self.n_solid
        if ns:
            for k, shape in SOLID_FIELDS:
                self._make(f"solid/{k}", shape(ns), np.float32)
            self.f.create_dataset("solid/radius", data=np.asarray(scene.solid.radius, np.float32))
            self.f.create_dataset("solid/fixed", data=np.asarray(scene.solid.fixed, np.uint8))
        if self.n_bonds:
            nb = self.n_bonds
            self.f.create_dataset("bonds/i", data=np.asarray(scene.bonds.i, np.int32))
            self.f.create_dataset("bonds/j", data=np.asarray(scene.bonds.j, np.int32))
            self._make("bonds/intact", (nb,), np.uint8)
            for k in BOND_FORCES:
                self._make(f"bonds/{k}", (nb,), np.float32)
            for k, dt in (("bond", np.int32), ("time", np.float64), ("mode", np.int32)):
                self.f.create_dataset(f"bonds/breaks/{k}", shape=(0,), maxshape=(None,),
                                      dtype=dt, chunks=(256,))
        self.n_structure = phys.n_structure if phys.has_fsi else 0
        if self.n_structure:
            self.f.create_dataset("fsi/idx", data=scene.solid.structure_indices())
            self._make("fsi/force", (self.n_structure, 2), np.float32)
            self._make("fsi/p", (self.n_structure,), np.float32)
        self.n_grain = phys.n_grain if phys.has_fpi else 0
        if self.n_grain:
            self._make("fluid/eps", (nf,), np.float32)
            self.f.create_dataset("fpi/idx", data=scene.solid.grain_indices())
            self._make("fpi/force", (self.n_grain, 2), np.float32)
            self._make("fpi/eps_p", (self.n_grain,), np.float32)
        if scene.walls is not None:
            self.f.create_dataset("walls/a", data=np.asarray(scene.walls.a, np.float32))
            self.f.create_dataset("walls/b", data=np.asarray(scene.walls.b, np.float32))
        self.frames = 0
        self.sph_params = params.sph

    def _make(self, name, shape, dtype):
        self.f.create_dataset(name, shape=(0,) + shape, maxshape=(None,) + shape,
                              dtype=dtype, chunks=(1,) + shape if shape else (1024,))

    def _append(self, name, value):
        d = self.f[name]
        d.resize(self.frames + 1, axis=0)
        d[self.frames] = value

    def _frame_data(self, state) -> dict:
        data = {}
        if self.n_fluid:
            fl, sp = state.fluid, self.sph_params
            data.update({f"fluid/{k}": v for k, v in (
                ("x", fl.x), ("v", fl.v), ("rho", fl.rho), ("h", fl.h),
                ("p", eos.pressure(fl.rho, sp.rho0, sp.c0, sp.gamma)))})
        if self.n_boundary:
            data["boundary/p"] = state.boundary.p
        if self.n_solid:
            data.update({f"solid/{k}": getattr(state.solid, k) for k, _ in SOLID_FIELDS})
        if self.n_bonds:
            data.update({f"bonds/{k}": getattr(state.bonds, k) for k in BOND_FORCES})
        if self.n_structure:
            data.update({"fsi/force": state.fsi.force, "fsi/p": state.fsi.p})
        if self.n_grain:
            data.update({"fluid/eps": state.fpi.eps, "fpi/force": state.fpi.force,
                         "fpi/eps_p": state.fpi.eps_p})
        data = {k: np.asarray(v) for k, v in data.items()}
        for k, v in data.items():
            if not np.all(np.isfinite(v)):
                raise ValueError(f"refusing to write non-finite {k} to {self.path}")
        return data

    def write_probes(self, times, values: dict):
        """Append the probe rows of one chunk (``values``: name → (n, k)); refuses
        non-finite values."""
        g = self.f["probes"]
        n0, n = g["time"].shape[0], len(times)
        rows = {}
        for pr in self.probes:
            v = np.asarray(values[pr.name], float).reshape(n, -1)
            if not np.all(np.isfinite(v)):
                raise ValueError(f"refusing to write non-finite probe {pr.name!r} to "
                                 f"{self.path}")
            rows[pr.name] = v
        g["time"].resize(n0 + n, axis=0)
        g["time"][n0:] = np.asarray(times, float)
        for name, v in rows.items():
            g[name].resize(n0 + n, axis=0)
            g[name][n0:] = v

    def write(self, state):
        """Append one frame; refuses non-finite data (the driver checks before calling)."""
        data = self._frame_data(state)
        self._append("time", float(state.t))
        self._append("step", int(state.step))
        for k, v in data.items():
            self._append(k, v)
        if self.n_bonds:
            b = state.bonds
            self._append("bonds/intact", np.asarray(b.intact, np.uint8))
            tb = np.asarray(b.t_break)
            k = np.flatnonzero(tb >= 0)
            k = k[np.argsort(tb[k], kind="stable")]
            for name, val in (("bond", k), ("time", tb[k]), ("mode", np.asarray(b.mode)[k])):
                d = self.f[f"bonds/breaks/{name}"]
                d.resize(len(k), axis=0)
                d[:] = val
        self.frames += 1
        self.f.flush()
        if self.frames & (self.frames - 1) == 0:
            write_xdmf(self.path, self.f)

    def close(self, status="finished", message=""):
        if self.f:
            self.f.attrs["status"] = status
            self.f.attrs["message"] = message
            if self.frames:
                write_xdmf(self.path, self.f)
            self.f.close()
            self.f = None


SOLID_FIELDS = (("x", lambda n: (n, 2)), ("v", lambda n: (n, 2)), ("omega", lambda n: (n,)),
                ("theta", lambda n: (n,)))
BOND_FORCES = ("fn", "fs", "m")


def _slab(h5name, path, k, n, ncomp=None, comp=None, total=None):
    """An XDMF hyperslab DataItem selecting frame k (and component ``comp``)."""
    if ncomp is None:
        sel = f"{k} 0 1 1 1 {n}"
        dims = f"{total} {n}"
        out = f"1 {n}"
    else:
        sel = f"{k} 0 {comp} 1 1 1 1 {n} 1"
        dims = f"{total} {n} {ncomp}"
        out = f"1 {n} 1"
    return (f'<DataItem ItemType="HyperSlab" Dimensions="{out}" Type="HyperSlab">'
            f'<DataItem Dimensions="{3} {len(dims.split())}" Format="XML">{sel}</DataItem>'
            f'<DataItem Dimensions="{dims}" NumberType="Float" Precision="4" Format="HDF">'
            f'{h5name}:{path}</DataItem></DataItem>')


def _geometry_xy(h5name, path, k, n, total):
    sel = f"{k} 0 0 1 1 1 1 {n} 2"
    return (f'<Geometry GeometryType="XY"><DataItem ItemType="HyperSlab" Dimensions="{n} 2" '
            f'Type="HyperSlab"><DataItem Dimensions="3 3" Format="XML">{sel}</DataItem>'
            f'<DataItem Dimensions="{total} {n} 2" NumberType="Float" Precision="4" '
            f'Format="HDF">{h5name}:{path}</DataItem></DataItem></Geometry>')


def write_xdmf(h5path, f=None):
    """(Re)write ``<run>.xdmf`` next to ``<run>.h5``: a temporal collection of point grids
    for the fluid (with vx, vy, rho, p, h) and one for the boundary (with p)."""
    own = f is None
    f = h5py.File(h5path, "r") if own else f
    try:
        times = f["time"][:]
        T = len(times)
        name = os.path.basename(h5path)
        parts = ['<?xml version="1.0" ?>', '<Xdmf Version="2.0">', "<Domain>"]
        for phase, scalars in (("fluid", ("rho", "p", "h")), ("solid", ("omega", "theta"))):
            if f"{phase}/x" not in f:
                continue
            nf = f[f"{phase}/x"].shape[1]
            parts.append(f'<Grid Name="{phase}" GridType="Collection" CollectionType="Temporal">')
            for k, t in enumerate(times):
                parts.append(f'<Grid Name="{phase}_{k}" GridType="Uniform">'
                             f'<Time Value="{t:.9g}"/>')
                parts.append(f'<Topology TopologyType="Polyvertex" NumberOfElements="{nf}"/>')
                parts.append(_geometry_xy(name, f"/{phase}/x", k, nf, T))
                for c, lab in enumerate(("vx", "vy")):
                    parts.append(f'<Attribute Name="{lab}" AttributeType="Scalar" Center="Node">'
                                 + _slab(name, f"/{phase}/v", k, nf, 2, c, T) + "</Attribute>")
                for q in [q for q in scalars + ("eps",) if f"{phase}/{q}" in f]:
                    parts.append(f'<Attribute Name="{q}" AttributeType="Scalar" Center="Node">'
                                 + _slab(name, f"/{phase}/{q}", k, nf, total=T) + "</Attribute>")
                if phase == "solid":
                    parts.append('<Attribute Name="radius" AttributeType="Scalar" Center="Node">'
                                 f'<DataItem Dimensions="{nf}" NumberType="Float" Precision="4" '
                                 f'Format="HDF">{name}:/solid/radius</DataItem></Attribute>')
                parts.append("</Grid>")
            parts.append("</Grid>")
        if "boundary" in f:
            nb = f["boundary/x"].shape[0]
            parts.append('<Grid Name="boundary" GridType="Collection" '
                         'CollectionType="Temporal">')
            for k, t in enumerate(times):
                parts.append(f'<Grid Name="boundary_{k}" GridType="Uniform">'
                             f'<Time Value="{t:.9g}"/>')
                parts.append(f'<Topology TopologyType="Polyvertex" NumberOfElements="{nb}"/>')
                parts.append(f'<Geometry GeometryType="XY"><DataItem Dimensions="{nb} 2" '
                             f'NumberType="Float" Precision="4" Format="HDF">{name}:/boundary/x'
                             f'</DataItem></Geometry>')
                parts.append('<Attribute Name="p" AttributeType="Scalar" Center="Node">'
                             + _slab(name, "/boundary/p", k, nb, total=T) + "</Attribute>")
                parts.append("</Grid>")
            parts.append("</Grid>")
        parts += ["</Domain>", "</Xdmf>"]
        tmp = os.path.splitext(h5path)[0] + ".xdmf"
        with open(tmp + ".tmp", "w") as fh:
            fh.write("\n".join(parts))
        os.replace(tmp + ".tmp", tmp)
    finally:
        if own:
            f.close()


@dataclass
class Run:
    """A run read back from disk: arrays per phase (time first) and the stored metadata."""

    time: np.ndarray
    step: np.ndarray
    fluid: dict
    boundary: dict
    solid: dict
    bonds: dict
    breaks: dict
    walls: dict
    scene: dict
    physics: dict
    params: dict
    status: str
    message: str
    fsi: dict | None = None
    fpi: dict | None = None
    probes: dict | None = None     # name -> (S, k) after every step, and 'time' (S,)

    @property
    def frames(self) -> int:
        return len(self.time)


def read(path) -> Run:
    """Read a file written by :class:`Writer` into numpy arrays."""
    with h5py.File(path, "r") as f:
        fluid = {k: f[f"fluid/{k}"][:] for k in f["fluid"]} if "fluid" in f else {}
        boundary = {k: f[f"boundary/{k}"][:] for k in f["boundary"]} if "boundary" in f else {}
        solid = {k: f[f"solid/{k}"][:] for k in f["solid"]} if "solid" in f else {}
        bonds = ({k: f[f"bonds/{k}"][:] for k in f["bonds"] if k != "breaks"}
                 if "bonds" in f else {})
        breaks = ({k: f[f"bonds/breaks/{k}"][:] for k in f["bonds/breaks"]}
                  if "bonds/breaks" in f else {})
        a = f.attrs
        return Run(time=f["time"][:], step=f["step"][:], fluid=fluid, boundary=boundary,
                   solid=solid, bonds=bonds, breaks=breaks,
                   walls={k: f[f"walls/{k}"][:] for k in f["walls"]} if "walls" in f else {},
                   scene=json.loads(a["scene"]), physics=json.loads(a["physics"]),
                   params=json.loads(a["params"]), status=str(a.get("status", "")),
                   message=str(a.get("message", "")),
                   fsi={k: f[f"fsi/{k}"][:] for k in f["fsi"]} if "fsi" in f else {},
                   fpi={k: f[f"fpi/{k}"][:] for k in f["fpi"]} if "fpi" in f else {},
                   probes=({k: f[f"probes/{k}"][:] for k in f["probes"]}
                           if "probes" in f else {}))
