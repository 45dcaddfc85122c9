"""`fpsi validate`: registered cases, records, analytic references from the parameters."""
import json

import pytest

from fpsi_jax import cli
from fpsi_jax.cases import validate
from fpsi_jax.cases.registry import Record

KEYS = {"case", "quantity", "value", "reference", "rel_error", "tolerance", "passed",
        "wall_s", "params"}


@pytest.fixture(scope="module")
def tank_records():
    return validate.run(["hydrostatic_tank"], quick=True)


def test_hydrostatic_tank_quick_pressure(tank_records):
    """Δx = 10 mm, 2 s: pressure vs ρ0 g (H − y) within 2 %."""
    assert len(tank_records) == 2
    p = tank_records[0]
    assert p.passed, p.rel_error
    assert p.params["quick"] and p.params["dx"] == 0.01
    assert tank_records[1].rel_error < 0.02      # regression guard on the residual velocity


def test_hydrostatic_tank_quick_residual_velocity(tank_records):
    """Δx = 10 mm, 2 s: max |v| at the end under 1 % of √(gH) (h = 1.5 Δx; 0.67 % measured)."""
    assert tank_records[1].passed, tank_records[1].rel_error


def test_reference_follows_overrides():
    """The analytic reference is computed from the overridden parameters."""
    r = validate.run(["hydrostatic_tank"], quick=True,
                     overrides={"depth": 0.1, "width": 0.1, "dx": 0.02, "t_end": 0.05})[0]
    assert r.params["depth"] == 0.1
    # rows below H − 3dx sit at y = 0.01, 0.03: mean of ρ0 g (H − y) = ρ0 g (0.1 − 0.02)
    assert r.reference == pytest.approx(1000 * 9.81 * (0.1 - 0.02), rel=0.02)


def test_json_records_have_the_documented_keys(tmp_path, monkeypatch, capsys):
    fake = [Record("hydrostatic_tank", "q", 1.0, 1.0, 0.0, 0.02, True, 0.1, {})]
    monkeypatch.setattr(validate, "run", lambda *a, **k: fake)
    out = tmp_path / "v.json"
    assert cli.main(["validate", "--quick", "--json", str(out)]) == 0
    recs = json.loads(out.read_text())
    assert set(recs[0]) == KEYS
    assert "PASS" in capsys.readouterr().out


@pytest.mark.xfail(strict=True, reason=(
    "dam-break front runs ahead of Koshizuka & Oka (1996): +14 % at T = 2.3 at dx = 10 mm "
    "(+13.8 % at 5 mm) against the 5 % target; see docs/validation.md"))
def test_dam_break_quick_front_within_5_percent():
    (r,) = validate.run(["dam_break"], quick=True)
    assert r.passed, r.rel_error


def test_dam_break_quick_front_is_measured():
    (r,) = validate.run(["dam_break"], quick=True)
    assert 0.0 <= r.rel_error < 0.3            # finite, same order as the data
    assert r.reference > 1.0 and r.params["steps"] > 100
