"""Stability stress tests.

    python experiments/stability.py                 # everything (~30 min on 2 cores)
    python experiments/stability.py --what dt stiffness tank10 overlap impact break

* dt         the time step swept past the derived bound, per case: where does each blow up,
             against the step the code derives (which must be stable, and within a factor 2
             of the largest stable one);
* stiffness  the bond (cantilever) and contact (dry dam break) stiffness over 4 decades,
             each at multiples of its derived step: the stability map (PNG);
* tank10     10 s of the hydrostatic tank: max |v| against √(gH) throughout, energy drift;
* overlap    discs started 50 % overlapping, two fluid particles started at one point;
* impact     a grain hitting a wall at 10 m/s: restitution, largest overlap / R;
* break      bonds breaking en masse (the failing gate with 1 kPa bonds).

Writes experiments/results/stability.json (merged per section), stability_map.png,
stability_tank10.png.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import time

import numpy as np

from fpsi_jax.cases import build
from fpsi_jax.cases.elastic_gate import GATE_COARSE
from fpsi_jax.model.errors import SimulationError
from fpsi_jax.run import stability
from fpsi_jax.run.driver import simulate

HERE = os.path.dirname(os.path.abspath(__file__))
OUT = os.path.join(HERE, "results")

# case: (scene, builder keywords, t_end, sweep the DEM sub-step instead of the step,
#        speed limit or None for the probe's default 10 × the velocity scale)
# The wall impact's limit is its impact speed: a damped contact that sends the grain back
# faster than it came has created energy (at 3 × the derived step the rebound is 1.6 × the
# impact speed, finite but wrong), which counts as unstable.
DT_CASES = {
    "hydrostatic_tank": ("hydrostatic_tank", {"dx": 0.01}, 1.0, False, None),
    "dam_break": ("dam_break", {"dx": 0.01}, 0.4, False, None),
    "cantilever_free": ("cantilever", {"d": 0.0025, "variant": "free"}, 0.03, False, None),
    "dry_dam_break": ("dry_dam_break", {}, 0.2, False, None),
    "wall_impact_10ms": ("wall_impact", {"speed": 10.0}, None, False, 10.0 * 1.001),
    "elastic_gate_dem": ("elastic_gate", GATE_COARSE, 0.1, True, None),
    "elastic_gate_sph": ("elastic_gate", GATE_COARSE, 0.1, False, None),
    "sedimentation": ("sedimentation", {}, 0.3, False, None),
    "two_phase_dam_break": ("two_phase_dam_break", {}, 0.15, False, None),
}
FACTORS = (0.5, 1.0, 1.25, 1.5, 1.75, 2.0, 2.5, 3.0, 4.0, 5.0, 6.0, 8.0)


def save(section, data):
    os.makedirs(OUT, exist_ok=True)
    path = os.path.join(OUT, "stability.json")
    allr = json.load(open(path)) if os.path.exists(path) else {}
    allr[section] = data
    with open(path, "w") as fh:
        json.dump(allr, fh, indent=1, default=float)


def load(section):
    path = os.path.join(OUT, "stability.json")
    return json.load(open(path)).get(section, {}) if os.path.exists(path) else {}


def dt_sweep(names):
    out = load("dt")                       # other cases' rows are kept
    for name in names:
        scene_name, kw, t_end, dem, v_limit = DT_CASES[name]
        sc = build(scene_name, **kw)
        t_end = t_end or sc.t_end
        t0 = time.perf_counter()
        rows = stability.sweep(sc, t_end, FACTORS, dem=dem, refine=3, v_limit=v_limit)
        best = stability.largest_stable(rows)
        dt0, n0 = stability.derived(sc)
        out[name] = {"scene": scene_name, "kwargs": kw, "t_end": t_end, "derived_dt": dt0,
                     "derived_dem_substeps": n0, "swept": "DEM sub-step" if dem else "dt",
                     "largest_stable_factor": best,
                     # factor ≤ 1: the derived step itself (a DEM sweep's derived sub-step
                     # count lands at a factor just under 1)
                     "derived_is_stable": (any(p.factor <= 1.0 + 1e-9 for p in rows) and all(
                         p.stable for p in rows if p.factor <= 1.0 + 1e-9)),
                     "within_factor_2": 0 < best <= 2.0 + 1e-9 or best == 0,
                     "rows": [p.as_dict() for p in rows], "wall_s": time.perf_counter() - t0}
        print(f"{name:20s} derived dt {dt0:.3g} s (×{n0})  largest stable factor {best}  "
              + "  ".join(f"{p.factor:g}:{'ok' if p.stable else 'X'}" for p in rows),
              flush=True)
        save("dt", out)
    return out


def stiffness_map():
    """Cantilever bond stiffness (E) and dry-dam-break contact stiffness over 4 decades
    (×0.01 … ×100), each at factors of its own derived step."""
    out = {}
    for label, scene_name, key, base, kw, t_end in (
            ("cantilever E", "cantilever", "E", 1.0e7, {"d": 0.0025, "variant": "free"},
             None),
            ("dry dam break k_n", "dry_dam_break", "kn", 69.0e9, {}, 0.05)):
        rows = []
        for s in (0.01, 0.1, 1.0, 10.0, 100.0):
            sc = build(scene_name, **{**kw, key: base * s})
            te = t_end or min(sc.t_end, 0.02)
            probes = stability.sweep(sc, te, (1.0, 1.25, 1.5, 1.75, 2.0, 2.5, 3.0))
            rows.append({"scale": s, key: base * s, "derived_dt": stability.derived(sc)[0],
                         "largest_stable_factor": stability.largest_stable(probes),
                         "probes": [p.as_dict() for p in probes]})
            print(f"{label:18s} ×{s:<6g} derived {rows[-1]['derived_dt']:.3g} s  "
                  + "  ".join(f"{p.factor:g}:{'ok' if p.stable else 'X'}" for p in probes),
                  flush=True)
        out[label] = rows
        save("stiffness", out)
    plot_map(out)
    return out


def plot_map(out):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, len(out), figsize=(5.5 * len(out), 4), squeeze=False)
    for ax, (label, rows) in zip(axes[0], out.items()):
        for r in rows:
            for p in r["probes"]:
                ax.scatter(r["scale"], p["factor"], marker="o" if p["stable"] else "x",
                           c="tab:green" if p["stable"] else "tab:red", s=50)
        ax.axhline(1.0, color="k", lw=0.8, ls="--", label="derived Δt")
        ax.axhline(2.0, color="grey", lw=0.8, ls=":", label="2 × derived")
        ax.set_xscale("log")
        ax.set_xlabel(f"{label} / default")
        ax.set_ylabel("Δt / derived Δt")
        ax.set_title(f"{label}: o stable, x unstable")
        ax.legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    fig.savefig(os.path.join(OUT, "stability_map.png"), dpi=120)


def tank10(dx=0.01, t_end=10.0):
    import jax.numpy as jnp
    sc = build("hydrostatic_tank", dx=dx, t_end=t_end)
    g = 9.81
    H = sc.builder_kwargs["depth"]
    sp = sc.params.sph
    B = float(sp.c0) ** 2 * float(sp.rho0) / float(sp.gamma)
    gam, rho0 = float(sp.gamma), float(sp.rho0)

    def observe(s):
        f = s.fluid
        v2 = jnp.sum(f.v * f.v, axis=1)
        ek = 0.5 * jnp.sum(f.mass * v2)
        ep = jnp.sum(f.mass * g * f.x[:, 1])
        # Tait internal energy per unit mass, u = ∫P/ρ² dρ (zero at ρ0)
        r = f.rho / rho0
        u = B / rho0 * ((r ** (gam - 1) - 1) / (gam - 1) + (1 / r - 1))
        ei = jnp.sum(f.mass * u)
        return jnp.stack([jnp.sqrt(jnp.max(v2)), ek, ep, ei])

    t0 = time.perf_counter()
    res = simulate(sc, t_end, observe=observe, every=0.5, progress=False)
    wall = time.perf_counter() - t0
    o = np.asarray(res.observations, float)
    t = (np.arange(len(o)) + 1) * float(res.params.dt)
    vref = math.sqrt(g * H)
    e = o[:, 1] + o[:, 2] + o[:, 3]
    m_gH = float(np.sum(np.asarray(sc.fluid.mass))) * g * H
    vmax = o[:, 0] / vref
    after = t >= 0.5
    out = {"dx": dx, "t_end": t_end, "n_fluid": sc.fluid.n, "steps": res.n_steps,
           "wall_s": wall, "sqrt_gH": vref,
           "max_v_over_sqrt_gH_throughout": float(vmax.max()),
           "t_of_max": float(t[np.argmax(vmax)]),
           "max_v_over_sqrt_gH_after_0.5s": float(vmax[after].max()),
           "max_v_over_sqrt_gH_at_end": float(vmax[-1]),
           "within_1pct_throughout": bool(vmax.max() < 0.01),
           "energy_drift_over_m_g_H": float((e[-1] - e[0]) / m_gH),
           "energy_min_max_over_m_g_H": [float((e.min() - e[0]) / m_gH),
                                         float((e.max() - e[0]) / m_gH)],
           "kinetic_max_over_m_g_H": float(o[:, 1].max() / m_gH)}
    print(json.dumps(out), flush=True)
    save("tank10", out)
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(1, 2, figsize=(10, 3.5))
    k = max(1, len(t) // 4000)
    ax[0].semilogy(t[::k], vmax[::k])
    ax[0].axhline(0.01, color="r", ls="--", label="1 % of √(gH)")
    ax[0].set_xlabel("t [s]"); ax[0].set_ylabel("max |v| / √(gH)"); ax[0].legend()
    ax[1].plot(t[::k], (e[::k] - e[0]) / m_gH)
    ax[1].set_xlabel("t [s]"); ax[1].set_ylabel("(E − E₀) / (M g H)")
    fig.suptitle(f"hydrostatic tank, dx = {dx * 1e3:g} mm, {t_end:g} s")
    fig.tight_layout()
    fig.savefig(os.path.join(OUT, "stability_tank10.png"), dpi=120)
    return out


def _outcome(fn):
    t0 = time.perf_counter()
    try:
        r = fn()
        return {"outcome": "ran", **r, "wall_s": time.perf_counter() - t0}
    except SimulationError as e:
        return {"outcome": "stopped", "diagnosis": str(e), "wall_s": time.perf_counter() - t0}


def overlap():
    out = {}

    def discs():
        sc = build("collision", radius=0.005, speed=0.01, kn=1.0e5, beta=0.1,
                          gap=-0.005, t_end=0.01)        # 50 % of R overlap at rest
        res = simulate(sc, progress=False)
        v = np.asarray(res.state.solid.v)
        m = np.asarray(sc.solid.mass)
        return {"final_speeds": np.linalg.norm(v, axis=1).tolist(),
                "momentum": (m[:, None] * v).sum(0).tolist(), "finite": bool(np.isfinite(v).all())}

    def fluid():
        sc = build("dam_break", dx=0.01, t_end=0.1)
        sc.fluid.x[1] = sc.fluid.x[0]                   # two particles at one point
        res = simulate(sc, progress=False)
        v = np.asarray(res.state.fluid.v)
        return {"max_speed": float(np.linalg.norm(v, axis=1).max()),
                "pair_distance_end_over_dx": float(np.linalg.norm(
                    np.asarray(res.state.fluid.x[0] - res.state.fluid.x[1])) / 0.01),
                "finite": bool(np.isfinite(v).all())}

    out["discs_50pct_overlap"] = _outcome(discs)
    out["fluid_coincident_pair"] = _outcome(fluid)
    print(json.dumps(out), flush=True)
    save("overlap", out)
    return out


def impact():
    out = {}
    for angle in (0.0, 45.0):
        sc = build("wall_impact", speed=10.0, angle=angle)
        r = float(sc.solid.radius[0])
        beta = float(sc.params.dem.beta_n)

        def run():
            import jax.numpy as jnp

            def observe(s):
                return jnp.stack([s.solid.x[0, 1], s.solid.v[0, 0], s.solid.v[0, 1]])
            res = simulate(sc, observe=observe, progress=False)
            o = np.asarray(res.observations)
            e = o[-1, 2] / (10.0 * math.cos(math.radians(angle)))
            e_ref = math.exp(-math.pi * beta / math.sqrt(1 - beta ** 2))
            return {"restitution": float(e), "restitution_analytic": e_ref,
                    "rel_error": float(e / e_ref - 1),
                    "max_overlap_over_R": float((r - o[:, 0].min()) / r),
                    "tangential_speed_kept": float(o[-1, 1] / (10 * math.sin(math.radians(angle))))
                    if angle else None,
                    "dt": float(res.params.dt), "steps": res.n_steps}
        out[f"angle_{angle:g}"] = _outcome(run)
    print(json.dumps(out), flush=True)
    save("impact", out)
    return out


def mass_break():
    sc = build("gate_failure", **GATE_COARSE, sigma_c=1.0e3, tau_c=1.0e3, t_end=0.1)

    def run():
        res = simulate(sc, progress=False)
        b = res.state.bonds
        intact = np.asarray(b.intact)
        tb = np.asarray(b.t_break)[~intact]
        return {"bonds": int(intact.size), "broken": int((~intact).sum()),
                "first_break_s": float(tb.min()) if tb.size else None,
                "last_break_s": float(tb.max()) if tb.size else None,
                "disc_max_speed": float(np.linalg.norm(np.asarray(res.state.solid.v),
                                                       axis=1).max()),
                "finite": bool(np.isfinite(np.asarray(res.state.solid.x)).all()),
                "steps": res.n_steps}
    out = _outcome(run)
    print(json.dumps(out), flush=True)
    save("break", out)
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--what", nargs="*",
                    default=["dt", "stiffness", "tank10", "overlap", "impact", "break"])
    ap.add_argument("--cases", nargs="*", default=list(DT_CASES))
    ap.add_argument("--tank-dx", type=float, default=0.01)
    ap.add_argument("--in-process", action="store_true",
                    help="run the dt cases in this process (default: one fresh process per "
                         "case; one long process that compiles hundreds of programs ran out "
                         "of LLVM code memory)")
    a = ap.parse_args()
    for w in a.what:
        if w == "dt" and (a.in_process or len(a.cases) == 1):
            dt_sweep(a.cases)
        elif w == "dt":
            import subprocess
            import sys
            for c in a.cases:
                subprocess.run([sys.executable, os.path.abspath(__file__), "--what", "dt",
                                "--cases", c], check=False)
        elif w == "stiffness":
            stiffness_map()
        elif w == "tank10":
            tank10(a.tank_dx)
        elif w == "overlap":
            overlap()
        elif w == "impact":
            impact()
        elif w == "break":
            mass_break()


if __name__ == "__main__":
    main()
