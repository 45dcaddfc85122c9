"""Material mappings of the bonds (fpsi_jax.build.materials: k42_mapping, lattice_mapping,
hexagonal_strength, shear_modulus) against numbers worked out by hand, and their refusals of
bad input."""
import math

import pytest

from fpsi_jax.build import hexagonal_strength, k42_mapping, lattice_mapping, shear_modulus
from fpsi_jax.model.errors import ParameterError


# K6.3.3's rubber: E = 10 MPa, ν = 0.33, discs d = 1.25 mm
E, NU, R = 10.0e6, 0.33, 0.000625
REL = 1e-12


def test_k42_mapping_numbers():
    """k̄_n = E/(2R) = 1e7/0.00125 = 8e9; G = E/2.66 = 3 759 398.50; k̄_s = G/(2R);
    k_n = λE, k_s = λG."""
    k = k42_mapping(E, NU, R)
    G = 3759398.4962406014
    assert shear_modulus(E, NU) == pytest.approx(G, rel=REL)
    assert k["bond_kn"] == pytest.approx(8.0e9, rel=REL)
    assert k["bond_ks"] == pytest.approx(3007518796.992481, rel=REL)
    assert k["kn"] == pytest.approx(1.0e7, rel=REL)
    assert k["ks"] == pytest.approx(G, rel=REL)
    k = k42_mapping(E, NU, R, lam=0.8)
    assert k["bond_kn"] == pytest.approx(8.0e9, rel=REL)    # k̄ does not depend on λ
    assert k["kn"] == pytest.approx(0.8e7, rel=REL) and k["ks"] == pytest.approx(0.8 * G)


def test_k42_plate_variant():
    """E' = E(1−ν)/((1+ν)(1−2ν)) = 6.7e6/0.4522 = 14 816 452.9; k_s = ½k_n, k̄_s = ½k̄_n."""
    k = k42_mapping(E, NU, R, plate=True)
    Ep = 14816452.896948252
    assert Ep == pytest.approx(E * 0.67 / (1.33 * 0.34), rel=REL)
    assert k["bond_kn"] == pytest.approx(Ep / 0.00125, rel=REL)
    assert k["bond_kn"] == pytest.approx(11853162317.558601, rel=REL)
    assert k["bond_ks"] == pytest.approx(0.5 * k["bond_kn"], rel=REL)
    assert k["kn"] == pytest.approx(Ep, rel=REL)
    assert k["ks"] == pytest.approx(0.5 * Ep, rel=REL)


@pytest.mark.parametrize("c, lam", [(0.01, 1.0), (0.25, 1.0), (0.01, 0.8), (0.0, 1.0)])
def test_k42_contact_fraction_split_keeps_the_total(c, lam):
    """A k̄ + k equals K42's bond stiffness A k̄ (A = 2λR·1 m), with k = c A k̄."""
    full = k42_mapping(E, NU, R, lam=lam)
    split = k42_mapping(E, NU, R, lam=lam, contact_fraction=c)
    A = 2 * lam * R * 1.0
    for b, s in (("bond_kn", "kn"), ("bond_ks", "ks")):
        assert A * split[b] + split[s] == pytest.approx(A * full[b], rel=REL)
        assert split[s] == pytest.approx(c * A * split[b], rel=REL, abs=1e-300)
    if c == 0.01 and lam == 1.0:        # the default of the cantilever scene, by hand
        assert split["bond_kn"] == pytest.approx(8.0e9 / 1.01, rel=REL)
        assert split["kn"] == pytest.approx(1.0e5 / 1.01, rel=REL)
        assert A * split["bond_kn"] + split["kn"] == pytest.approx(1.0e7, rel=REL)


def test_lattice_mapping_numbers():
    """K_n = E t/(√3(1−ν)) = 1e7/(1.7320508·0.67) = 8 617 168.2 N/m; K_s = K_n·0.01/1.33;
    split 1 %: k̄ = K/(1.01·A), A = 2R t = 0.00125 m², k = 0.01 K/1.01."""
    k = lattice_mapping(E, NU, R)
    Kn = 8617168.196860088
    Ks = 64790.73832225635
    assert Kn == pytest.approx(1e7 / (math.sqrt(3) * 0.67), rel=REL)
    assert Ks == pytest.approx(Kn * 0.01 / 1.33, rel=REL)
    assert k["bond_kn"] == pytest.approx(6825479759.889179, rel=REL)
    assert k["bond_ks"] == pytest.approx(51319396.69089612, rel=REL)
    assert k["kn"] == pytest.approx(85318.49699861473, rel=REL)
    assert k["ks"] == pytest.approx(641.4924586362015, rel=REL)
    A = 2 * R
    assert A * k["bond_kn"] + k["kn"] == pytest.approx(Kn, rel=REL)
    assert A * k["bond_ks"] + k["ks"] == pytest.approx(Ks, rel=REL)
    # thickness scales K and A alike: k̄ unchanged, k doubles
    k2 = lattice_mapping(E, NU, R, thickness=2.0)
    assert k2["bond_kn"] == pytest.approx(k["bond_kn"], rel=REL)
    assert k2["kn"] == pytest.approx(2 * k["kn"], rel=REL)
    # ν = 1/3 is the limit: K_s = 0
    k3 = lattice_mapping(E, 1.0 / 3.0, R)
    assert k3["bond_ks"] == pytest.approx(0.0, abs=1e-6) and k3["ks"] == pytest.approx(0.0, abs=1e-9)


@pytest.mark.parametrize("nu", [0.34, 0.4, 0.49])
def test_lattice_mapping_refuses_nu_above_one_third(nu):
    with pytest.raises(ParameterError, match=r"\bnu\b"):
        lattice_mapping(E, nu, R)


@pytest.mark.parametrize("call, word", [
    (lambda: k42_mapping(E, 0.5, R), "nu"),
    (lambda: k42_mapping(-1.0, NU, R), "E"),
    (lambda: k42_mapping(E, NU, 0.0), "radius"),
    (lambda: k42_mapping(E, NU, R, lam=1.5), "lam"),
    (lambda: k42_mapping(E, NU, R, contact_fraction=-0.1), "contact_fraction"),
    (lambda: lattice_mapping(E, NU, R, thickness=0.0), "thickness"),
    (lambda: hexagonal_strength(1e6, 1.0 / 3.0, R), "nu"),
    (lambda: hexagonal_strength(0.0, 0.25, R), "sigma_ult"),
])
def test_mappings_refuse_bad_input(call, word):
    with pytest.raises(ParameterError, match=word):
        call()


def test_hexagonal_strength_numbers():
    """σ_ult = 1 MPa, ν = 0.25, R̄ = 5 mm, t = 1: f_n = R̄tσ(√3 − ν/√3)/(2(1−ν))
    = 5000·1.5877132/1.5 = 5292.38 N, f_s = 5000·0.25/1.5 = 833.33 N, σ = f/(2R̄t)."""
    h = hexagonal_strength(1.0e6, 0.25, 0.005)
    assert h["fn_crit"] == pytest.approx(5292.377467571569, rel=REL)
    assert h["fs_crit"] == pytest.approx(833.3333333333334, rel=REL)
    assert h["sigma_c"] == pytest.approx(529237.7467571568, rel=REL)
    assert h["tau_c"] == pytest.approx(83333.33333333333, rel=REL)
    # λ and t cancel in the stresses
    h2 = hexagonal_strength(1.0e6, 0.25, 0.005, thickness=3.0, lam=0.5)
    assert h2["sigma_c"] == pytest.approx(h["sigma_c"], rel=REL)
    assert h2["fn_crit"] == pytest.approx(h["fn_crit"] * 1.5, rel=REL)


def test_k42_split_of_a_stretched_lattice_leaves_the_bond_whole():
    """touching=False (bonded discs a gap apart: the contact springs cannot act while the
    bond holds): k̄_n = E/2R itself, the contact springs keep c/(1 + c)."""
    k = k42_mapping(10e6, 0.33, 0.000625, contact_fraction=0.01, touching=False)
    assert k["bond_kn"] == pytest.approx(10e6 / 0.00125, rel=1e-15)
    assert k["kn"] == pytest.approx(0.01 * 10e6 / 1.01, rel=1e-15)
    t = k42_mapping(10e6, 0.33, 0.000625, contact_fraction=0.01)
    assert t["bond_kn"] == pytest.approx(10e6 / 0.00125 / 1.01, rel=1e-15)
