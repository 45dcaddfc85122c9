"""HDF5 + XDMF output (fpsi_jax.run.io): round trip, metadata, and a sidecar ParaView can
parse."""
import json
import os
import xml.etree.ElementTree as ET

import h5py
import numpy as np

from fpsi_jax.run import io
from fpsi_jax.run.driver import simulate


def test_round_trip_and_metadata(tmp_path, tiny_tank):
    out = tmp_path / "r.h5"
    res = simulate(tiny_tank, t_end=0.005, every=0.0025, output=str(out), progress=False)
    run = io.read(out)
    np.testing.assert_allclose(run.fluid["x"][-1], np.asarray(res.state.fluid.x), atol=1e-7)
    np.testing.assert_allclose(run.fluid["rho"][-1], np.asarray(res.state.fluid.rho),
                               rtol=1e-7)
    assert run.scene["name"] == "hydrostatic_tank"
    assert run.physics["n_fluid"] == tiny_tank.fluid.n
    assert run.params["sph.rho0"] == 1000.0
    with h5py.File(out) as f:
        assert f["fluid/x"].maxshape[0] is None          # extendible along time
        json.loads(f.attrs["scene"])


def test_xdmf_sidecar_points_at_existing_datasets(tmp_path, tiny_tank):
    out = tmp_path / "r.h5"
    simulate(tiny_tank, t_end=0.005, every=0.0025, output=str(out), progress=False)
    xdmf = tmp_path / "r.xdmf"
    assert xdmf.exists()
    root = ET.parse(xdmf).getroot()
    grids = root.findall("./Domain/Grid")
    assert [g.get("Name") for g in grids] == ["fluid", "boundary"]
    steps = grids[0].findall("./Grid")
    assert len(steps) >= 3
    times = [float(g.find("Time").get("Value")) for g in steps]
    assert times == sorted(times) and times[0] == 0.0
    with h5py.File(out) as f:
        for item in root.iter("DataItem"):
            if item.get("Format") == "HDF":
                fname, path = item.text.strip().split(":")
                assert fname == os.path.basename(out)
                assert path in f
                dims = tuple(int(d) for d in item.get("Dimensions").split())
                assert f[path].shape == dims
