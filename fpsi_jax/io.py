"""Output: HDF5 frames (h5py) with an XDMF sidecar so ParaView opens the run.

Layout of a file::

    /time (T,)  /step (T,)                     one entry per written frame
    /fluid/{x (T,n,2), v (T,n,2), rho (T,n), p (T,n), h (T,n)}
    /boundary/{x (n,2), rho (n,), p (T,n)}     positions are fixed, pressure may not be
    attrs: scene, physics, params (JSON), fpsi_version, status

Datasets are extendible along the time axis and the file is flushed after every frame, so
a run that stops (or crashes) leaves a valid file up to its last good frame. Nothing
non-finite is ever written: the driver checks a frame before handing it over.
"""
from __future__ import annotations

import json
import os
from dataclasses import dataclass

import h5py
import numpy as np

from . import __version__, sph

FLUID_FIELDS = ("x", "v", "rho", "p", "h")


class Writer:
    """Append frames of a run to an HDF5 file and keep its XDMF sidecar up to date."""

    def __init__(self, path, scene, phys, params):
        os.makedirs(os.path.dirname(os.path.abspath(path)) or ".", exist_ok=True)
        self.path = str(path)
        self.f = h5py.File(self.path, "w")
        self.f.attrs["scene"] = scene.to_json()
        self.f.attrs["physics"] = phys.to_json()
        self.f.attrs["params"] = json.dumps(params.to_json())
        self.f.attrs["fpsi_version"] = __version__
        self.f.attrs["status"] = "running"
        self.n_fluid, self.n_boundary = phys.n_fluid, phys.n_boundary
        self._make("time", (), np.float64)
        self._make("step", (), np.int64)
        nf = self.n_fluid
        for k, shape in (("x", (nf, 2)), ("v", (nf, 2)), ("rho", (nf,)), ("p", (nf,)),
                         ("h", (nf,))):
            self._make(f"fluid/{k}", shape, np.float32)
        if self.n_boundary:
            self.f.create_dataset("boundary/x", data=np.asarray(scene.boundary.x, np.float32))
            self.f.create_dataset("boundary/rho", data=np.asarray(scene.boundary.rho,
                                                                  np.float32))
            self._make("boundary/p", (self.n_boundary,), np.float32)
        self.frames = 0
        self.sph_params = params.sph

    def _make(self, name, shape, dtype):
        self.f.create_dataset(name, shape=(0,) + shape, maxshape=(None,) + shape,
                              dtype=dtype, chunks=(1,) + shape if shape else (1024,))

    def _append(self, name, value):
        d = self.f[name]
        d.resize(self.frames + 1, axis=0)
        d[self.frames] = value

    def write(self, state):
        """Append one frame; refuses non-finite data (the driver checks before calling)."""
        fl = state.fluid
        sp = self.sph_params
        data = {"x": fl.x, "v": fl.v, "rho": fl.rho, "h": fl.h,
                "p": sph.eos_pressure(fl.rho, sp.rho0, sp.c0, sp.gamma)}
        data = {k: np.asarray(v) for k, v in data.items()}
        for k, v in data.items():
            if not np.all(np.isfinite(v)):
                raise ValueError(f"refusing to write non-finite fluid.{k} to {self.path}")
        self._append("time", float(state.t))
        self._append("step", int(state.step))
        for k in FLUID_FIELDS:
            self._append(f"fluid/{k}", data[k])
        if self.n_boundary:
            self._append("boundary/p", np.asarray(state.boundary.p))
        self.frames += 1
        self.f.flush()
        write_xdmf(self.path, self.f)

    def close(self, status="finished", message=""):
        if self.f:
            self.f.attrs["status"] = status
            self.f.attrs["message"] = message
            self.f.close()
            self.f = None


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
        nf = f["fluid/x"].shape[1]
        parts = ['<?xml version="1.0" ?>', '<Xdmf Version="2.0">', "<Domain>"]
        parts.append('<Grid Name="fluid" GridType="Collection" CollectionType="Temporal">')
        for k, t in enumerate(times):
            parts.append(f'<Grid Name="fluid_{k}" GridType="Uniform"><Time Value="{t:.9g}"/>')
            parts.append(f'<Topology TopologyType="Polyvertex" NumberOfElements="{nf}"/>')
            parts.append(_geometry_xy(name, "/fluid/x", k, nf, T))
            for c, lab in enumerate(("vx", "vy")):
                parts.append(f'<Attribute Name="{lab}" AttributeType="Scalar" Center="Node">'
                             + _slab(name, "/fluid/v", k, nf, 2, c, T) + "</Attribute>")
            for q in ("rho", "p", "h"):
                parts.append(f'<Attribute Name="{q}" AttributeType="Scalar" Center="Node">'
                             + _slab(name, f"/fluid/{q}", k, nf, total=T) + "</Attribute>")
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
    scene: dict
    physics: dict
    params: dict
    status: str
    message: str

    @property
    def frames(self) -> int:
        return len(self.time)


def read(path) -> Run:
    """Read a file written by :class:`Writer` into numpy arrays."""
    with h5py.File(path, "r") as f:
        fluid = {k: f[f"fluid/{k}"][:] for k in f["fluid"]} if "fluid" in f else {}
        boundary = {k: f[f"boundary/{k}"][:] for k in f["boundary"]} if "boundary" in f else {}
        a = f.attrs
        return Run(time=f["time"][:], step=f["step"][:], fluid=fluid, boundary=boundary,
                   scene=json.loads(a["scene"]), physics=json.loads(a["physics"]),
                   params=json.loads(a["params"]), status=str(a.get("status", "")),
                   message=str(a.get("message", "")))
