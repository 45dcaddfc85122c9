"""Fluid–structure scenes (issue 4): an elastic plate under still water (K6.3.3) and the
Antoci et al. (2007) dam break through an elastic rubber gate (K6.3, W6.1), intact and with
bonds weak enough to break.

Structures are bonded square packings of discs of diameter d: the 5 mm plate and gate are 4
rows of d = 1.25 mm, and a bond of section 2R̄t between discs 2R apart is then an exact bar,
so K42 gives the continuum bending stiffness (see ``beams.cantilever``). Both are thin plates
spanning the tank's width, so by default the bonds use the plane-strain modulus E/(1−ν²)
(``plane_strain=True``): the strip then has the plate stiffness D = Ee³/(12(1−ν²)) that the
analytic plate solution (K44–K45) assumes. Disc masses are the packing's cell area × ρ.
"""
from __future__ import annotations

import math

import numpy as np

from ..build import (G, boundary_block, boundary_layers, box_walls, check_positive, disc_block,
                     hydrostatic_fluid, k42_mapping, lattice, sph_params, tank_walls,
                     touching_pairs)
from ..model.errors import ParameterError
from ..model.options import FsiMethod, choose
from ..model.params import BondParams, DemParams, Params
from ..model.scene import Scene


def _check_coupling(coupling):
    choose(FsiMethod, "coupling", coupling)


def _bond_params(E, nu, d, plane_strain, sigma_c=1.0e30, tau_c=1.0e30, shear_factor=1.0):
    """K42–K43 stiffnesses with W's 1 % contact split (the cantilever's default mapping);
    the shear springs (k̄_s, k_s) scaled by ``shear_factor``."""
    check_positive(shear_factor=shear_factor)
    k = k42_mapping(E, nu, d / 2, contact_fraction=0.01, plane_strain=plane_strain)
    k = {**k, "bond_ks": k["bond_ks"] * shear_factor, "ks": k["ks"] * shear_factor}
    return k, BondParams(kn=k["bond_kn"], ks=k["bond_ks"], sigma_c=sigma_c, tau_c=tau_c)


def _rows(length, d, name):
    n = int(round(length / d))
    if n < 1:
        raise ParameterError(f"{name} = {length} holds no disc of diameter d = {d}")
    return n


# --- hydrostatic plate -------------------------------------------------------------------
def plate_deflection(span, thickness, water_height, E, nu, rho_water=1000.0, rho_plate=1100.0,
                     g=G, shear_modulus=None, kappa=5.0 / 6.0):
    """Midpoint deflection of a plate strip clamped at both ends under its own weight and a
    water column (K44–K45): w = q L⁴/(384 D), q = g(ρ_w H + ρ_p e), D = Ee³/(12(1−ν²)).
    (K44 writes the coefficient 0.0026 ≈ 1/384.)

    K44 is the thin (Kirchhoff, shear-rigid) plate. With ``shear_modulus`` G the Timoshenko
    shear deflection of the clamped–clamped strip, q L²/(8 κ G e), is added: for the rubber
    plate (E/(1−ν²))/G = 2/(1−ν) = 3.3 and L/e = 15.75, which makes it 6.4 % of the total."""
    q = g * (rho_water * water_height + rho_plate * thickness)
    D = E * thickness ** 3 / (12.0 * (1.0 - nu * nu))
    w = q * span ** 4 / (384.0 * D)
    if shear_modulus is not None:
        w += q * span ** 2 / (8.0 * kappa * shear_modulus * thickness)
    return w


def plate_reference(builder_kwargs, g=G):
    """The deflection the scene should reach: K44 plus the shear deflection of the strip's
    shear modulus G·shear_factor, for the as-built span, thickness and water."""
    b = builder_kwargs
    G_eff = b["E"] / (2 * (1 + b["nu"])) * b["shear_factor"]
    return plate_deflection(b["span_built"], b["thickness_built"], b["water_height_built"],
                            b["E"], b["nu"], b["rho_water"], b["rho_plate"], g,
                            shear_modulus=G_eff)


def hydrostatic_plate(*, span=0.07875, thickness=0.005, water_height=0.1575005, E=10.0e6,
                      nu=0.4, rho_plate=1100.0, rho_water=1000.0, dx=0.00175, d=0.00125,
                      dx_boundary=0.00125, h0=None, mu=8.9e-4, c0=None,
                      coupling="extrapolated", alpha=0.7, damping=0.0, plane_strain=True,
                      shear_factor=1.0, clamp_columns=3, r_clump=0.01, eps_xsph=0.5,
                      delta=0.1, alpha_av=0.02, t_end=0.5) -> Scene:
    """K6.3.3: a 5 mm plate of span 0.07875 m clamped at both ends under 0.1575005 m of still
    water (ρ_p 1100, ν 0.4, E 10 MPa). Reference: :func:`plate_deflection`, 1.2915 mm (K
    quotes 1.2895 mm with the rounded coefficient 0.0026).

    As built: the clamps are the disc columns at x ≤ 0 and x ≥ L with L = round(span/d)·d
    (the last clamped centres are exactly L apart: a bonded strip bends from the last fixed
    disc centre), the water fills [0, L] between two walls of SPH boundary particles, on a
    dx lattice of floor(L/dx) × round(H/dx) particles. ``builder_kwargs`` records the as-built
    span and the water height that carries the same mass (``span_built``,
    ``water_height_built``); the reference uses them. At the seed's resolution (dx 1.75 mm,
    d 1.25 mm) both equal the nominal values.

    The plate starts straight and the water hydrostatic; local damping ``alpha`` (DEM K25)
    settles the plate (by 0.25 s at the seed resolution); the midpoint deflection is read
    after the transient.

    K44 is a thin-plate (shear-rigid) formula; the bonded strip has the shear flexibility of
    the rubber (G = E/(2(1+ν))), 6.4 % of the deflection here. :func:`plate_reference` gives
    the deflection for the scene's parameters with the Timoshenko shear term.
    ``shear_factor`` multiplies the shear springs (20 would make a continuum strip
    shear-rigid to 0.3 %, but in the square lattice it also stiffens bending by 3 %: README).
    Runs in float64: in float32 the DEM-only strip comes out 1 % (shear_factor 1) to 9 %
    (shear_factor 20) off, positions ~0.08 m leave too few digits for bond strains. Coupling: ``extrapolated`` (ours; fsi.py says why); K's three methods let the
    water through the plate at this resolution."""
    check_positive(span=span, thickness=thickness, water_height=water_height, E=E,
                   rho_plate=rho_plate, rho_water=rho_water, dx=dx, d=d,
                   dx_boundary=dx_boundary)
    _check_coupling(coupling)
    h = 1.25 * dx if h0 is None else h0
    n_span = _rows(span, d, "span")
    n_rows = _rows(thickness, d, "thickness")
    L = n_span * d
    # plate: columns k d, k = −(c−1) … n_span + c − 1; rows below y = 0
    cols = np.arange(-(clamp_columns - 1), n_span + clamp_columns)
    X, Y = np.meshgrid(cols * d, -d / 2 - d * np.arange(n_rows), indexing="ij")
    xs = np.stack([X.ravel(), Y.ravel()], axis=1)
    tol = 1e-9 * d
    fixed = (xs[:, 0] <= tol) | (xs[:, 0] >= L - tol)
    k, bp = _bond_params(E, nu, d, plane_strain, shear_factor=shear_factor)
    blk = disc_block(xs, d / 2, rho_plate, mass_model="lattice", packing="square",
                     fixed=fixed)
    blk.sph_volume = np.full(blk.n, d * d)
    bonds = touching_pairs(xs, d / 2)
    # water between the walls
    nx = max(1, int(math.floor(L / dx + 1e-9)))
    ny = _rows(water_height, dx, "water_height")
    H = ny * dx
    v_max = float(np.sqrt(2 * G * H))
    c0 = 10.0 * v_max if c0 is None else c0
    sp = sph_params(rho_water, c0, mu, dx, r_clump, eps_xsph, delta, alpha=alpha_av)
    x0 = 0.5 * (L - nx * dx)
    fluid = hydrostatic_fluid(lattice(x0, 0.0, nx * dx, H, dx), rho_water, c0, sp.gamma, H,
                              dx=dx, h=h)
    layers = boundary_layers(h, dx_boundary)
    t = layers * dx_boundary
    top = 1.2 * H
    wall = lattice(0.0, 0.0, t, top, dx_boundary)
    xb = np.concatenate([wall - [t, 0.0], wall + [L, 0.0]])
    boundary = boundary_block(xb, rho_water, dx_boundary, h)
    pad = t + clamp_columns * d + 2 * h
    return Scene(
        name="hydrostatic_plate",
        params=Params(sph=sp, dem=DemParams(kn=k["kn"], ks=k["ks"], mu=0.0, alpha=alpha,
                                                damping=damping),
                      bond=bp),
        domain_lo=(-pad, -thickness - pad), domain_hi=(L + pad, top + pad), v_max=v_max,
        fluid=fluid, boundary=boundary, solid=blk, bonds=bonds, t_end=t_end,
        options={"fsi": coupling, "boundary_pressure": "extrapolated", "delta_sph": True,
                 "artificial_viscosity": True, "x64": True},
        builder_kwargs=dict(span=span, thickness=thickness, water_height=water_height, E=E,
                            nu=nu, rho_plate=rho_plate, rho_water=rho_water, dx=dx, d=d,
                            dx_boundary=dx_boundary, h0=h, mu=mu, c0=c0, coupling=coupling,
                            alpha=alpha, damping=damping, plane_strain=plane_strain,
                            shear_factor=shear_factor, clamp_columns=clamp_columns, r_clump=r_clump, eps_xsph=eps_xsph,
                            delta=delta, alpha_av=alpha_av, t_end=t_end, span_built=L,
                            thickness_built=n_rows * d,
                            water_height_built=nx * dx * H / L))


def plate_midpoint(x0):
    """Indices of the plate's discs in the middle column (all rows) for the initial
    positions ``x0``; their mean y is the midpoint deflection."""
    xm = 0.5 * (x0[:, 0].min() + x0[:, 0].max())
    col = np.abs(x0[:, 0] - xm) <= np.min(np.abs(x0[:, 0] - xm)) + 1e-12
    return np.nonzero(col)[0]


# --- elastic gate ------------------------------------------------------------------------
def gate_discs(x_face, gap, length, thickness, d, clamp_rows):
    """Disc centres of a gate hanging from a clamp: ``round(thickness/d)`` columns from
    x = x_face, free rows centred at gap + d/2 + k d for k < round(length/d), then
    ``clamp_rows`` fixed rows. Returns (x, fixed, tip) with ``tip`` the bottom row."""
    n_cols = _rows(thickness, d, "gate_thickness")
    n_free = _rows(length, d, "gate_length")
    rows = np.arange(n_free + clamp_rows)
    X, Y = np.meshgrid(x_face + d / 2 + d * np.arange(n_cols), gap + d / 2 + d * rows,
                       indexing="ij")
    x = np.stack([X.ravel(), Y.ravel()], axis=1)
    k = np.broadcast_to(rows[None, :], X.shape).ravel()
    return x, k >= n_free, k == 0


# The elastic gate's coarse resolution (fluid 3.5 mm, discs and boundary 2.5 mm, h 4.375 mm):
# what the quick validation, the tests, the calibration and the experiments run.
GATE_COARSE = {"dx": 0.0035, "d": 0.0025, "dx_boundary": 0.0025, "h0": 0.004375}


def elastic_gate(*, water_width=0.1, water_height=0.14, gate_length=0.079,
                 gate_thickness=0.005, gap=0.0, E=10.0e6, nu=0.4, rho_gate=1100.0,
                 rho_water=1000.0, dx=0.00175, d=0.00125, dx_boundary=0.00125, h0=0.0021875,
                 mu=8.9e-4, c0=None, coupling="extrapolated", alpha=0.0, damping=0.0,
                 plane_strain=True, shear_factor=1.0, tank_length=0.6, tank_height=0.16, clamp_rows=3,
                 sigma_c=1.0e30, tau_c=1.0e30, r_clump=0.01, eps_xsph=0.5, delta=0.1,
                 alpha_av=0.02, t_end=0.4) -> Scene:
    """Antoci, Gallati & Sibilla (2007): water ``water_width`` × ``water_height`` (0.1 ×
    0.14 m) held by a rubber gate ``gate_length`` × ``gate_thickness`` (0.079 × 0.005 m, ρ
    1100) clamped at its top, free at the bottom; the barrier that held the gate is gone at
    t = 0 (the gate starts straight, the water hydrostatic). Seed 001 Table 5 resolution:
    fluid dx 1.75 mm, boundary 1.25 mm, discs 1.25 mm, h 2.1875 mm.

    Documented defaults (README): E = 10 MPa and ν = 0.4 (K's final attempts; C and N in
    ``antoci2007_case_parameters.csv``), mapped with the plane-strain modulus E/(1−ν²) =
    11.9 MPa; no local damping, α = 0 (K6.3.1 used 0.157: local damping −α|F_i|sign(v_i)
    is a quasi-static device; on a moving bonded body the discs' vibrating internal forces
    make it a drag on the whole body — the broken-off gate of ``gate_failure`` stopped in
    mid-water under an unbalanced fluid force of 3 N with α = 0.157 — and it flattens the
    gate's response: peak ux 35.9 mm with 0.157, 39.5 mm with 0); the ``extrapolated`` coupling (ours,
    see fsi.py; K's three are options, compared in experiments/elastic_gate.py); the gate
    fully clamped (K's 'semi-rigid' clamp is not modelled); gap 0 between the gate's tip
    and the floor (the experiment's gate closes the tank; C uses a 2.5 mm model gap).
    No viscous damping by default either (``damping`` = c of DemParams.damping, the
    smooth damping that calibration fits). c0 = 10 √(2 g H). δ-SPH and α = 0.02
    artificial viscosity as in the dam break.
    Tank: floor from x = 0 to ``tank_length`` (0.6 m: the released water's front reaches
    x = 0.5 m at 0.38 s, and with a 0.5 m tank a fluid particle went through the end wall at
    0.387 s and left the domain, stopping the 0.4 s main job; the comparison window is
    0–0.36 s) with walls at both ends ``tank_height``
    high (SPH boundary particles for the water, DEM line walls for the discs: the two never
    interact, so without the DEM walls a broken-off gate falls through the floor); a rigid
    wall of boundary particles above the clamp.

    As built: the free rows hold round(gate_length/d) = 63 discs, the last clamped row's
    centre is 79.375 mm above the tip (free length 79.375 mm to the tip's edge).
    ``sigma_c``/``tau_c`` are the bonds' strengths (unbreakable by default; see
    :func:`gate_failure`)."""
    check_positive(water_width=water_width, water_height=water_height,
                   gate_length=gate_length, gate_thickness=gate_thickness, E=E,
                   rho_gate=rho_gate, rho_water=rho_water, dx=dx, d=d,
                   dx_boundary=dx_boundary, h0=h0, tank_length=tank_length,
                   tank_height=tank_height, sigma_c=sigma_c, tau_c=tau_c)
    _check_coupling(coupling)
    if gap < 0:
        raise ParameterError(f"gap = {gap} out of range; allowed [0, inf)")
    if tank_length < water_width + gate_thickness + 0.05:
        raise ParameterError(f"tank_length = {tank_length} out of range; allowed "
                             f"[{water_width + gate_thickness + 0.05:.4g}, inf)")
    xs, fixed, tip = gate_discs(water_width, gap, gate_length, gate_thickness, d, clamp_rows)
    top_gate = xs[:, 1].max() + d / 2
    if top_gate >= tank_height:
        raise ParameterError(f"tank_height = {tank_height} out of range; the gate and its "
                             f"clamp reach {top_gate:.4g} m")
    k, bp = _bond_params(E, nu, d, plane_strain, sigma_c, tau_c, shear_factor)
    blk = disc_block(xs, d / 2, rho_gate, mass_model="lattice", packing="square",
                     fixed=fixed)
    blk.sph_volume = np.full(blk.n, d * d)
    bonds = touching_pairs(xs, d / 2)
    v_max = float(np.sqrt(2 * G * water_height))
    c0 = 10.0 * v_max if c0 is None else c0
    sp = sph_params(rho_water, c0, mu, dx, r_clump, eps_xsph, delta, alpha=alpha_av)
    fluid = hydrostatic_fluid(lattice(0.0, 0.0, water_width, water_height, dx), rho_water, c0,
                              sp.gamma, _rows(water_height, dx, "water_height") * dx, dx=dx,
                              h=h0)
    layers = boundary_layers(h0, dx_boundary)
    xb = tank_walls(tank_length, tank_height, dx_boundary, layers)
    n_wall = _rows(gate_thickness, dx_boundary, "gate_thickness")
    wall = lattice(water_width, top_gate, n_wall * dx_boundary, tank_height - top_gate,
                   dx_boundary)
    boundary = boundary_block(np.concatenate([xb, wall]), rho_water, dx_boundary, h0)
    pad = layers * dx_boundary + 2 * h0
    return Scene(
        name="elastic_gate",
        params=Params(sph=sp, dem=DemParams(kn=k["kn"], ks=k["ks"], mu=0.0, alpha=alpha,
                                                damping=damping),
                      bond=bp),
        domain_lo=(-pad, -pad), domain_hi=(tank_length + pad, 1.5 * tank_height),
        v_max=v_max, fluid=fluid, boundary=boundary, solid=blk, bonds=bonds,
        walls=box_walls(0.0, 0.0, tank_length, tank_height), t_end=t_end,
        options={"fsi": coupling, "boundary_pressure": "extrapolated", "delta_sph": True,
                 "artificial_viscosity": True},
        builder_kwargs=dict(water_width=water_width, water_height=water_height,
                            gate_length=gate_length, gate_thickness=gate_thickness, gap=gap,
                            E=E, nu=nu, rho_gate=rho_gate, rho_water=rho_water, dx=dx, d=d,
                            dx_boundary=dx_boundary, h0=h0, mu=mu, c0=c0, coupling=coupling,
                            alpha=alpha, damping=damping, plane_strain=plane_strain,
                            shear_factor=shear_factor, tank_length=tank_length,
                            tank_height=tank_height, clamp_rows=clamp_rows, sigma_c=sigma_c,
                            tau_c=tau_c, r_clump=r_clump, eps_xsph=eps_xsph, delta=delta,
                            alpha_av=alpha_av, t_end=t_end,
                            tip=np.nonzero(tip)[0].tolist()))


def gate_failure(*, sigma_c=2.0e5, tau_c=2.0e5, t_end=0.3, **kwargs) -> Scene:
    """The elastic gate with bonds weak enough to break (seed 000 §6.3 in spirit): the
    hydrostatic bending stress at the clamp is about 6M/e² ≈ 0.8 MPa (M ≈ ρg(HL²/2 − L³/6)),
    so σ̄_c = τ̄_c = 0.2 MPa lets the gate crack at the clamp soon after release and be
    carried off by the flow. Every other keyword as :func:`elastic_gate`."""
    scene = elastic_gate(sigma_c=sigma_c, tau_c=tau_c, t_end=t_end, **kwargs)
    scene.name = "gate_failure"
    return scene


def _failure_signature():
    import inspect
    sig = inspect.signature(elastic_gate)
    new = {"sigma_c": 2.0e5, "tau_c": 2.0e5, "t_end": 0.3}
    return sig.replace(parameters=[p.replace(default=new.get(p.name, p.default))
                                   for p in sig.parameters.values()])


gate_failure.__signature__ = _failure_signature()


def gate_tip(scene: Scene) -> np.ndarray:
    """Indices of the gate's bottom-row discs (their mean is the free end)."""
    return np.asarray(scene.builder_kwargs["tip"], int)
