"""`fpsi validate` solid cases (fast versions) against their analytic references."""
import pytest

from fpsi_jax.cases import validate


def test_collision_restitution_and_duration():
    """β ∈ {0, 0.1, 0.3}: e within 1 %, contact time within 2 % of the analytic values."""
    recs = validate.run(["collision"])
    assert len(recs) == 6
    for r in recs:
        assert r.passed, (r.quantity, r.rel_error)
    betas = [r.params["beta"] for r in recs]
    assert sorted(set(betas)) == [0.0, 0.1, 0.3]


def test_rolling_ends_at_two_thirds():
    (r,) = validate.run(["rolling"])
    assert r.reference == pytest.approx(2 / 3)
    assert r.passed, r.rel_error
    # it really rolls: ω R matches v at the end
    assert r.params["omega_R_over_v0"] == pytest.approx(r.value, rel=0.01)


def test_itasca_beam_within_0p2_percent():
    (r,) = validate.run(["itasca_beam"])
    assert r.params["reference_in"] == pytest.approx(0.082893, rel=1e-4)
    assert r.passed, r.rel_error
    assert r.params["last_10pct_change"] < 1e-4          # static state reached


def test_bond_breaks_in_tension_at_sigma_c():
    (r,) = validate.run(["bond_tension"])
    assert r.params["mode"] == "tension"
    assert r.passed, r.rel_error


@pytest.fixture(scope="module")
def cantilever_quick():
    return validate.run(["cantilever"], quick=True)[0]


def test_cantilever_quick_builds_the_nominal_span(cantilever_quick):
    """d = 2.5 mm (79.375/2.5 = 31.75 is no whole number of discs): the clamp column on
    x = 0, the tip column on x = L, settled."""
    r = cantilever_quick
    assert r.params["as_built_span"] == pytest.approx(0.079375, rel=1e-12)
    assert r.params["last_10pct_change"] < 2e-3


def test_cantilever_quick_within_1_percent_of_euler_bernoulli(cantilever_quick):
    """+0.48 % measured; the shear part PL/(κGA) is +0.32 % of it."""
    assert cantilever_quick.passed, cantilever_quick.rel_error
    assert abs(cantilever_quick.params["error_vs_reference_with_shear"]) < 0.01


def test_cantilever_frequency_quick():
    """d = 2.5 mm: f1 within 2 % of Euler–Bernoulli for the nominal span (−0.54 %)."""
    (r,) = validate.run(["cantilever_frequency"], quick=True)
    assert r.passed, r.rel_error
    assert r.params["periods"] >= 4


@pytest.mark.slow
def test_cantilever_frequency_full():
    (r,) = validate.run(["cantilever_frequency"])
    assert r.passed, r.rel_error
