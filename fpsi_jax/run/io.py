"""Output: HDF5 frames (h5py) with an XDMF sidecar ParaView opens, and run checkpoints.

Layout of a file::

    /time (T,)  /step (T,)                     one entry per complete frame (the frame count)
    /frames/000042/                            frame 42, every array plain (n, ...):
        fluid/{x (n,2), v (n,3), rho, p, h}      v with a zero z, so viewers see a vector
        fluid/eps (n,)                           fluid voidage, with grains (fpi)
        fluid/excluded (n,) uint8                1: left through an open side (scenes with one)
        boundary/p (nb,)
        solid/{x (n,2), v (n,3), omega, theta}   solid/excluded as the fluid's
        solid/fluid_force (n,3), solid/fluid_p (n,)  the fluid's force on each disc and the
                                                 structure discs' pressure (fsi, fpi)
        bonds/{intact (b,) uint8, fn, fs, m}
        fpi/eps_p (g,)
    /boundary/{x (nb,2), rho (nb,)}  /solid/{radius, fixed}  /bonds/{i, j, ij (b,2)}
    /bonds/breaks/{bond, time, mode}            every break so far (mode 1 tension, 2 shear,
                                                3 a disc left the domain)
    /walls/{a, b (w,2), points (2w,2), segments (w,2)}
    /fsi/idx (s,)  /fpi/idx (g,)                structure discs and grains (disc indices)
    /probes/{time (S,), <name> (S,k)}           every probe after every step (run.probes)
    /checkpoint/…                               the whole State of the last frame (resume)
    attrs: scene, physics, params, run (JSON), fpsi_version, status, message

A frame is written whole or not at all: its group is written under a temporary name and
moved into place, the checkpoint is saved and the file flushed, then /time and /step grow
by one and the file is flushed again, and last the sidecar gets the frame's block;
:func:`read` only counts frames listed in /time and checks that each is complete. The
sidecar lists the same frames: each frame appends one block in a single write at the end
of the file (O(1) per frame), so a run killed at any moment leaves it matching the file,
or, for a kill during that one write, one frame behind it (never ahead: every frame it
lists is in /time); ``--resume`` rewrites it whole.

Plain datasets only (no HyperSlab items: ParaView's default Xdmf3 reader crashes on
hyperslab geometry and drops hyperslab attributes), positions as XY geometry, velocities
and forces as Vector attributes, bonds and walls as two-node Polyline cells.

The writer holds the file without HDF5's lock (``locking=False``) and flushes after every
frame, so h5py, ParaView or VTK can open it to watch a run between frames; another run
that wants the same file is refused by an advisory lock on ``<file>.lock``
(:func:`check_output`), before anything is opened for writing.

Status values: ``running``, ``finished``, ``interrupted`` (SIGINT/SIGTERM: stopped at the
end of a chunk), ``unstable`` (SimulationError, message says where), ``failed`` (a write
error such as a full disk; the frames before it are intact).
"""
from __future__ import annotations

import errno
import fcntl
import json
import os
import tempfile
from dataclasses import dataclass

import h5py
import jax
import numpy as np

from .. import __version__
from ..model.errors import ParameterError
from ..physics import eos

FLUID_FIELDS = ("x", "v", "rho", "p", "h")
SUFFIXES = (".h5", ".hdf5")
BREAK_FIELDS = (("bond", np.int32), ("time", np.float64), ("mode", np.int32))


class OutputError(RuntimeError):
    """Writing a frame failed (e.g. the disk is full); the file keeps every earlier frame."""


def sidecar(path) -> str:
    """The XDMF file next to ``path``."""
    return os.path.splitext(str(path))[0] + ".xdmf"


def _writable_folder(path: str) -> str | None:
    """None if a file can be created in ``path``'s folder (the folder may not exist yet:
    its nearest existing ancestor is probed with a temporary file, removed at once), else
    why not."""
    folder = os.path.dirname(os.path.abspath(path))
    probe = folder
    while not os.path.exists(probe):
        probe = os.path.dirname(probe)
    if not os.path.isdir(probe):
        return f"{probe} is a file, not a folder"
    try:
        with tempfile.TemporaryFile(dir=probe):
            pass
    except OSError as e:
        return f"cannot write in {probe}: {e.strerror or e}"
    return None


def ours(path) -> bool:
    """The file at ``path`` is an HDF5 file written by fpsi-jax."""
    try:
        with h5py.File(path, "r", locking=False) as f:
            return "fpsi_version" in f.attrs
    except (OSError, ValueError):
        return False


def check_output(path, overwrite: bool = False, kind: str = "h5") -> None:
    """Refuse an output path before anything is set up (ParameterError, one line).

    kind 'h5': a run's HDF5 file (``.h5``/``.hdf5``, distinct from its ``.xdmf`` sidecar;
    an existing file only with ``overwrite`` and only if fpsi-jax wrote it; not a file
    another run is writing). Other kinds ('json', 'png', 'csv', 'folder'): the path's
    folder must be writable and the path not an existing folder (a folder for 'folder')."""
    path = str(path)
    if kind == "h5":
        if not path.lower().endswith(SUFFIXES):
            raise ParameterError(f"--out = {path!r} must name an .h5 or .hdf5 file (the .xdmf "
                                 "sidecar is written beside it)")
    if kind == "folder":
        if os.path.exists(path) and not os.path.isdir(path):
            raise ParameterError(f"--out = {path!r} is a file, not a folder")
        why = _writable_folder(os.path.join(path, "x"))
    else:
        if os.path.isdir(path):
            raise ParameterError(f"{path!r} is a folder; name a file")
        why = _writable_folder(path)
    if why:
        raise ParameterError(f"output {path!r} cannot be written: {why}")
    if kind != "h5":
        return
    if busy(path):
        raise ParameterError(f"--out = {path!r} is being written by another run "
                             f"({path}.lock is held); choose another file")
    if os.path.exists(path):
        if not ours(path):
            raise ParameterError(f"--out = {path!r} exists and was not written by fpsi-jax; "
                                 "it is never overwritten")
        if not overwrite:
            raise ParameterError(f"--out = {path!r} exists; pass --overwrite to replace it "
                                 "(or --resume to continue it)")


def _lock_path(path) -> str:
    return str(path) + ".lock"


def busy(path) -> bool:
    """Another process holds the run lock of ``path``."""
    lock = _lock_path(path)
    if not os.path.exists(lock):
        return False
    try:
        fd = os.open(lock, os.O_RDWR)
    except OSError:
        return False
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        fcntl.flock(fd, fcntl.LOCK_UN)
        return False
    except OSError:
        return True
    finally:
        os.close(fd)


class RunLock:
    """An advisory lock on ``<file>.lock`` held while a run writes ``file``."""

    def __init__(self, path):
        self.path = _lock_path(path)
        os.makedirs(os.path.dirname(os.path.abspath(self.path)) or ".", exist_ok=True)
        self.fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(self.fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(self.fd)
            self.fd = None
            raise ParameterError(f"{path!r} is being written by another run") from None

    def release(self):
        if self.fd is not None:
            try:
                os.remove(self.path)
            except OSError:
                pass
            fcntl.flock(self.fd, fcntl.LOCK_UN)
            os.close(self.fd)
            self.fd = None


def _v3(v):
    """(n, 2) → (n, 3) with a zero z (what viewers draw as a vector)."""
    v = np.asarray(v)
    return np.concatenate([v, np.zeros(v.shape[:-1] + (1,), v.dtype)], axis=-1)


def frame_name(k: int) -> str:
    return f"frames/{k:06d}"


class Writer:
    """Append frames of a run to an HDF5 file, keep its XDMF sidecar and the run's
    checkpoint up to date. ``resume=True`` continues an existing file after its last
    complete frame (see :func:`load_checkpoint`)."""

    def __init__(self, path, scene, phys, params, probes=(), run_info=None, resume=False):
        self.path = str(path)
        self.lock = RunLock(self.path)
        try:
            self._open(scene, phys, params, probes, run_info, resume)
        except BaseException:
            self.lock.release()
            raise

    def _open(self, scene, phys, params, probes, run_info, resume):
        self.n_fluid, self.n_boundary = phys.n_fluid, phys.n_boundary
        self.n_solid, self.n_bonds = phys.n_solid, phys.n_bonds
        self.n_structure = phys.n_structure if phys.has_fsi else 0
        self.n_grain = phys.n_grain if phys.has_fpi else 0
        self.sph_params = params.sph
        self.probes = list(probes or ())
        self.xdmf = sidecar(self.path)
        if resume:
            self.f = h5py.File(self.path, "a", locking=False)
            self.frames = len(self.f["time"])
            for k in list(self.f["frames"]):
                if k.startswith("tmp") or int(k) >= self.frames:
                    del self.f[f"frames/{k}"]          # an incomplete frame of the stop
            self.f.attrs["status"] = "running"
            self.f.attrs["physics"] = phys.to_json()
            self.f.flush()
            write_xdmf(self.path, self.f)
            return
        self.f = h5py.File(self.path, "w", locking=False)
        a = self.f.attrs
        a["scene"] = scene.to_json()
        a["physics"] = phys.to_json()
        a["params"] = json.dumps(params.to_json())
        a["run"] = json.dumps(run_info or {}, default=str)
        a["fpsi_version"] = __version__
        a["status"] = "running"
        a["message"] = ""
        for name, dt in (("time", np.float64), ("step", np.int64)):
            self.f.create_dataset(name, shape=(0,), maxshape=(None,), dtype=dt, chunks=(1024,))
        self.f.create_group("frames")
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
        if self.n_boundary:
            self.f["boundary/x"] = np.asarray(scene.boundary.x, np.float32)
            self.f["boundary/rho"] = np.asarray(scene.boundary.rho, np.float32)
        if self.n_solid:
            self.f["solid/radius"] = np.asarray(scene.solid.radius, np.float32)
            self.f["solid/fixed"] = np.asarray(scene.solid.fixed, np.uint8)
        if self.n_bonds:
            i, j = np.asarray(scene.bonds.i, np.int32), np.asarray(scene.bonds.j, np.int32)
            self.f["bonds/i"], self.f["bonds/j"] = i, j
            self.f["bonds/ij"] = np.stack([i, j], axis=1)
            for k, dt in BREAK_FIELDS:
                self.f.create_dataset(f"bonds/breaks/{k}", shape=(0,), maxshape=(None,),
                                      dtype=dt, chunks=(256,))
        if self.n_structure:
            self.f["fsi/idx"] = scene.solid.structure_indices()
        if self.n_grain:
            self.f["fpi/idx"] = scene.solid.grain_indices()
        if scene.walls is not None:
            a_, b_ = np.asarray(scene.walls.a, np.float32), np.asarray(scene.walls.b, np.float32)
            self.f["walls/a"], self.f["walls/b"] = a_, b_
            self.f["walls/points"] = np.stack([a_, b_], axis=1).reshape(-1, 2)
            self.f["walls/segments"] = np.arange(2 * len(a_), dtype=np.int32).reshape(-1, 2)
        self.frames = 0
        self.f.flush()
        write_xdmf(self.path, self.f)

    # --- one frame ---------------------------------------------------------------------
    def _frame_data(self, state) -> dict:
        data = {}
        if self.n_fluid:
            fl, sp = state.fluid, self.sph_params
            data.update({"fluid/x": fl.x, "fluid/v": _v3(fl.v), "fluid/rho": fl.rho,
                         "fluid/h": fl.h,
                         "fluid/p": eos.pressure(fl.rho, sp.rho0, sp.c0, sp.gamma)})
            if fl.t_out is not None:
                data["fluid/excluded"] = (np.asarray(fl.t_out) >= 0).astype(np.uint8)
        if self.n_boundary:
            data["boundary/p"] = state.boundary.p
        if self.n_solid:
            s = state.solid
            data.update({"solid/x": s.x, "solid/v": _v3(s.v), "solid/omega": s.omega,
                         "solid/theta": s.theta})
            if s.t_out is not None:
                data["solid/excluded"] = (np.asarray(s.t_out) >= 0).astype(np.uint8)
            if self.n_structure or self.n_grain:
                f = np.zeros((self.n_solid, 2), np.float32)
                p = np.zeros(self.n_solid, np.float32)
                if self.n_structure:
                    f[np.asarray(state.fsi.idx)] += np.asarray(state.fsi.force)
                    p[np.asarray(state.fsi.idx)] = np.asarray(state.fsi.p)
                if self.n_grain:
                    f[np.asarray(state.fpi.idx)] += np.asarray(state.fpi.force)
                data["solid/fluid_force"], data["solid/fluid_p"] = _v3(f), p
        if self.n_bonds:
            b = state.bonds
            data.update({"bonds/intact": np.asarray(b.intact, np.uint8), "bonds/fn": b.fn,
                         "bonds/fs": b.fs, "bonds/m": b.m})
        if self.n_grain:
            data.update({"fluid/eps": state.fpi.eps, "fpi/eps_p": state.fpi.eps_p})
        out = {}
        for k, v in data.items():
            v = np.asarray(v)
            if v.dtype.kind == "f":
                v = v.astype(np.float32)
                if not np.all(np.isfinite(v)):
                    raise ValueError(f"refusing to write non-finite {k} to {self.path}")
            out[k] = v
        return out

    def write_probes(self, times, values: dict):
        """Append the probe rows of one chunk (``values``: name → (n, k)); refuses
        non-finite values."""
        try:
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
        except OSError as e:
            raise OutputError(f"writing the probes to {self.path} failed: {e}") from e

    def set_physics(self, phys) -> None:
        """Record ``phys`` as the run's Physics (after its lists were regrown), so that a
        resume from a later checkpoint reallocates them as large (driver.grown_like)."""
        self.f.attrs["physics"] = phys.to_json()

    def write(self, state, checkpoint: bool = True):
        """Append one frame whole (and the checkpoint of ``state``); refuses non-finite data
        (the driver checks before calling); OutputError when the file cannot be written."""
        data = self._frame_data(state)
        k = self.frames
        try:
            tmp = f"frames/tmp{k:06d}"
            if tmp in self.f:
                del self.f[tmp]
            g = self.f.create_group(tmp)
            for name, v in data.items():
                g.create_dataset(name, data=v)
            self.f.move(tmp, frame_name(k))
            if self.n_bonds:
                self._breaks(state.bonds)
            if checkpoint:
                save_checkpoint(self.f, state, k)
            self.f.flush()
            for name, v in (("time", float(state.t)), ("step", int(state.step))):
                self.f[name].resize(k + 1, axis=0)
                self.f[name][k] = v
            self.f.flush()
            # the sidecar last: a kill can leave it one frame behind the file (for the
            # one write of its block; --resume rewrites it whole), never listing a frame
            # that /time does not
            append_xdmf(self.path, self.f, k, float(state.t))
        except OSError as e:
            raise OutputError(f"writing frame {k} to {self.path} failed: "
                              f"{os.strerror(e.errno) if e.errno else e}") from e
        self.frames += 1

    def _breaks(self, b):
        tb = np.asarray(b.t_break)
        k = np.flatnonzero(tb >= 0)
        k = k[np.argsort(tb[k], kind="stable")]
        for name, val in (("bond", k), ("time", tb[k]), ("mode", np.asarray(b.mode)[k])):
            d = self.f[f"bonds/breaks/{name}"]
            d.resize(len(k), axis=0)
            d[:] = val

    def close(self, status="finished", message=""):
        if self.f:
            try:
                self.f.attrs["status"] = status
                self.f.attrs["message"] = message
                self.f.close()
            except (OSError, RuntimeError):
                pass                      # a full disk: the frames so far stay readable
            self.f = None
        self.lock.release()


# --- checkpoints ---------------------------------------------------------------------------
def _leaves(state):
    return [(jax.tree_util.keystr(k), v) for k, v in
            jax.tree_util.tree_flatten_with_path(state)[0]]


def _key(name: str) -> str:
    return name.replace("/", "|")


def save_checkpoint(f, state, frame: int):
    """Every leaf of ``state`` into /checkpoint (overwritten in place; a dataset whose shape
    changed, e.g. a regrown neighbour list, is made again) and the neighbour lists' static
    sizes as attributes; ``frame`` is the frame it belongs to."""
    g = f.require_group("checkpoint")
    for name, v in _leaves(state):
        v = np.asarray(v)
        key = _key(name)
        if key in g and (g[key].shape != v.shape or g[key].dtype != v.dtype):
            del g[key]
        if key in g:
            g[key][...] = v
        else:
            g.create_dataset(key, data=v)
    for attr in ("nbrs", "solid_nbrs"):
        nb = getattr(state, attr)
        if nb is not None:
            g.attrs[f"{attr}.max_occupancy"] = int(nb.max_occupancy)
            g.attrs[f"{attr}.cell_list_capacity"] = int(nb.cell_list_capacity or 0)
    g.attrs["frame"] = frame


@dataclass
class Checkpoint:
    """The state of a stopped run at its last complete frame (:func:`load_checkpoint`)."""
    frame: int
    leaves: dict
    attrs: dict
    physics: dict
    run: dict
    status: str


def load_checkpoint(path) -> Checkpoint:
    """The checkpoint of ``path`` at its last complete frame. A frame whose group and
    checkpoint were written but whose /time entry was not (a kill in between) is completed
    first. ParameterError if the file has no usable checkpoint."""
    if not os.path.exists(path):
        raise ParameterError(f"--resume = {str(path)!r} does not exist")
    if not ours(path):
        raise ParameterError(f"--resume = {str(path)!r} is not a run written by fpsi-jax")
    if busy(path):
        raise ParameterError(f"--resume = {str(path)!r} is being written by another run")
    with h5py.File(path, "a", locking=False) as f:
        if "checkpoint" not in f:
            raise ParameterError(f"--resume = {str(path)!r} has no checkpoint to resume from")
        g = f["checkpoint"]
        frame, T = int(g.attrs["frame"]), len(f["time"])
        leaves = {k.replace("|", "/"): g[k][()] for k in g}
        if frame == T and frame_name(frame) in f:            # finish the frame of the kill
            t = float(leaves[".t"])
            for name, v in (("time", t), ("step", int(leaves[".step"]))):
                f[name].resize(T + 1, axis=0)
                f[name][T] = v
            f.flush()
            write_xdmf(path, f)
        elif frame != T - 1:
            raise ParameterError(f"--resume = {str(path)!r}: its checkpoint (frame {frame}) "
                                 f"does not match its last complete frame ({T - 1})")
        return Checkpoint(frame=frame, leaves=leaves, attrs=dict(g.attrs),
                          physics=json.loads(f.attrs["physics"]),
                          run=json.loads(f.attrs.get("run", "{}")),
                          status=str(f.attrs.get("status", "")))


#: state leaves that only size regrown neighbour lists or count rebuilds; a checkpoint
#: without them resumes with them at 0
_RUN_TALLIES = (".status.sph_need", ".status.dem_need", ".status.dem_rebuilds")
#: state leaves a checkpoint may lack, with the value that is always safe (None: the fresh
#: state's own): every disc's wall contacts are then evaluated until the DEM list's next
#: rebuild asks which discs are near a wall again
_SAFE_DEFAULTS = {".walls.near": None, ".walls.image_side": None, ".walls.n_near": 2 ** 30, ".status.dem_stale": False}


def restore(state, ck: Checkpoint):
    """``state`` (a fresh initial state of the same scene and Physics) with every leaf and
    the neighbour lists' static sizes of the checkpoint."""
    import dataclasses
    for attr in ("nbrs", "solid_nbrs"):
        nb = getattr(state, attr)
        if nb is not None and f"{attr}.max_occupancy" in ck.attrs:
            cap = int(ck.attrs[f"{attr}.cell_list_capacity"]) or nb.cell_list_capacity
            nb = dataclasses.replace(nb, max_occupancy=int(ck.attrs[f"{attr}.max_occupancy"]),
                                     cell_list_capacity=cap)
            state = state.replace(**{attr: nb})
    paths, treedef = jax.tree_util.tree_flatten_with_path(state)
    leaves = []
    for k, v in paths:
        name = jax.tree_util.keystr(k)
        if name not in ck.leaves and name in _RUN_TALLIES:
            leaves.append(v)          # a file written before these tallies: start at 0
            continue
        if name not in ck.leaves and name in _SAFE_DEFAULTS:
            safe = _SAFE_DEFAULTS[name]
            leaves.append(v if safe is None else jax.numpy.asarray(safe, np.asarray(v).dtype))
            continue
        if name not in ck.leaves:
            raise ParameterError(f"the checkpoint lacks {name}: the scene or options differ "
                                 "from the run that wrote it")
        saved = np.asarray(ck.leaves[name])
        want = np.asarray(v)
        if name in _RUN_TALLIES and saved.shape != want.shape:
            saved = np.resize(np.append(saved, np.zeros_like(want)), want.shape)  # fewer tallies
        if saved.dtype != want.dtype:
            raise ParameterError(f"checkpoint {name} is {saved.dtype}, the run {want.dtype}: "
                                 "the scene or options differ from the run that wrote it")
        leaves.append(jax.numpy.asarray(saved))
    return jax.tree_util.tree_unflatten(treedef, leaves)


def read_probes(path) -> tuple:
    """(times (S,), {name: (S, k)}) of the probes a run's file recorded (empty without any)."""
    with h5py.File(path, "r", locking=False) as f:
        if "probes" not in f:
            return np.zeros(0), {}
        g = f["probes"]
        return g["time"][:], {k: g[k][:] for k in g if k != "time"}


def truncate_probes(path, t_last: float):
    """Drop probe rows after ``t_last`` (written by a chunk whose frame was not)."""
    with h5py.File(path, "a", locking=False) as f:
        if "probes" not in f:
            return
        g = f["probes"]
        keep = int(np.searchsorted(g["time"][:], t_last * (1 + 1e-12) + 1e-15, side="right"))
        for name in g:
            g[name].resize(keep, axis=0)


# --- XDMF ------------------------------------------------------------------------------------
XDMF_HEAD = ('<?xml version="1.0" ?>\n<Xdmf Version="2.0">\n<Domain>\n'
             '<Grid Name="run" GridType="Collection" CollectionType="Temporal">\n')
XDMF_TAIL = "</Grid>\n</Domain>\n</Xdmf>\n"


def _item(h5name, path, dims, dtype="Float", precision=4):
    dims = " ".join(str(d) for d in dims)
    return (f'<DataItem Dimensions="{dims}" NumberType="{dtype}" Precision="{precision}" '
            f'Format="HDF">{h5name}:{path}</DataItem>')


def _attr(name, h5name, path, shape, center="Node"):
    kind = "Vector" if len(shape) == 2 and shape[1] == 3 else "Scalar"
    dtype, prec = ("UChar", 1) if name in ("intact", "excluded", "fixed") else ("Float", 4)
    return (f'<Attribute Name="{name}" AttributeType="{kind}" Center="{center}">'
            + _item(h5name, path, shape, dtype, prec) + "</Attribute>")


def frame_xdmf(f, h5name: str, k: int, t: float) -> str:
    """The sidecar block of frame ``k`` (a Spatial collection at time ``t``)."""
    fr = f"/{frame_name(k)}"
    grp = f[frame_name(k)]
    out = [f'<Grid Name="frame_{k}" GridType="Collection" CollectionType="Spatial">'
           f'<Time Value="{t:.9g}"/>']

    def points(name, geo_path, n, attrs, static=()):
        out.append(f'<Grid Name="{name}" GridType="Uniform">'
                   f'<Topology TopologyType="Polyvertex" NumberOfElements="{n}"/>'
                   f'<Geometry GeometryType="XY">{_item(h5name, geo_path, (n, 2))}</Geometry>')
        for a in attrs:
            if a in grp.get(name, {}):
                d = grp[f"{name}/{a}"]
                label = "velocity" if a == "v" else ("fluid_force" if a == "fluid_force" else a)
                out.append(_attr(label, h5name, f"{fr}/{name}/{a}", d.shape))
        for a in static:
            out.append(_attr(a, h5name, f"/{name}/{a}", f[f"{name}/{a}"].shape))
        out.append("</Grid>")

    if "fluid" in grp:
        n = grp["fluid/x"].shape[0]
        points("fluid", f"{fr}/fluid/x", n, ("v", "rho", "p", "h", "eps", "excluded"))
    if "boundary" in f and "boundary/x" in f:
        n = f["boundary/x"].shape[0]
        out.append(f'<Grid Name="boundary" GridType="Uniform">'
                   f'<Topology TopologyType="Polyvertex" NumberOfElements="{n}"/>'
                   f'<Geometry GeometryType="XY">{_item(h5name, "/boundary/x", (n, 2))}</Geometry>'
                   + _attr("p", h5name, f"{fr}/boundary/p", (n,)) + "</Grid>")
    if "solid" in grp:
        n = grp["solid/x"].shape[0]
        points("solid", f"{fr}/solid/x", n,
               ("v", "omega", "theta", "excluded", "fluid_force", "fluid_p"), ("radius", "fixed"))
        if "bonds" in grp:
            nb = grp["bonds/intact"].shape[0]
            out.append(f'<Grid Name="bonds" GridType="Uniform">'
                       f'<Topology TopologyType="Polyline" NodesPerElement="2" '
                       f'NumberOfElements="{nb}">'
                       + _item(h5name, "/bonds/ij", (nb, 2), "Int", 4) + "</Topology>"
                       f'<Geometry GeometryType="XY">{_item(h5name, f"{fr}/solid/x", (n, 2))}'
                       "</Geometry>")
            for a in ("intact", "fn", "fs", "m"):
                out.append(_attr(a, h5name, f"{fr}/bonds/{a}", (nb,), center="Cell"))
            out.append("</Grid>")
    if "walls" in f:
        w = f["walls/a"].shape[0]
        out.append(f'<Grid Name="walls" GridType="Uniform">'
                   f'<Topology TopologyType="Polyline" NodesPerElement="2" '
                   f'NumberOfElements="{w}">'
                   + _item(h5name, "/walls/segments", (w, 2), "Int", 4) + "</Topology>"
                   f'<Geometry GeometryType="XY">{_item(h5name, "/walls/points", (2 * w, 2))}'
                   "</Geometry></Grid>")
    out.append("</Grid>\n")
    return "".join(out)


def append_xdmf(h5path, f, k: int, t: float):
    """Append frame ``k``'s block to the sidecar with one write over its closing tags
    (the sidecar is (re)written whole when it does not end with them)."""
    path = sidecar(h5path)
    block = (frame_xdmf(f, os.path.basename(h5path), k, t) + XDMF_TAIL).encode()
    tail = XDMF_TAIL.encode()
    try:
        fd = os.open(path, os.O_RDWR)
    except FileNotFoundError:
        write_xdmf(h5path, f, extra=(k, t))
        return
    try:
        size = os.fstat(fd).st_size
        ok = size >= len(tail) and os.pread(fd, len(tail), size - len(tail)) == tail
        if ok:
            os.pwrite(fd, block, size - len(tail))
    finally:
        os.close(fd)
    if not ok:
        write_xdmf(h5path, f, extra=(k, t))


def write_xdmf(h5path, f=None, extra=None):
    """(Re)write ``<run>.xdmf`` whole from the file's complete frames (and ``extra`` = (k, t),
    a frame being added); atomically, through a temporary file."""
    own = f is None
    f = h5py.File(h5path, "r", locking=False) if own else f
    try:
        name = os.path.basename(h5path)
        frames = list(enumerate(f["time"][:]))
        if extra is not None:
            frames.append(extra)
        body = "".join(frame_xdmf(f, name, k, float(t)) for k, t in frames)
        tmp = sidecar(h5path) + ".tmp"
        with open(tmp, "w") as fh:
            fh.write(XDMF_HEAD + body + XDMF_TAIL)
        os.replace(tmp, sidecar(h5path))
    finally:
        if own:
            f.close()


# --- reading ---------------------------------------------------------------------------------
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
    run: dict | None = None        # how it was started (fpsi run's arguments)

    @property
    def frames(self) -> int:
        return len(self.time)


def _stack(f, T, phase, names):
    out = {}
    for name in names:
        arrs = [f[f"{frame_name(k)}/{phase}/{name}"][()] for k in range(T)]
        a = np.stack(arrs) if arrs else np.zeros((0,))
        if name in ("v", "fluid_force") and a.ndim == 3:
            a = a[..., :2]
        out[name] = a
    return out


def read(path) -> Run:
    """Read a file written by :class:`Writer` into numpy arrays (time first). Checks that
    every frame listed in /time is complete; ValueError otherwise."""
    with h5py.File(path, "r", locking=False) as f:
        time, step = f["time"][:], f["step"][:]
        T = len(time)
        if len(step) != T:
            raise ValueError(f"{path}: /time has {T} entries and /step {len(step)}")
        fields = {}
        for k in range(T):
            name = frame_name(k)
            if name not in f:
                raise ValueError(f"{path}: frame {k} is listed in /time but missing")
            g = f[name]
            here = {ph: sorted(g[ph]) for ph in g}
            if k == 0:
                fields = here
            elif here != fields:
                raise ValueError(f"{path}: frame {k} holds {here}, frame 0 {fields}")
        fluid = _stack(f, T, "fluid", fields.get("fluid", []))
        solid = _stack(f, T, "solid", fields.get("solid", []))
        for k in ("radius", "fixed"):
            if f"solid/{k}" in f:
                solid[k] = f[f"solid/{k}"][:]
        boundary = _stack(f, T, "boundary", fields.get("boundary", []))
        if "boundary/x" in f:
            boundary.update(x=f["boundary/x"][:], rho=f["boundary/rho"][:])
        bonds = _stack(f, T, "bonds", fields.get("bonds", []))
        if "bonds/i" in f:
            bonds.update(i=f["bonds/i"][:], j=f["bonds/j"][:])
        breaks = ({k: f[f"bonds/breaks/{k}"][:] for k in f["bonds/breaks"]}
                  if "bonds/breaks" in f else {})
        fsi = fpi = {}
        if "fsi/idx" in f:
            idx = f["fsi/idx"][:]
            fsi = {"idx": idx, "force": solid["fluid_force"][:, idx],
                   "p": solid["fluid_p"][:, idx]}
        if "fpi/idx" in f:
            idx = f["fpi/idx"][:]
            fpi = {"idx": idx, "force": solid["fluid_force"][:, idx],
                   **_stack(f, T, "fpi", ["eps_p"])}
        a = f.attrs
        return Run(time=time, step=step, fluid=fluid, boundary=boundary, solid=solid,
                   bonds=bonds, breaks=breaks,
                   walls={k: f[f"walls/{k}"][:] for k in ("a", "b")} if "walls" in f else {},
                   scene=json.loads(a["scene"]), physics=json.loads(a["physics"]),
                   params=json.loads(a["params"]), status=str(a.get("status", "")),
                   message=str(a.get("message", "")), fsi=fsi, fpi=fpi,
                   probes=({k: f[f"probes/{k}"][:] for k in f["probes"]}
                           if "probes" in f else {}),
                   run=json.loads(a.get("run", "{}")))
