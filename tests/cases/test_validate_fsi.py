"""Fast versions of the fluid–structure validation cases (the full ones run in
experiments/: hydrostatic_plate.py, elastic_gate.py)."""
import numpy as np
import pytest

from fpsi_jax import cases
from fpsi_jax.cases import CASES
from fpsi_jax.cases.elastic_gate import GATE_COARSE
from fpsi_jax.cases.hydrostatic_plate import plate_deflection
from fpsi_jax.run import io
from fpsi_jax.run.driver import simulate


def test_plate_reference_is_K44():
    """K6.3.3's numbers: 1.2915 mm with 1/384 (K prints 1.2895 mm with the rounded 0.0026)."""
    w = plate_deflection(0.07875, 0.005, 0.1575005, 10e6, 0.4)
    assert w == pytest.approx(1.2915e-3, rel=2e-4)
    assert w * 0.0026 * 384 == pytest.approx(1.2895e-3, rel=5e-4)


def test_hydrostatic_plate_quick_within_5_percent():
    """Coarse plate (fluid 3.5 mm, 2 rows of 2.5 mm discs): the settled midpoint deflection
    within 5 % of K44 + Timoshenko shear for the as-built span and water."""
    rec, = CASES["hydrostatic_plate"](quick=True)
    assert rec.passed, rec


def test_gate_run_writes_the_coupling_and_reads_back(tmp_path):
    sc = cases.build("elastic_gate", **GATE_COARSE)
    out = tmp_path / "gate.h5"
    res = simulate(sc, t_end=0.0012, output=str(out), every=0.0006, progress=False)
    run = io.read(out)
    assert run.fsi["idx"].shape == (sc.solid.n,)
    assert run.fsi["force"].shape == (run.frames, sc.solid.n, 2)
    np.testing.assert_allclose(run.fsi["force"][-1], np.asarray(res.state.fsi.force), rtol=1e-6)
    # the water pushes the gate downstream
    assert run.fsi["force"][-1][:, 0].sum() > 0


def test_elastic_gate_quick_lies_in_the_published_spread():
    """Coarse gate (fluid 3.5 mm, 2 columns of 2.5 mm discs, defaults): the peak tip ux and
    its time lie in the band spanned by the experiment (46 mm at 0.16 s) and the later codes
    (Yang 2012 35.5 mm at 0.10 s … Khayyer 2018 42.7 mm at 0.115 s). The case's target
    (peak within 15 %, time within 0.03 s) is checked at full resolution by
    experiments/elastic_gate.py, and is not met on the time (docs/validation.md)."""
    recs = CASES["elastic_gate"](quick=True)
    peak, when = recs[0].value, recs[1].value
    assert 0.033 <= peak <= 0.050, recs[0]
    assert 0.09 <= when <= 0.17, recs[1]
