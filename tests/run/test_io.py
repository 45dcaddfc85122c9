"""HDF5 + XDMF output (fpsi_jax.run.io): round trip, whole frames, a sidecar both XDMF
readers can open, outputs that are never lost."""
import json
import os
import xml.etree.ElementTree as ET

import h5py
import numpy as np
import pytest

from fpsi_jax.model.errors import ParameterError
from fpsi_jax.run import io
from fpsi_jax.run.driver import simulate


def test_round_trip_and_metadata(tmp_path, tiny_tank):
    out = tmp_path / "r.h5"
    res = simulate(tiny_tank, t_end=0.005, every=0.0025, output=str(out), progress=False)
    run = io.read(out)
    np.testing.assert_allclose(run.fluid["x"][-1], np.asarray(res.state.fluid.x), atol=1e-7)
    np.testing.assert_allclose(run.fluid["v"][-1], np.asarray(res.state.fluid.v), atol=1e-7)
    np.testing.assert_allclose(run.fluid["rho"][-1], np.asarray(res.state.fluid.rho),
                               rtol=1e-7)
    assert run.scene["name"] == "hydrostatic_tank"
    assert run.physics["n_fluid"] == tiny_tank.fluid.n
    assert run.params["sph.rho0"] == 1000.0
    assert run.status == "finished"
    with h5py.File(out) as f:
        assert f["time"].maxshape[0] is None          # extendible along time
        assert f["frames/000000/fluid/v"].shape == (tiny_tank.fluid.n, 3)   # a 3-vector
        json.loads(f.attrs["scene"])


def test_xdmf_sidecar_lists_every_frame_with_plain_datasets(tmp_path, tiny_tank):
    out = tmp_path / "r.h5"
    simulate(tiny_tank, t_end=0.005, every=0.0025, output=str(out), progress=False)
    root = ET.parse(tmp_path / "r.xdmf").getroot()
    run, = root.findall("./Domain/Grid")
    frames = run.findall("./Grid")
    assert len(frames) == io.read(out).frames >= 3
    times = [float(g.find("Time").get("Value")) for g in frames]
    assert times == sorted(times) and times[0] == 0.0
    assert [g.get("Name") for g in frames[0].findall("./Grid")] == ["fluid", "boundary"]
    assert not [i for i in root.iter("DataItem") if i.get("ItemType") == "HyperSlab"]
    with h5py.File(out) as f:
        for item in root.iter("DataItem"):
            fname, path = item.text.strip().split(":")
            assert fname == os.path.basename(out)
            dims = tuple(int(d) for d in item.get("Dimensions").split())
            assert f[path].shape == dims, path
    vel = frames[0].find("./Grid[@Name='fluid']/Attribute[@Name='velocity']")
    assert vel.get("AttributeType") == "Vector"


@pytest.fixture(scope="module")
def gate_file(tmp_path_factory):
    """A few frames of the coarse elastic gate: fluid, walls, bonded discs, FSI."""
    from fpsi_jax import cases
    from fpsi_jax.cases.elastic_gate import GATE_COARSE
    out = tmp_path_factory.mktemp("gate") / "gate.h5"
    sc = cases.build("elastic_gate", **GATE_COARSE)
    res = simulate(sc, t_end=0.003, every=0.001, output=str(out), progress=False)
    return out, sc, res


def test_coupled_run_writes_bonds_walls_and_the_fluid_force(gate_file):
    out, sc, res = gate_file
    run = io.read(out)
    assert run.fsi["idx"].shape == (sc.solid.n,)
    assert run.fsi["force"].shape == (run.frames, sc.solid.n, 2)
    np.testing.assert_allclose(run.fsi["force"][-1], np.asarray(res.state.fsi.force),
                               rtol=1e-6)
    assert run.bonds["intact"].shape == (run.frames, sc.bonds.n)
    assert run.walls["a"].shape == (sc.walls.n, 2)
    grids = ET.parse(str(out).replace(".h5", ".xdmf")).getroot().findall(
        "./Domain/Grid/Grid")[-1]
    assert [g.get("Name") for g in grids.findall("./Grid")] == [
        "fluid", "boundary", "solid", "bonds", "walls"]


def test_vtk_xdmf_reader_opens_the_sidecar(gate_file):
    """VTK's own XDMF reader (the Xdmf2 one ParaView also offers; the Xdmf3 readers are not
    in VTK's wheels) sees every frame, the velocity as a 3-vector and the bonds as cells."""
    pytest.importorskip("vtkmodules.vtkIOXdmf2")
    from vtkmodules.vtkCommonDataModel import vtkCompositeDataSet
    from vtkmodules.vtkCommonExecutionModel import vtkStreamingDemandDrivenPipeline
    from vtkmodules.vtkIOXdmf2 import vtkXdmfReader
    out, sc, res = gate_file
    rd = vtkXdmfReader()
    rd.SetFileName(str(out).replace(".h5", ".xdmf"))
    rd.UpdateInformation()
    steps = rd.GetOutputInformation(0).Get(vtkStreamingDemandDrivenPipeline.TIME_STEPS())
    assert len(steps) == io.read(out).frames
    rd.UpdateTimeStep(steps[-1])
    blocks = {}
    it = rd.GetOutputDataObject(0).NewIterator()
    it.InitTraversal()
    while not it.IsDoneWithTraversal():
        name = it.GetCurrentMetaData().Get(vtkCompositeDataSet.NAME()).split("[")[0]
        blocks[name] = it.GetCurrentDataObject()
        it.GoToNextItem()
    assert set(blocks) == {"fluid", "boundary", "solid", "bonds", "walls"}
    fluid = blocks["fluid"].GetPointData()
    assert fluid.GetArray("velocity").GetNumberOfComponents() == 3
    assert {fluid.GetArrayName(i) for i in range(fluid.GetNumberOfArrays())} >= {
        "velocity", "rho", "p", "h", "excluded"}
    x = np.array([blocks["fluid"].GetPoint(i)[:2] for i in range(3)])
    np.testing.assert_allclose(x, np.asarray(res.state.fluid.x)[:3], atol=1e-6)
    assert blocks["bonds"].GetNumberOfCells() == sc.bonds.n
    assert blocks["bonds"].GetCellData().GetArray("intact") is not None
    assert blocks["walls"].GetNumberOfCells() == sc.walls.n
    assert blocks["solid"].GetPointData().GetArray("fluid_force").GetNumberOfComponents() == 3


# --- outputs that are never lost ---------------------------------------------------------------
def test_output_paths_are_checked(tmp_path):
    with pytest.raises(ParameterError, match="must name an .h5"):
        io.check_output(tmp_path / "x.xdmf")
    (tmp_path / "file").write_text("not a folder")
    with pytest.raises(ParameterError, match="is a file, not a folder"):
        io.check_output(tmp_path / "file" / "x.h5")
    with pytest.raises(ParameterError, match="cannot be written"):
        io.check_output("/proc/x.h5")
    foreign = tmp_path / "theirs.h5"
    with h5py.File(foreign, "w") as f:
        f["a"] = 1
    for overwrite in (False, True):
        with pytest.raises(ParameterError, match="not written by fpsi-jax"):
            io.check_output(foreign, overwrite)
    with pytest.raises(ParameterError, match="is a folder"):
        io.check_output(tmp_path, kind="json")
    io.check_output(tmp_path / "new" / "deeper" / "x.h5")          # folders made later
    assert not (tmp_path / "new").exists()                          # nothing written


def test_an_existing_run_is_replaced_only_with_overwrite(tmp_path, tiny_tank):
    out = tmp_path / "r.h5"
    simulate(tiny_tank, t_end=0.0025, output=str(out), progress=False)
    size = out.stat().st_size
    with pytest.raises(ParameterError, match="exists; pass --overwrite"):
        simulate(tiny_tank, t_end=0.0025, output=str(out), progress=False)
    assert out.stat().st_size == size and io.read(out).status == "finished"
    simulate(tiny_tank, t_end=0.0025, output=str(out), progress=False, overwrite=True)


def test_read_refuses_a_frame_that_is_not_whole(tmp_path, tiny_tank):
    out = tmp_path / "r.h5"
    simulate(tiny_tank, t_end=0.005, every=0.0025, output=str(out), progress=False)
    with h5py.File(out, "a") as f:
        del f["frames/000001/fluid/rho"]
    with pytest.raises(ValueError, match="frame 1 holds"):
        io.read(out)
    with h5py.File(out, "a") as f:
        f["frames/000001/fluid/rho"] = f["frames/000000/fluid/rho"][()]
        for k in ("time", "step"):                                  # a frame never written
            f[k].resize(len(f[k]) + 1, axis=0)
    with pytest.raises(ValueError, match="missing"):
        io.read(out)


def test_a_full_disk_stops_the_run_with_the_frames_so_far(tmp_path, tiny_tank, monkeypatch):
    """ENOSPC while writing the third frame: OutputError, status 'failed', two whole frames,
    a sidecar that lists those two, no temporary files."""
    out = tmp_path / "r.h5"
    real = io.Writer.write
    calls = []

    def full(self, state, checkpoint=True):
        calls.append(1)
        if len(calls) == 3:
            raise io.OutputError(f"writing frame 2 to {out} failed: "
                                 f"{os.strerror(28)}")
        return real(self, state, checkpoint)

    monkeypatch.setattr(io.Writer, "write", full)
    with pytest.raises(io.OutputError, match="No space left"):
        simulate(tiny_tank, t_end=0.01, every=0.0025, output=str(out), progress=False)
    run = io.read(out)
    assert run.frames == 2 and run.status == "failed" and "No space" in run.message
    assert len(ET.parse(tmp_path / "r.xdmf").getroot().findall("./Domain/Grid/Grid")) == 2
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.h5", "r.xdmf"]


def test_an_oserror_inside_a_frame_write_becomes_an_output_error(tmp_path, tiny_tank,
                                                                 monkeypatch):
    out = tmp_path / "r.h5"
    real = h5py.Group.create_dataset
    n = []

    def enospc(self, *a, **kw):
        if "frames/tmp000001" in self.name:
            n.append(1)
            raise OSError(28, os.strerror(28))
        return real(self, *a, **kw)

    monkeypatch.setattr(h5py.Group, "create_dataset", enospc)
    with pytest.raises(io.OutputError, match="frame 1 .*No space left"):
        simulate(tiny_tank, t_end=0.005, every=0.0025, output=str(out), progress=False)
    monkeypatch.undo()
    assert n and io.read(out).frames == 1 and io.read(out).status == "failed"


def test_the_same_run_twice_gives_identical_files(tmp_path, tiny_tank):
    outs = [tmp_path / f"r{k}.h5" for k in (0, 1)]
    for out in outs:
        simulate(tiny_tank, t_end=0.005, every=0.0025, output=str(out), progress=False)
    with h5py.File(outs[0]) as a, h5py.File(outs[1]) as b:
        names = []
        a.visititems(lambda n, o: names.append(n) if isinstance(o, h5py.Dataset) else None)
        assert len(names) > 10
        for n in names:
            assert np.array_equal(a[n][()], b[n][()]), n


def test_resume_restores_contacts_and_bonds_bitwise(tmp_path):
    """A bonded strip (DEM contacts, bond state, their neighbour list) run to 40 chunks, and
    the same run stopped after 20 and resumed from its file: the same final frame, bit for
    bit (the file's checkpoint without the neighbour lists' need tallies, as older files
    have: they start again at 0)."""
    from fpsi_jax import cases
    sc = cases.build("cantilever", d=0.0025, variant="free")
    dt = float(simulate(sc, t_end=1e-4, progress=False).params.dt)
    every = 25 * dt
    whole, part = tmp_path / "whole.h5", tmp_path / "part.h5"
    simulate(sc, t_end=40 * every, every=every, output=str(whole), progress=False)
    simulate(sc, t_end=20 * every, every=every, output=str(part), progress=False)
    with h5py.File(part, "a") as f:     # as a file written before the lists' need tallies
        for name in io._RUN_TALLIES:
            del f["checkpoint"][name]
    res = simulate(sc, t_end=40 * every, every=every, resume=str(part), progress=False,
                   observe=lambda s: s.t)
    assert res.steps_run == 500 and res.n_steps == 1000
    # what this call recorded is its own 500 steps, at their times
    np.testing.assert_allclose(res.times, np.asarray(res.observations), rtol=1e-6)
    assert res.times[0] == pytest.approx(501 * dt)
    a, b = io.read(whole), io.read(part)
    assert a.frames == b.frames == 41
    for phase in ("solid", "bonds"):
        for k, v in getattr(a, phase).items():
            assert np.array_equal(v, getattr(b, phase)[k]), (phase, k)


def test_resume_without_the_discs_near_the_walls(tmp_path):
    """A file whose checkpoint lacks WallState.near and n_near (written before they
    existed) resumes with every disc's wall contacts evaluated until the DEM list's next
    build: a grain fired at a floor ends where the unbroken run ends (to round-off: the
    walls are evaluated, to zero, in the steps the discs near them are unknown)."""
    from fpsi_jax import cases
    sc = cases.build("wall_impact", t_end=2e-3)
    whole, part = tmp_path / "whole.h5", tmp_path / "part.h5"
    simulate(sc, t_end=2e-3, every=5e-4, output=str(whole), progress=False)
    simulate(sc, t_end=5e-4, every=5e-4, output=str(part), progress=False)
    with h5py.File(part, "a") as f:
        del f["checkpoint"][".walls.near"]
        del f["checkpoint"][".walls.n_near"]
    simulate(sc, t_end=2e-3, every=5e-4, resume=str(part), progress=False)
    a, b = io.read(whole), io.read(part)
    assert a.frames == b.frames == 5
    assert float(a.solid["v"][-1][0, 1]) > 0                         # it bounced
    for k in ("x", "v"):
        np.testing.assert_allclose(b.solid[k][-1], a.solid[k][-1], rtol=1e-12, atol=1e-15)
