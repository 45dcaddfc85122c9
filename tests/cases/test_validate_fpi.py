"""Fluid–particle validation cases, quick versions (the full ones run in experiments/)."""
import pytest

from fpsi_jax.cases import CASES


def test_terminal_velocity_quick_within_2_percent_of_the_drag_law_balance():
    """A 0.5 mm grain (ε_p ≈ 0.9996) settling in still fluid: its mean slip over the last
    two thirds of 0.15 s matches the root of (ρ_p − ρ_f) g = β/(1 − ε) s within 2 %."""
    rec, = CASES["terminal_velocity"](quick=True)
    assert rec.reference > 0.03 and rec.params["eps_p"] > 0.999
    assert rec.passed, rec


def test_neutrally_buoyant_grain_quick_stays_within_a_tenth_of_a_diameter():
    rec, = CASES["neutral_buoyancy"](quick=True)
    assert rec.passed, rec


def test_neutral_buoyancy_refuses_a_heavy_grain():
    with pytest.raises(Exception, match="rho_grain == rho_fluid"):
        CASES["neutral_buoyancy"](quick=True, overrides={"rho_grain": 1100.0})
