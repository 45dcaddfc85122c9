"""Skip what a scene does not need, measured: for every registered scene, the mechanisms
and neighbour lists compiled into its step, the step time of that specialised program, and
the step time of the same scene with every mechanism forced on but masked so that it
contributes nothing.

    nice -n 10 .venv/bin/python experiments/specialisation.py [--scenes LABEL ...]
        [--target-s 1.0] [--min-rounds 7] [--max-rounds 40] [--cpu 0]

Writes experiments/results/specialisation.json (everything, per case: mechanisms, the
named scopes found in the lowered step, list flags, compile time, every chunk time, state
checks) and specialisation.md (the table and, per case, the dummies added and what could
not be forced). A case is a row of CASES (coarse builder settings, chunk length; "dam_break
(minimal SPH)" is the dam break with XSPH, anti-clump, δ-SPH and artificial viscosity off,
where masking has to pay per pair) or any other registered scene at its defaults. Each case
runs in a subprocess of its own (``--worker LABEL``; the float64 scenes switch
jax_enable_x64 on for the whole process), pinned to one core (``--cpu``) before Python
starts: unpinned, on this shared VM under load ~7, the same program ran at 2.9 or 11
µs/step in different processes and two identical programs at 4.1 and 7.6 ms/step in one
(the bimodality experiments/bench_dem.py describes); pinned, identical programs agreed
within a few per cent.

Three programs per case, all at the specialised run's Δt and DEM sub-steps:

specialised  ``setup(scene)``: what a run compiles (``Physics.mechanisms()``, confirmed by
             the ``jax.named_scope`` names in the lowered step, loop bodies included; lists:
             ``Physics.neighbors`` / ``dem_neighbors`` and the scopes neighbors.update /
             neighbors.dem_update).
masked       every SPH switch on (XSPH, anti-clump, variable h, δ-SPH, artificial viscosity,
             extrapolated boundary) with its coefficient zeroed in Params where the scene
             had it off (sph.eps_xsph, r_clump, delta, alpha = 0), and an inert dummy for
             each family the scene lacks, added at scene level: a pair of fixed, bonded discs
             (DEM list, contacts, local damping, bonds), a wall segment (DEM walls), a fixed
             structure disc (fsi 'extrapolated'), and for scenes without fluid a hydrostatic
             3 × 2 block of fluid in a tank of boundary particles (SPH list, every SPH
             mechanism, anticlump_boundary too) with a fixed grain (fpi). Dummy discs have
             the scene's largest radius (0.4 h without discs), the dummy fluid spacing is
             that radius. The dummies sit in a strip added above the scene's domain, farther
             from everything real than twice any cut-off + skin, so the real particles must
             move as in the specialised run: max |Δx|, |Δv| of the real fluid and discs after
             the warm-up chunk (``steps`` steps from t = 0) are recorded.
control      the specialised Physics on the masked scene's (larger) domain, no dummies: the
             domain fixes the neighbour grids, so masked / control is the cost of the
             mechanisms alone and control / specialised that of the larger grid (and of
             noise: they are otherwise the same program).

Not forced, because no Params coefficient turns them off (core code changes needed):
fpi in a scene with real fluid (with grains the pressure bracket becomes (P_i+P_j)/(ρ̃_iρ̃_j),
which differs from P_i/ρ_i² + P_j/ρ_j² even at ε = 1), anticlump_boundary where the anti-
clump term is on for real fluid (r_clump is shared by both pair kinds), and variable_h or the
extrapolated boundary in a fluid scene that has them off (none here). Alternatives (kernel,
boundary_pressure, fsi method, fpi_pressure, voidage, bond_section) are one-of choices, not
add-ons: the masked run keeps the scene's. The masked run uses ``unsafe_dt`` (the dummies'
bounds are not the scene's; Δt is the specialised run's).

The dummies are as small as a family can be, so the masked run's extra cost is the fixed
cost of each mechanism (its kernels, gathers and list checks): a lower bound on what a code
that masked absent mechanisms over all its particles would pay.

Timing: one warm-up chunk of ``steps`` steps per program (excluded) and one more as a check
(an overflowing list is grown and the chunk recompiled, as the driver does), then rounds in
which each program runs one chunk from its post-warm-up state (the same chunk every round,
so runs that end soon, e.g. the collision, stay valid); µs/step is the median over the
rounds (best also recorded), rounds = clamp(target_s / slowest chunk, min, max). Chunks of
the three programs are interleaved so that load changes hit them alike.

Observed (results/specialisation.md: core 0, load 2-6 from other work; a second full run
gave the same picture, ratios within the spreads quoted): DEM-only scenes run 2.2-28x
slower masked (the SPH and fpi machinery for 51 dummy particles costs 22-40 µs/step
against steps of 1-20 µs; the tiny scenes' ratios moved up to 2x between runs, e.g. the
collision 7.9 and 14.4); fluid-only scenes 1.16-1.32x slower with the dummy DEM, bond,
wall and fsi families, 1.7x when the four optional SPH terms are masked instead of left out
(dam break, both runs); sedimentation 1.2x (artificial viscosity, bonds, fsi). Where the
absent family is one cheap add-on to a multi-ms coupled step (a wall for the plate, a bond
for the two-phase dam break) the difference, 0-2 %, is within the noise: the cases with
nothing to add (elastic gate, gate failure, fpsi failure) read 0.98-1.00. The larger
domain alone doubles the step of the one-disc scenes (rolling, wall impact: the cell grid
dominates there), hence the control. After one chunk masked and control are bitwise
equal in 13 of 16 cases; the rest differ by round-off where zero-coefficient terms or dummy
discs change the order of XLA's sums (≤ 3e-8 m in float32, 1 ulp; 8e-17 m in float64).
Against the specialised run the larger grid reorders the neighbour sums: ≤ 9e-8 m in
float32 (a few ulp), ≤ 8e-17 m in float64, 0 in 8 cases.
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import platform
import re
import statistics
import subprocess
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
MARK = "SPECIALISATION_ROW "

# label: (scene, builder kwargs (coarse: each compiles and runs in seconds), Physics
# overrides, chunk length in steps); every registered scene without a row here runs with its
# defaults and DEFAULT_STEPS
COARSE_GATE = dict(dx=0.0035, d=0.0025, dx_boundary=0.0025, h0=0.004375)
MINIMAL_SPH = dict(xsph=False, anticlump=False, delta_sph=False, artificial_viscosity=False,
                   wall_repulsion=False)
CASES = {
    "hydrostatic_tank": ("hydrostatic_tank", dict(dx=0.01), {}, 100),
    "dam_break": ("dam_break", dict(dx=0.01), {}, 100),
    # the same with the optional SPH terms off: masking them costs per pair
    "dam_break (minimal SPH)": ("dam_break", dict(dx=0.01), MINIMAL_SPH, 100),
    # the warm-up and check chunks run 2 x steps from t = 0 and must end before a disc
    # leaves the box (the run stops there with SimulationError)
    "collision": ("collision", {}, {}, 80),        # a disc leaves the box at step 176
    "rolling": ("rolling", {}, {}, 150),           # the disc leaves the floor at step 331
    "dry_dam_break": ("dry_dam_break", {}, {}, 2000),
    "wall_impact": ("wall_impact", {}, {}, 60),    # the grain leaves the box after ~150
    "itasca_beam": ("itasca_beam", {}, {}, 2000),
    "cantilever": ("cantilever", dict(d=0.0025), {}, 2000),
    "bond_tension": ("bond_tension", {}, {}, 2000),
    "hydrostatic_plate": ("hydrostatic_plate", dict(dx=0.0035, d=0.0025, dx_boundary=0.0025),
                          {}, 20),
    "elastic_gate": ("elastic_gate", COARSE_GATE, {}, 20),
    "gate_failure": ("gate_failure", COARSE_GATE, {}, 20),
    "sedimentation": ("sedimentation", {}, {}, 40),
    "two_phase_dam_break": ("two_phase_dam_break", dict(dx=0.004, dx_boundary=0.0025,
                                                        h0=0.005), {}, 10),
    "fpsi_failure": ("fpsi_failure", dict(dx=0.004, dx_boundary=0.0025, h0=0.005), {}, 10),
}
DEFAULT_STEPS = 100
# switch: the Params.sph coefficient that zeroes it
SPH_SWITCHES = {"xsph": "eps_xsph", "anticlump": "r_clump", "delta_sph": "delta",
                "artificial_viscosity": "alpha", "wall_repulsion": "wall_beta"}
SCOPES = ("sph.", "boundary.", "dem.", "bonds", "fsi.", "fpi.", "neighbors.")


# --- the masked scene -------------------------------------------------------------------
def _reach(r_disc, h_fluid):
    """Twice the largest list cut-off + skin that the masked scene can have: the gap that
    keeps the dummies out of every real particle's reach."""
    sph = (2 * 1.05 + 0.25) * h_fluid
    dem = (2 * 1.1 + 0.5) * r_disc if r_disc else 0.0   # 1.1: lubrication reach
    return 2.0 * max(sph, dem)


def _dummy_tank(x0, y0, s, dt, gravity):
    """A 3 × 2 block of fluid at spacing ``s`` in a tank of boundary particles, hydrostatic,
    lower-left outer corner at (x0, y0). c0 keeps its acoustic step ≥ 2 Δt. Returns
    (fluid, boundary, SphParams, width, height)."""
    from fpsi_jax.build import (boundary_block, boundary_layers, hydrostatic_fluid, lattice,
                                sph_params, tank_walls)
    h = 1.25 * s
    layers = boundary_layers(h, s)
    t = layers * s
    g = float(np.linalg.norm(gravity))
    c0 = min(10.0 * math.sqrt(2 * max(g, 9.81) * 2 * s), 0.125 * h / dt)
    sp = sph_params(1000.0, c0, 1.0e-3, s, 0.01, 0.5, 0.1, alpha=0.02)
    off = np.array([x0 + t, y0 + t])
    fluid = hydrostatic_fluid(lattice(0.0, 0.0, 3 * s, 2 * s, s) + off, 1000.0, c0, sp.gamma,
                              off[1] + 2 * s, g=g, dx=s, h=h)
    xb = tank_walls(3 * s, 3 * s, s, layers) + off
    boundary = boundary_block(xb, 1000.0, s, h, p=1000.0 * g * np.maximum(
        off[1] + 2 * s - xb[:, 1], 0.0), c0=c0)
    return fluid, boundary, sp, 3 * s + 2 * t, 3 * s + t


def _solid_with(scene, real_structure, real_grain, x, r, structure, grain):
    """The scene's discs followed by fixed dummy discs at ``x`` (radius r), masks explicit."""
    from fpsi_jax.build import disc_block
    from fpsi_jax.model.scene import SolidBlock
    d = disc_block(np.asarray(x, float), r, 1000.0, fixed=np.ones(len(x), bool))
    so = scene.solid
    if so is None:
        return dataclasses.replace(d, structure=np.asarray(structure, bool),
                                   grain=np.asarray(grain, bool), sph_volume=d.volumes())
    cat = lambda a, b: np.concatenate([np.asarray(a), np.asarray(b)])
    return SolidBlock(x=cat(so.x, d.x), v=cat(so.v, d.v), omega=cat(so.omega, d.omega),
                      radius=cat(so.radius, d.radius), mass=cat(so.mass, d.mass),
                      inertia=cat(so.inertia, d.inertia), fixed=cat(so.fixed, d.fixed),
                      f_ext=cat(so.f_ext, d.f_ext),
                      structure=cat(real_structure, structure), grain=cat(real_grain, grain),
                      sph_volume=cat(so.volumes(), d.volumes()))


def masked_scene(scene, phys, dt):
    """(scene with the inert dummies, its Physics overrides, its Params, the dummies added,
    notes on what could not be forced): see the module docstring. ``phys`` is the
    specialised Physics, ``dt`` its time step."""
    from fpsi_jax.model.params import BondParams, DemParams, FpiParams
    from fpsi_jax.model.scene import BondBlock, WallBlock
    so = scene.solid
    r_real = float(np.max(so.radius)) if so is not None else 0.0
    h_real = float(np.max(scene.fluid.h)) if scene.fluid is not None else 0.0
    r = r_real if so is not None else 0.4 * h_real         # dummy disc radius
    s = r_real                                              # dummy fluid spacing
    gap = _reach(max(r_real, r), h_real or 1.25 * s)
    lo, hi = np.asarray(scene.domain_lo, float), np.asarray(scene.domain_hi, float)
    x, y0 = lo[0] + gap, hi[1] + gap
    top = y0 + 2 * r
    new, added, notes = {}, [], []
    params = scene.params
    opts = dict(xsph=True, anticlump=True, variable_h=True, delta_sph=True,
                artificial_viscosity=True, wall_repulsion=True,
                dem_substeps=phys.dem_substeps)
    if scene.fluid is None:
        fluid, boundary, sp, w, hgt = _dummy_tank(x, y0, s, dt, params.gravity)
        new.update(fluid=fluid, boundary=boundary)
        params = params.replace(sph=sp)
        opts.update(boundary_pressure="extrapolated", anticlump_boundary=True)
        added.append(f"fluid tank ({fluid.n} fluid, {boundary.n} boundary)")
        x, top = x + w + gap, max(top, y0 + hgt)
    else:
        sp = params.sph
        for switch, coef in SPH_SWITCHES.items():
            if not getattr(phys, switch):
                sp = sp.replace(**{coef: 0.0})
                notes.append(f"{switch} forced on with sph.{coef} = 0")
        params = params.replace(sph=sp)
        if not phys.variable_h:
            notes.append("variable_h not forced (no coefficient turns it off)")
        if phys.has_boundary and phys.boundary_pressure != "extrapolated":
            notes.append("extrapolated boundary not forced (no coefficient)")
        if phys.anticlump and not phys.anticlump_boundary:
            notes.append("anticlump_boundary not forced (r_clump is shared with "
                         "fluid-fluid pairs)")
    xd, structure, grain = [], [], []
    bonds, walls = scene.bonds, scene.walls
    n_real = so.n if so is not None else 0
    if scene.bonds is None:
        xd += [(x + r, y0 + r), (x + 3 * r, y0 + r)]
        structure += [False, False]
        grain += [False, False]
        bonds = BondBlock(i=np.array([n_real], np.int32), j=np.array([n_real + 1], np.int32))
        params = params.replace(bond=BondParams())
        added.append("bonded disc pair" if so is not None else "bonded disc pair (DEM list)")
        x += 4 * r + gap
    if not phys.has_fsi:
        xd.append((x + r, y0 + r))
        structure.append(True)
        grain.append(False)
        opts["fsi"] = "extrapolated"
        added.append("structure disc (fsi.extrapolated)")
        x += 2 * r + gap
    if not phys.has_fpi:
        if scene.fluid is None:
            xd.append((x + r, y0 + r))
            structure.append(False)
            grain.append(True)
            opts["fpi"] = True
            params = params.replace(fpi=FpiParams())
            added.append("grain (fpi)")
            x += 2 * r + gap
        else:
            notes.append("fpi not forced: with grains the pressure bracket changes "
                         "even at voidage 1 (no coefficient)")
    if scene.walls is None:
        a = np.array([[x, y0 + r]])
        walls = WallBlock(a=a, b=a + [2 * r, 0.0])
        added.append("wall segment")
        x += 2 * r + gap
    if xd:
        rs = np.zeros(n_real, bool)
        if so is not None and phys.has_fsi:
            rs[so.structure_indices()] = True
        rg = np.zeros(n_real, bool)
        if so is not None and phys.has_fpi:
            rg[so.grain_indices()] = True
        new["solid"] = _solid_with(scene, rs, rg, xd, r, structure, grain)
    if params.dem is None:
        params = params.replace(dem=DemParams())
    if not added:
        notes.append("nothing to add: the scene has every family that can be masked")
    hi_new = (max(hi[0], x + gap), top + gap)
    sc = dataclasses.replace(scene, params=params, bonds=bonds, walls=walls,
                             domain_hi=hi_new, **new)
    return sc.validate(), opts, params, added, notes


# --- one program ------------------------------------------------------------------------
def hlo_scopes(phys, state, params):
    """Mechanism scopes (``jax.named_scope``) in the lowered step, read from its op
    locations as tests/conftest.py's step_hlo does, and also from the locations inside loop
    bodies (the DEM sub-steps), which are relative ("dem.contacts/...", no "jit(step)/")."""
    import jax

    from fpsi_jax import solver
    text = jax.jit(solver.step, static_argnums=0).lower(phys, state, params).as_text(
        debug_info=True)
    scopes = set()
    for loc in re.findall(r'loc\("([^"]*)"', text):
        scopes.update(p for p in loc.split("/")
                      if p.startswith(SCOPES) and not p.endswith(".py"))
    return sorted(scopes)


def prepare(scene, steps, dt=None, params=None, unsafe_dt=False, **opts):
    """Setup, initial state, compiled chunk and warm-up (``_bench``), then one more chunk
    from the warm-up's end: the timed chunks start there, so their lists must not overflow
    either (grown, reallocated and recompiled by ``run_until_fits``, as the driver does).
    Returns a dict."""
    from _bench import compile_and_warm_up

    from fpsi_jax import solver
    from fpsi_jax.run.driver import run_until_fits, setup
    phys, prm = setup(scene, dt=dt, params=params, unsafe_dt=unsafe_dt, **opts)
    p = prm.as_arrays(solver.dtype(phys))
    st0 = solver.init_state(scene, phys, p)
    scopes = hlo_scopes(phys, st0, p)
    phys, warm, chunk, compile_s = compile_and_warm_up(phys, st0, p, steps)
    c = run_until_fits(chunk, phys, warm, chunk.dt)
    return dict(phys=c.phys, params=prm, p=p, warm=warm, start=c.state, chunk=chunk,
                compile_s=compile_s, scopes=scopes, times=[], end=None)


def run_chunk(prog):
    """Time one chunk from the program's post-warm-up state (compiled by ``prepare``)."""
    end, wall = prog["chunk"](prog["phys"], prog["start"])
    prog["times"].append(wall)
    prog["end"] = end


def max_diff(a, b, n_fluid, n_solid):
    """max |Δx|, |Δv| over the first ``n_fluid`` fluid particles and ``n_solid`` discs (the
    real ones) of two states."""
    d = {"x": 0.0, "v": 0.0}
    for phase, n in (("fluid", n_fluid), ("solid", n_solid)):
        for k in d if n else ():
            ua = np.asarray(getattr(getattr(a, phase), k))[:n]
            ub = np.asarray(getattr(getattr(b, phase), k))[:n]
            d[k] = max(d[k], float(np.max(np.abs(ua - ub))))
    return d["x"], d["v"]


def status(state):
    s = state.status
    return {"bad": bool(s.bad), "code": int(s.code), "step": int(s.step),
            "particle": int(s.particle), "overflow": bool(s.overflow)}


def summary(prog, steps):
    phys = prog["phys"]
    med = statistics.median(prog["times"])
    return {"mechanisms": list(phys.mechanisms()), "hlo_scopes": prog["scopes"],
            "sph_list": phys.neighbors is not None, "dem_list": phys.dem_neighbors is not None,
            "n_fluid": phys.n_fluid, "n_boundary": phys.n_boundary, "n_solid": phys.n_solid,
            "n_bonds": phys.n_bonds, "n_walls": phys.n_walls, "n_structure": phys.n_structure,
            "n_grain": phys.n_grain, "dem_substeps": phys.dem_substeps, "x64": phys.x64,
            "compile_s": prog["compile_s"], "chunk_s": prog["times"],
            "us_per_step": 1e6 * med / steps, "us_per_step_best": 1e6 * min(prog["times"]) / steps,
            "steps_per_s": steps / med, "status_end": status(prog["end"])}


# --- one scene (worker) -----------------------------------------------------------------
def bench_scene(label, target_s, min_rounds, max_rounds):
    from fpsi_jax.cases import build
    name, kw, popts, steps = CASES.get(label, (label, {}, {}, DEFAULT_STEPS))
    scene = build(name, **kw)
    spec = prepare(scene, steps, **popts)
    dt, sub = float(spec["params"].dt), spec["phys"].dem_substeps
    msc, opts, mparams, added, notes = masked_scene(scene, spec["phys"], dt)
    masked = prepare(msc, steps, dt=dt, params=mparams, unsafe_dt=True, **opts)
    ctrl_scene = dataclasses.replace(scene, domain_hi=msc.domain_hi)
    control = prepare(ctrl_scene, steps, dt=dt, **{**popts, "dem_substeps": sub})
    n_f, n_s = spec["phys"].n_fluid, spec["phys"].n_solid
    diffs = {f"{a}_vs_{b}": max_diff(x["warm"], y["warm"], n_f, n_s)
             for a, b, x, y in (("masked", "specialised", masked, spec),
                                ("control", "specialised", control, spec),
                                ("masked", "control", masked, control))}
    progs = {"specialised": spec, "masked": masked, "control": control}
    for prog in progs.values():
        run_chunk(prog)
    slowest = max(max(p["times"]) for p in progs.values())
    rounds = int(min(max_rounds, max(min_rounds, math.ceil(target_s / slowest))))
    for _ in range(rounds - 1):
        for prog in progs.values():
            run_chunk(prog)
    out = {k: summary(p, steps) for k, p in progs.items()}
    us = {k: out[k]["us_per_step"] for k in progs}
    best = {k: out[k]["us_per_step_best"] for k in progs}
    return {"case": label, "scene": name, "kwargs": kw, "physics_overrides": popts, "dt": dt,
            "steps": steps, "rounds": rounds, "masked_added": added, "masked_notes": notes,
            "masked_options": opts, "domain_hi": list(scene.domain_hi),
            "masked_domain_hi": list(msc.domain_hi),
            "added_mechanisms": [m for m in out["masked"]["mechanisms"]
                                 if m not in out["specialised"]["mechanisms"]],
            "compared_after_steps": steps,
            "max_abs_dx": {k: v[0] for k, v in diffs.items()},
            "max_abs_dv": {k: v[1] for k, v in diffs.items()},
            "speedup": us["masked"] / us["specialised"],
            "speedup_best": best["masked"] / best["specialised"],
            "masked_over_control": us["masked"] / us["control"],
            "control_over_specialised": us["control"] / us["specialised"], **out}


def worker(args):
    row = bench_scene(args.worker, args.target_s, args.min_rounds, args.max_rounds)
    print(MARK + json.dumps(row), flush=True)


# --- driver -----------------------------------------------------------------------------
def cases():
    """Every row of CASES, then every registered scene no row covers (defaults)."""
    from fpsi_jax.cases import SCENES
    covered = {c[0] for c in CASES.values()}
    return list(CASES) + [n for n in SCENES if n not in covered]


def run_worker(label, args):
    cmd = [sys.executable, os.path.abspath(__file__), "--worker", label,
           "--target-s", str(args.target_s), "--min-rounds", str(args.min_rounds),
           "--max-rounds", str(args.max_rounds)]
    pin = (lambda: os.sched_setaffinity(0, {args.cpu})) if args.cpu >= 0 else None
    t0 = time.perf_counter()
    res = subprocess.run(cmd, capture_output=True, text=True, cwd=os.path.dirname(HERE),
                         preexec_fn=pin)
    for line in res.stdout.splitlines():
        if line.startswith(MARK):
            row = json.loads(line[len(MARK):])
            row["wall_s"] = time.perf_counter() - t0
            return row
    return {"case": label, "error": (res.stderr or res.stdout)[-2000:]}


def _lists(r):
    return "+".join(n for n, k in (("SPH", "sph_list"), ("DEM", "dem_list")) if r[k]) or "none"


def _short(mechs):
    """Mechanism names grouped by family: sph(continuity, eos, ...) dem(...) bonds ..."""
    groups: dict = {}
    for m in mechs:
        fam, _, rest = m.partition(".")
        groups.setdefault(fam, []).append(rest)
    return " ".join(f"{f}({', '.join(r for r in rs if r)})" if any(rs) else f
                    for f, rs in groups.items())


HEAD = ("| case | real particles | compiled (specialised) | lists built | forced on in masked "
        "| specialised µs/step | masked µs/step | speed-up median (best) | control µs/step "
        "| masked / control | max abs Δx masked vs specialised (m) "
        "| max abs Δx masked vs control (m) |")


def table(rows):
    lines = [HEAD, "|" + "---|" * (HEAD.count("|") - 1)]
    for r in rows:
        if "error" in r:
            lines.append(f"| {r['case']} | error (see JSON) |" + " |" * (HEAD.count("|") - 3))
            continue
        s, m, c = r["specialised"], r["masked"], r["control"]
        n = s["n_fluid"] + s["n_boundary"] + s["n_solid"]
        dx = r["max_abs_dx"]
        lines.append(
            f"| {r['case']} | {n} | {_short(s['mechanisms'])} | {_lists(s)} "
            f"| {_short(r['added_mechanisms']) or 'nothing'} | {s['us_per_step']:.1f} "
            f"| {m['us_per_step']:.1f} | {r['speedup']:.2f} ({r['speedup_best']:.2f}) "
            f"| {c['us_per_step']:.1f} | {r['masked_over_control']:.2f} "
            f"| {dx['masked_vs_specialised']:.1e} | {dx['masked_vs_control']:.1e} |")
    return "\n".join(lines)


def notes(rows):
    """Per case: the dummies added and what could not be forced."""
    out = []
    for r in rows:
        if "error" not in r:
            out.append(f"- {r['case']} ({r['steps']}-step chunks, {r['rounds']} rounds): added "
                       f"{', '.join(r['masked_added']) or 'nothing'}"
                       + (f"; {'; '.join(r['masked_notes'])}" if r["masked_notes"] else ""))
    return "\n".join(out)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--scenes", nargs="*", default=None,
                    help="case labels (CASES) or scene names; default: all")
    ap.add_argument("--target-s", type=float, default=1.0,
                    help="timed seconds per program (sets the number of rounds)")
    ap.add_argument("--min-rounds", type=int, default=7)
    ap.add_argument("--max-rounds", type=int, default=40)
    ap.add_argument("--cpu", type=int, default=0,
                    help="core each worker is pinned to before Python starts; -1: not pinned")
    ap.add_argument("--worker", default=None, help=argparse.SUPPRESS)
    ap.add_argument("--out", default="specialisation", help="file stem in experiments/results")
    args = ap.parse_args()
    if args.worker:
        return worker(args)
    rows = []
    for label in args.scenes or cases():
        r = run_worker(label, args)
        rows.append(r)
        if "error" in r:
            print(f"{label}: ERROR\n{r['error']}", flush=True)
            continue
        print(f"{label:24s} spec {r['specialised']['us_per_step']:9.1f}  masked "
              f"{r['masked']['us_per_step']:9.1f}  control {r['control']['us_per_step']:9.1f}"
              f" µs/step  x{r['speedup']:.2f}  |dx| {r['max_abs_dx']['masked_vs_specialised']:.1e}"
              f"  ({r['rounds']} rounds, {r['wall_s']:.0f} s)", flush=True)
    md = table(rows) + "\n\n" + notes(rows)
    print(md)
    import jax
    out = {"machine": {"cpu_count": os.cpu_count(), "platform": platform.platform(),
                       "jax": jax.__version__, "backend": jax.default_backend(),
                       "note": "2-core VM shared with other work while measured; run under "
                               "nice -n 10", "pinned_cpu": args.cpu,
                       "loadavg_at_end": os.getloadavg()},
           "method": "experiments/specialisation.py (module docstring)", "rows": rows}
    os.makedirs(os.path.join(HERE, "results"), exist_ok=True)
    with open(os.path.join(HERE, "results", args.out + ".json"), "w") as fh:
        json.dump(out, fh, indent=1)
    with open(os.path.join(HERE, "results", args.out + ".md"), "w") as fh:
        fh.write(md + "\n")


if __name__ == "__main__":
    main()
