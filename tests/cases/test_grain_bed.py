"""The packed grain bed scene (fpsi_jax.cases.grain_bed): its packings and its start."""
import math

import numpy as np
import pytest

from fpsi_jax import cases
from fpsi_jax.cases.grain_bed import hex_bed, random_bed, separate
from fpsi_jax.model.errors import ParameterError


def test_hex_bed_has_the_layers_asked_for():
    """0.05 m at d = 2.4 mm: rows of 20 and 19 touching discs, √3/2 d apart (the scene's
    0.0504 m = 21 d fills the width: rows of 21 and 20)."""
    x = hex_bed(0.05, 0.0024, 4)
    rows = np.unique(np.round(x[:, 1], 12))
    assert x.shape[0] == 78 and rows.size == 4
    np.testing.assert_allclose(np.diff(rows), math.sqrt(3) / 2 * 0.0024, rtol=1e-9)
    d = np.linalg.norm(x[:, None] - x[None], axis=-1) + np.eye(len(x))
    assert d.min() == pytest.approx(0.0024, rel=1e-12)
    assert hex_bed(0.0504, 0.0024, 4).shape[0] == 82


def test_random_bed_settles_without_overlap_on_the_floor():
    x = random_bed(0.02, 0.0024, 12, seed=3, t_settle=0.3)
    d = np.linalg.norm(x[:, None] - x[None], axis=-1) + np.eye(len(x))
    assert d.min() > 0.0024 * (1 - 1e-9)          # the soft settle's overlaps pushed apart
    assert x[:, 1].min() == pytest.approx(0.0012, rel=0.02)   # the lowest disc on the floor
    assert (x[:, 0] > 0.0012 * 0.98).all() and (x[:, 0] < 0.02 - 0.0012 * 0.98).all()


def test_random_bed_refuses_a_packing_not_at_rest():
    """0.1 s after the drop the discs are still falling: with no more time allowed the
    builder says so (one line: the seed, the fastest disc, the bound) instead of returning
    a bed that is not settled."""
    with pytest.raises(ParameterError, match=r"seed = 3: .* not at rest after 0.1 s .*v_rest"):
        random_bed(0.02, 0.0024, 12, seed=3, t_settle=0.1, t_max=0.1)


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


def test_separate_removes_the_soft_settles_overlaps_inside_the_walls():
    """Three discs overlapping by 0.5 % of d, one pressed into the left wall: after
    ``separate`` no pair overlaps by more than 1e-9 d and every disc is inside the box and
    above the floor (under the scene's 1e9 N/m contacts a 0.5 % overlap of a 2.4 mm disc
    stores ½ kn δ² = 72 mJ per unit thickness)."""
    d = 0.0024
    x = np.array([[0.0011, d / 2], [0.0011 + 0.995 * d, d / 2], [0.0023, d / 2 + 0.86 * d]])
    y = separate(x, d, 0.01)
    gap = np.linalg.norm(y[:, None] - y[None], axis=-1) + np.eye(3)
    assert gap.min() > d * (1 - 1e-9)
    assert (y[:, 0] >= d / 2).all() and (y[:, 0] <= 0.01 - d / 2).all()
    assert (y[:, 1] >= d / 2).all()
