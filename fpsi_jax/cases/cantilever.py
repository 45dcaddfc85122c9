"""K6.3.3's rubber cantilever strip of bonded discs: the scene and its two validations,
the static tip deflection and the first natural frequency (Euler–Bernoulli)."""
from __future__ import annotations

import math

import numpy as np

from ..build import (check_positive, disc_block, hex_packing, k42_mapping, lattice_mapping,
                     span_spacing, strip_ends, touching_pairs)
from ..build import packing as disc_packing
from ..model.errors import ParameterError
from ..model.params import BondParams, DemParams, Params
from ..model.scene import Scene
from . import overrides as ov
from .measure import crossings, displacement_run
from .registry import Record, scene, validation

MAPPINGS = ("lattice", "k42", "k42_plate", "k42_split")
PACKINGS = ("hex", "square")


def beam_discs(length, height, d, packing="hex", clamp_columns=1):
    """Disc centres of a beam clamped at x = 0 and free at x = ``length``: rows along x centred
    on y = 0, the discs with x ≤ 0 (``clamp_columns`` of them per row; the bonded strip
    bends from the last one, so more only add discs that never move) are the clamp. The
    columns are s = :func:`~fpsi_jax.build.span_spacing` (length, d) ≥ d apart (1.2599 mm
    for 79.375 mm at d = 1.25 mm), so a clamped disc centre sits at x = 0 and a loaded tip
    disc at x = length whatever d is: the free span is the length asked for. Tip discs:
    every row of the square packing (:func:`beam_box`), the rows like the top one of the
    hex packing. Returns (x, fixed, tip, s)."""
    if packing not in PACKINGS:
        raise ParameterError(f"packing must be one of {PACKINGS}, got {packing!r}")
    s = span_spacing(length, d)
    if packing == "square":
        x0, y0, x1, y1 = beam_box(length, height, d)
        x = disc_packing(x0, y0, x1 - x0, y1 - y0, d, "square", stretch=True)
        col = x[np.abs(x[:, 0]) <= 1e-9 * d]
        x = np.concatenate([col - [k * s, 0.0] for k in range(clamp_columns - 1, 0, -1)]
                           + [x])
    else:
        x = hex_beam(length, height, d, clamp_columns)
        x[:, 0] = length + (x[:, 0] - length) * (s / d)
    tol = 1e-9 * d
    fixed = x[:, 0] <= tol
    tip = np.abs(x[:, 0] - length) <= tol
    return x, fixed, tip, s


def beam_box(length, height, d):
    """The rectangle (x0, y0, x1, y1) [m] of the strip from the clamp at x = 0 to the tip at
    x = length, round-down(height/d) rows of discs d centred on y = 0: a stretched square
    packing of it (``packing(…, stretch=True)``, a scene file's ``stretch = true``) has its
    end columns on x = 0 and x = length."""
    n_rows = int(math.floor(height / d + 1e-9))
    return 0.0, -n_rows * d / 2, length, n_rows * d / 2


def hex_beam(length, height, d, clamp_columns=3):
    """Hex-packed disc centres of the beam: a packing wider than the beam shifted so that a
    disc of its top row (and of the rows like it) sits at x = length, cut at the tip and
    behind the clamp, its rows centred on y = 0."""
    n_half = int(math.ceil(length / d)) + clamp_columns + 1
    width = (n_half + 1) * d
    x = hex_packing(0.0, 0.0, width, height, d)
    top = x[:, 1] == x[:, 1].max()
    x[:, 0] += length - x[top, 0].max()
    tol = 1e-9 * d
    x = x[x[:, 0] <= length + tol]
    clamp_limit = -(clamp_columns - 1) * d - tol
    x = x[x[:, 0] >= clamp_limit - d / 2]
    x[:, 1] -= x[:, 1].mean()
    return x


def mode_shape(s):
    """First Euler–Bernoulli cantilever mode φ(s), s = x/L, normalised to φ(1) = 1."""
    b = 1.8751040687
    sig = (math.cosh(b) + math.cos(b)) / (math.sinh(b) + math.sin(b))
    phi = lambda z: np.cosh(b * z) - np.cos(b * z) - sig * (np.sinh(b * z) - np.sin(b * z))
    return phi(s) / phi(1.0)


def euler_bernoulli_f1(E, rho, height, length):
    """f1 = (1.875²/2π) √(EI/(ρAL⁴)), I = h³/12, A = h per unit width."""
    return 1.8751040687 ** 2 / (2 * math.pi) * math.sqrt(E * height ** 2 / 12 / (rho * length ** 4))


def timoshenko_shear_deflection(load, length, E, nu, height, kappa=5.0 / 6.0):
    """The shear part of a Timoshenko cantilever's tip deflection, PL/(κGA), A = height per
    unit width, κ = 5/6 (rectangle): 0.32 % of PL³/(3EI) for the 79.4 × 5 mm strip. The
    bonded strip has shear springs (K43), so its deflection includes this part; the
    validation compares with PL³/(3EI) and records both."""
    return load * length / (kappa * E / (2 * (1 + nu)) * height)


def tip_deflection(load, length, E, height):
    """Euler–Bernoulli δ = PL³/(3EI), I = h³/12 per unit width."""
    return load * length ** 3 / (3 * E * height ** 3 / 12)


@scene
def cantilever(*, length=0.079375, height=0.005, d=0.00125, E=10.0e6, nu=0.33, rho=1100.0,
               load=1.0, mapping="k42_split", packing="square", variant="tip", alpha=None,
               damping=0.0, amplitude=0.02, clamp_columns=1, t_end=None) -> Scene:
    """K6.3.3's rubber strip: ``length`` × ``height`` (5 mm × 79.375 mm), E = 10 MPa, discs
    d = 1.25 mm, clamped at x = 0, per unit width (t = 1 m), no gravity.

    variant 'tip'   ``load`` [N] downwards shared by the tip discs (x = length), local
                    damping α = 0.7 to the static state; Euler–Bernoulli δ = PL³/(3EI) with
                    I = height³/12: 1.6 mm
    variant 'free'  no load, no damping; initial velocity in the first Euler–Bernoulli mode
                    shape with ``amplitude`` m/s at the tip; f1 = (1.875²/2π)√(EI/(ρAL⁴))
    mapping         'k42_split' (default: K42–K43 bond stiffness, the total split as in
                    W26–W30 with 1 % in the contact springs), 'k42' (K42–K43 literally: the
                    contact springs as stiff as the bond), 'k42_plate' (K's plate variant,
                    k_s = ½k_n), 'lattice' (hexagonal plane stress, Griffiths & Mustoe;
                    ν ≤ 1/3)
    packing         'square' (default: 4 rows of d = 1.25 mm fill the 5 mm exactly, and a
                    bond of section 2R̄t between discs 2R apart is then an exact bar, so K42
                    gives the continuum EI) or 'hex' (4 rows fit, representing 4.33 mm)
    damping         mass-proportional viscous damping rate c [1/s] (DemParams.damping): the
                    first mode decays with damping ratio ζ1 = c/(4π f1)
    t_end           default six periods of f1 [s]
    The clamp is the discs with x ≤ 0; the columns are L/⌊L/d⌋ apart (1.2599 mm at the
    default d), so the last clamped column sits at x = 0 and the loaded tip column at x = L:
    the free span is L at any d (:func:`beam_discs`).
    Disc masses: the packing's cell area d·s (mass per area exactly ρ; physics.md allows it),
    half a cell for the tip column (:func:`~fpsi_jax.build.strip_ends`: the strip ends at
    x = L, its mass is ρ·height·L; a whole tip cell lowered f1 by 1.6 % at the default d).
    """
    check_positive(length=length, height=height, d=d, E=E, rho=rho, load=load)
    if mapping not in MAPPINGS:
        raise ParameterError(f"mapping must be one of {MAPPINGS}, got {mapping!r}")
    if variant not in ("tip", "free"):
        raise ParameterError(f"variant must be 'tip' or 'free', got {variant!r}")
    x, fixed, tip, spacing = beam_discs(length, height, d, packing, clamp_columns)
    R = d / 2
    if mapping == "lattice":
        k = lattice_mapping(E, nu, R)
    elif mapping == "k42_split":
        k = k42_mapping(E, nu, R, contact_fraction=0.01, touching=spacing <= d * (1 + 1e-9))
    else:
        k = k42_mapping(E, nu, R, plate=mapping == "k42_plate")
    f_ext = np.zeros_like(x)
    v = np.zeros_like(x)
    if variant == "tip":
        f_ext[tip, 1] = -load / tip.sum()
        alpha = 0.7 if alpha is None else alpha
    else:
        alpha = 0.0 if alpha is None else alpha
        v[:, 1] = amplitude * mode_shape(np.clip(x[:, 0], 0, None) / length)
    blk = disc_block(x, R, rho, mass_model="lattice", packing=packing, fixed=fixed, f_ext=f_ext,
                     v=v, column_spacing=spacing)
    blk = strip_ends(blk, 0.0, length)
    bonds = touching_pairs(x, R, gap=spacing - d)
    if t_end is None:
        # six periods either way: the local damping of the static variant converges per
        # step, not per period (at 4 periods, 27 k steps of the derived step, the tip still
        # moved 0.24 % over the last tenth of the run; at 6, 0.02 %)
        t_end = 6.0 / euler_bernoulli_f1(E, rho, height, length)
    pad = 0.3 * length
    return Scene(
        name="cantilever",
        params=Params(gravity=(0.0, 0.0),
                      dem=DemParams(kn=k["kn"], ks=k["ks"], mu=0.0, alpha=alpha,
                                    damping=damping),
                      bond=BondParams(kn=k["bond_kn"], ks=k["bond_ks"])),
        domain_lo=(-clamp_columns * spacing - pad, -pad), domain_hi=(length + pad, pad), v_max=1.0,
        solid=blk, bonds=bonds, t_end=t_end, options={"x64": True},
        builder_kwargs=dict(alpha=alpha, t_end=t_end))


def cantilever_static(overrides=None, base=None):
    """Run the tip-loaded strip to rest; returns (tip deflection [m], its change over the
    last tenth of the run relative to it, scene, result, wall seconds)."""
    scene, phys = ov.build("cantilever", overrides or {}, {"variant": "tip", **(base or {})})
    y, res, wall = displacement_run(scene, phys, np.abs(scene.solid.f_ext[:, 1]) > 0)
    return -float(y[-1]), abs(float(y[-1] - y[int(0.9 * len(y))])) / abs(float(y[-1])), \
        scene, res, wall


@validation("cantilever", "K6.3.3 rubber cantilever, 1 N tip load: deflection vs PL³/(3EI) (1 %)")
def cantilever_case(quick: bool = False, overrides: dict | None = None):
    base = {"d": 0.0025} if quick else {}
    val, settle, scene, res, wall = cantilever_static(overrides, base)
    kw = scene.builder_kwargs
    ref = tip_deflection(kw["load"], kw["length"], kw["E"], kw["height"])
    span = kw["length"] - float(scene.solid.x[scene.solid.fixed, 0].max())
    timo = ref + timoshenko_shear_deflection(kw["load"], kw["length"], kw["E"], kw["nu"],
                                             kw["height"])
    err = abs(val - ref) / ref
    info = {**kw, "quick": quick, "n_discs": scene.solid.n, "steps": res.n_steps,
            "dt": float(res.params.dt), "last_10pct_change": settle,
            "as_built_span": span, "reference_with_shear": timo,
            "error_vs_reference_with_shear": (val - timo) / timo}
    return [Record("cantilever", "tip deflection [m] vs PL³/(3EI)", val, ref, err, 0.01,
                   err < 0.01, wall, info)]


@validation("cantilever_frequency", "cantilever free vibration f1 vs Euler–Bernoulli (2 %)",
            scene="cantilever")
def cantilever_frequency_case(quick: bool = False, overrides: dict | None = None):
    base = {"variant": "free", **({"d": 0.0025} if quick else {})}
    scene, phys = ov.build("cantilever", overrides or {}, base)
    x = scene.solid.x
    y, res, wall = displacement_run(scene, phys, np.abs(x[:, 0] - x[:, 0].max()) < 1e-9)
    dt = float(res.params.dt)
    tc = crossings(dt * np.arange(1, len(y) + 1), y)
    f = (len(tc) - 1) / (tc[-1] - tc[0])
    kw = scene.builder_kwargs
    ref = euler_bernoulli_f1(kw["E"], kw["rho"], kw["height"], kw["length"])
    span = kw["length"] - float(x[scene.solid.fixed, 0].max())
    err = abs(f - ref) / ref
    info = {**kw, "quick": quick, "n_discs": scene.solid.n, "steps": res.n_steps, "dt": dt,
            "periods": len(tc) - 1, "as_built_span": span,
            "reference_as_built_span": euler_bernoulli_f1(kw["E"], kw["rho"], kw["height"], span)}
    return [Record("cantilever_frequency", "first natural frequency [Hz]", f, ref, err, 0.02,
                   err < 0.02, wall, info)]
