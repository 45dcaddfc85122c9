"""The packed grain bed scene (fpsi_jax.cases.grain_bed): its packings and its start."""
import math

import numpy as np
import pytest

from fpsi_jax import cases
from fpsi_jax.cases.grain_bed import hex_bed, random_bed


def test_hex_bed_has_the_layers_asked_for():
    """0.05 m at d = 2.4 mm: rows of 20 and 19 touching discs, √3/2 d apart."""
    x = hex_bed(0.05, 0.0024, 4)
    rows = np.unique(np.round(x[:, 1], 12))
    assert x.shape[0] == 78 and rows.size == 4
    np.testing.assert_allclose(np.diff(rows), math.sqrt(3) / 2 * 0.0024, rtol=1e-9)
    d = np.linalg.norm(x[:, None] - x[None], axis=-1) + np.eye(len(x))
    assert d.min() == pytest.approx(0.0024, rel=1e-12)


def test_random_bed_settles_without_overlap_on_the_floor():
    x = random_bed(0.02, 0.0024, 12, seed=3, t_settle=0.3)
    d = np.linalg.norm(x[:, None] - x[None], axis=-1) + np.eye(len(x))
    assert d.min() > 0.0024 * 0.99                      # soft contacts: < 1 % overlap
    assert x[:, 1].min() == pytest.approx(0.0012, rel=0.02)   # the lowest disc on the floor
    assert (x[:, 0] > 0.0012 * 0.98).all() and (x[:, 0] < 0.02 - 0.0012 * 0.98).all()


def test_bed_starts_hydrostatic_with_pore_fluid_of_its_voidage():
    """Fluid particles among the grains carry ε ρ0 Δx² (ε = 1 − Σ V_p W ≈ 0.1 inside the
    bed; next to the side walls the kernel sum sees only half a bed), free water ρ0 Δx²."""
    sc = cases.build("grain_bed")
    dx = sc.builder_kwargs["dx"]
    eps = sc.fluid.mass / (1000.0 * dx * dx)
    x = sc.fluid.x
    in_bed = (x[:, 1] > 0.003) & (x[:, 1] < 0.006) & (x[:, 0] > 0.006) & (x[:, 0] < 0.044)
    assert eps[in_bed].max() < 0.2
    assert eps[sc.fluid.x[:, 1] > 0.03].min() == pytest.approx(1.0, rel=1e-12)
    assert sc.options["eps_floor"] == 0.0 and sc.options["voidage"] == "area"
