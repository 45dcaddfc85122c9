"""Pressure of the fixed boundary particles extrapolated from the fluid (Adami, Hu & Adams
2012; fpsi_jax.physics.boundary), against the formula in plain Python; the density is taken
from the inverted EOS as the step takes it (solver/stages.py)."""
import math

import jax.numpy as jnp
import numpy as np
import pytest

from fpsi_jax.physics import boundary, eos

from .sph_reference import G, KERN, RTOL, SP, W, _a

pytestmark = pytest.mark.usefixtures("float64")  # conftest: x64 for this module only


# --- extrapolated boundary pressure (Adami et al. 2012) ----------------------------------
XB = [[-0.002, 0.003], [0.0025, 0.004], [0.0, -0.001], [0.004, -0.001], [0.5, 0.5]]
HB = [0.004, 0.0045, 0.0035, 0.004, 0.004]
RHOB = [1002.0, 1001.0, 1234.0, 987.0, 1000.0]   # boundary entries must not be used
PB = [150.0, 80.0, 9999.0, -777.0, 0.0]
NFB = 2
IDXB = [[0, 1, 3, 5], [0, 1, 2, 5], [5, 5, 5, 5]]   # rows: boundary 2, 3, 4 (4 is alone)


def _ref_pb(b, fluid, p, g=G, a_b=(0.0, 0.0)):
    num = den = 0.0
    gma = np.asarray(g, float) - np.asarray(a_b, float)
    for f in fluid:
        xbf = np.asarray(XB[b]) - np.asarray(XB[f])
        w = W(math.hypot(*xbf), 0.5 * (HB[b] + HB[f]))
        num += p[f] * w + float(gma @ xbf) * RHOB[f] * w
        den += w
    return max(num / den, 0.0) if den > 0 else 0.0


def _pb(p=PB, g=G, acc_b=None, idx=IDXB):
    """(P_b, ρ_b): the extrapolated pressure and, as the step takes it, ρ_b from the inverted
    EOS."""
    pb = boundary.extrapolated_pressure(
        NFB, KERN, _a(g), _a(XB), _a(HB), _a(RHOB), _a(p), jnp.asarray(idx),
        acc_b=None if acc_b is None else _a(acc_b))
    return pb, eos.density(pb, SP["rho0"], SP["c0"], SP["gamma"])


def test_extrapolated_boundary_pressure():
    pb, rhob = (np.asarray(a) for a in _pb())
    want = [_ref_pb(2, [0, 1], PB), _ref_pb(3, [0, 1], PB), 0.0]
    # the hydrostatic term really matters: the wall below the fluid sees more than Σ PW/ΣW
    no_g = _ref_pb(2, [0, 1], PB, g=(0.0, 0.0))
    assert want[0] > no_g > 0
    assert want[0] - no_g == pytest.approx(
        sum(9.81 * (XB[f][1] - XB[2][1]) * RHOB[f]
            * W(math.dist(XB[2], XB[f]), 0.5 * (HB[2] + HB[f])) for f in (0, 1))
        / sum(W(math.dist(XB[2], XB[f]), 0.5 * (HB[2] + HB[f])) for f in (0, 1)), rel=1e-12)
    np.testing.assert_allclose(pb, want, rtol=RTOL, atol=1e-12)
    np.testing.assert_allclose(rhob, [float(eos.density(jnp.float64(p), 1000.0, 20.0, 7.0))
                                      for p in want], rtol=1e-13)
    assert rhob[2] == 1000.0                  # no fluid neighbour: P = 0, ρ = ρ0


def test_extrapolated_boundary_pressure_wall_acceleration():
    """A wall accelerating with g feels no hydrostatic correction: (g − a_b) = 0."""
    acc_b = np.tile(G, (3, 1))
    pb = np.asarray(_pb(acc_b=acc_b)[0])
    want = [_ref_pb(b, [0, 1], PB, a_b=G) for b in (2, 3)]
    np.testing.assert_allclose(pb[:2], want, rtol=RTOL)
    np.testing.assert_allclose(pb[:2], [_ref_pb(b, [0, 1], PB, g=(0, 0)) for b in (2, 3)],
                               rtol=RTOL)


def test_extrapolated_boundary_pressure_clamped_at_zero():
    p_neg = [-3000.0, -2500.0, 0.0, 0.0, 0.0]
    pb, rhob = (np.asarray(a) for a in _pb(p=p_neg))
    raw = [sum(
        (p_neg[f] + float(G @ (np.asarray(XB[b]) - np.asarray(XB[f]))) * RHOB[f])
        * W(math.dist(XB[b], XB[f]), 0.5 * (HB[b] + HB[f])) for f in (0, 1)) for b in (2, 3)]
    assert all(r < 0 for r in raw)            # the unclamped Adami value is a suction
    np.testing.assert_array_equal(pb, 0.0)
    np.testing.assert_array_equal(rhob, 1000.0)


def test_extrapolated_boundary_pressure_padding_exact():
    a = [np.asarray(t) for t in _pb(idx=[[0, 1], [0, 1], [5, 5]])]
    b = [np.asarray(t) for t in _pb(idx=[[5, 0, 5, 5, 1, 3], [2, 5, 1, 0, 5, 5],
                                         [5, 5, 5, 5, 5, 5]])]
    for u, w in zip(a, b):
        np.testing.assert_allclose(u, w, rtol=1e-15, atol=0)
