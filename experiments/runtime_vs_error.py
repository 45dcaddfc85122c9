"""Run time against error for four validation cases.

    python experiments/runtime_vs_error.py                    # full sweep (~30-40 min, 2 cores)
    python experiments/runtime_vs_error.py --quick --out /tmp/rve   # smoke test (~2 min)
    python experiments/runtime_vs_error.py --cases cantilever dam_break --resume
    python experiments/runtime_vs_error.py --report-only      # redo CSV / PNG / MD from the JSON

Cases and error measures (each from the registered ``fpsi validate`` case):

* cantilever          static tip deflection vs PL^3/(3EI)            |rel_error|
* hydrostatic_plate   settled midpoint deflection vs K44 + shear     |rel_error|
* dam_break           front Z(T) vs Koshizuka & Oka (1996), T <= 2.5  max rel. error
* elastic_gate        RMS of tip ux vs the experiment / experiment's peak ux (0-0.36 s)

Swept: resolution, time step (``dt_factor`` x the derived step) or DEM sub-steps
(``substeps_factor`` x the derived count), float32 vs float64 (``x64``) and the coupling
method. Each point runs in its own Python process (a fresh compile, no float64 flag left
over from an earlier point, a per-point timeout); the wall time is ``perf_counter`` around
the case call (scene build + compile + run), the CPU time ``process_time`` over the same
span (all threads: robust to other load, but > wall when XLA uses both cores).

The validation cases call ``simulate(scene, ...)`` without ``dt=``; the dt sweep here
therefore wraps ``simulate`` in the case modules and passes ``dt = dt_factor x derived``
explicitly, with ``unsafe_dt=True`` for factors above 1 (steps past the derived bound,
which the stability sweeps found 4.7-6.5x conservative). The wrapper also records the
step, sub-steps, compile time and dtype of the run actually made.

Writes (under --out, default experiments/results): runtime_vs_error.json (after every
point), runtime_vs_error.csv, runtime_vs_error_pareto.png, runtime_vs_error_pareto.md.
"""
from __future__ import annotations

import argparse
import csv
import json
import math
import os
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
OUT = os.path.join(HERE, "results")
STEM = "runtime_vs_error"
CASE_ORDER = ("cantilever", "hydrostatic_plate", "dam_break", "elastic_gate")
ERROR_NAME = {
    "cantilever": "|tip deflection / (PL³/3EI) − 1|",
    "hydrostatic_plate": "|midpoint deflection / (K44 + shear) − 1|",
    "dam_break": "max |Z/Z_K&O − 1|, T ≤ 2.5",
    "elastic_gate": "RMS(ux − ux_exp) / max ux_exp, 0–0.36 s",
}
TARGETS = (0.02, 0.05)

D3 = 5e-3 / 3          # 1.667 mm: divides the 5 mm beam / plate / gate thickness
PLATE = {"coarse": dict(dx=0.0035, d=0.0025, dx_boundary=0.0025, t_end=0.8),
         "medium": dict(dx=0.0025, d=D3, dx_boundary=D3),
         "seed": dict(dx=0.00175, d=0.00125, dx_boundary=0.00125)}
GATE = {"coarse": dict(dx=0.0035, d=0.0025, dx_boundary=0.0025, h0=0.004375),
        "medium": dict(dx=0.0025, d=D3, dx_boundary=D3, h0=1.25 * 0.0025),
        "seed": dict(dx=0.00175, d=0.00125, dx_boundary=0.00125, h0=0.0021875)}
COUPLINGS = ("extrapolated", "stationary", "pressure_gradient", "pressure_approximation")


def point(case, label, overrides=None, dt_factor=1.0, substeps_factor=None, timeout=1500):
    return {"case": case, "label": f"{case}:{label}", "overrides": dict(overrides or {}),
            "dt_factor": dt_factor, "substeps_factor": substeps_factor, "timeout": timeout}


def plan(quick: bool):
    """The sweep, cheapest first within each case (so a cut-off run keeps the cheap end)."""
    P = []
    if quick:
        P += [point("cantilever", "quick_d2.5_f64", {"d": 0.0025}),
              point("cantilever", "quick_d2.5_f32_dt0.5", {"d": 0.0025, "x64": False}, 0.5),
              point("hydrostatic_plate", "quick_coarse_t0.05",
                    {**PLATE["coarse"], "t_end": 0.05}),
              point("hydrostatic_plate", "quick_coarse_t0.05_sub2",
                    {**PLATE["coarse"], "t_end": 0.05}, substeps_factor=2),
              point("dam_break", "quick_dx0.02", {"dx": 0.02}),
              point("dam_break", "quick_dx0.02_dt0.5", {"dx": 0.02}, 0.5),
              point("elastic_gate", "quick_coarse_t0.05", {**GATE["coarse"], "t_end": 0.05})]
        return P
    # cantilever (default float64): d, float32 vs float64, dt at 1x / 0.5x at d = 2.5 mm
    for dname, d in (("2.5", 0.0025), ("1.667", D3), ("1.25", 0.00125)):
        for prec, x64 in (("f64", True), ("f32", False)):
            P.append(point("cantilever", f"d{dname}_{prec}", {"d": d, "x64": x64}))
            if dname == "2.5":
                P.append(point("cantilever", f"d{dname}_{prec}_dt0.5", {"d": d, "x64": x64},
                               0.5))
    P.append(point("cantilever", "d2.5_f64_dt2", {"d": 0.0025, "x64": True}, 2.0))
    # hydrostatic plate (default float64)
    for c in COUPLINGS:
        P.append(point("hydrostatic_plate", f"coarse_{c}", {**PLATE["coarse"], "coupling": c}))
    P.append(point("hydrostatic_plate", "coarse_f32", {**PLATE["coarse"], "x64": False}))
    P.append(point("hydrostatic_plate", "coarse_dt2", PLATE["coarse"], 2.0))
    P.append(point("hydrostatic_plate", "coarse_sub2", PLATE["coarse"], substeps_factor=2))
    P.append(point("hydrostatic_plate", "medium", PLATE["medium"]))
    # dam break (default float32)
    P += [point("dam_break", "dx0.02", {"dx": 0.02}),
          point("dam_break", "dx0.01", {"dx": 0.01}),
          point("dam_break", "dx0.01_f64", {"dx": 0.01, "x64": True}),
          point("dam_break", "dx0.01_dt0.5", {"dx": 0.01}, 0.5),
          point("dam_break", "dx0.01_dt2", {"dx": 0.01}, 2.0),
          point("dam_break", "dx0.005", {"dx": 0.005})]
    # elastic gate (default float32)
    for c in COUPLINGS:
        P.append(point("elastic_gate", f"coarse_{c}", {**GATE["coarse"], "coupling": c}))
    P.append(point("elastic_gate", "coarse_f64", {**GATE["coarse"], "x64": True}))
    P.append(point("elastic_gate", "coarse_sub2", GATE["coarse"], substeps_factor=2))
    P.append(point("elastic_gate", "medium", GATE["medium"]))
    # the two seed-resolution runs last (several minutes each)
    P.append(point("elastic_gate", "seed", GATE["seed"], timeout=1200))
    P.append(point("hydrostatic_plate", "seed", PLATE["seed"], timeout=1200))
    # run order: cantilever, dam break, the coarse gate and plate points, then the medium
    # and seed resolutions (so a cut-off sweep still has every case's cheap end)
    rank = {"cantilever": 0, "dam_break": 1, "elastic_gate": 2, "hydrostatic_plate": 3}
    tier = lambda p: 2 if p["label"].endswith(":seed") else 1 if p["label"].endswith(
        ":medium") else 0
    return sorted(P, key=lambda p: (tier(p), rank[p["case"]]))


# --- worker: one point, in its own process -----------------------------------------------
def _plain(v):
    """JSON-safe copy of a record's params (numpy scalars / small arrays)."""
    import numpy as np
    if isinstance(v, dict):
        return {str(k): _plain(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_plain(x) for x in v]
    if isinstance(v, (np.bool_, bool)):
        return bool(v)
    if isinstance(v, (np.integer,)):
        return int(v)
    if isinstance(v, (np.floating, float)):
        f = float(v)
        return f if math.isfinite(f) else str(f)
    if isinstance(v, np.ndarray):
        return _plain(v.tolist()) if v.size <= 16 else f"array{v.shape}"
    if v is None or isinstance(v, (int, str)):
        return v
    return str(v)


def worker(spec: dict) -> dict:
    import numpy as np  # noqa: F401
    from fpsi_jax.cases import CASES   # importing the package registers every case
    from fpsi_jax.cases import overrides as ov
    from fpsi_jax.model.config import Physics
    from fpsi_jax.run import stability
    from fpsi_jax.run import driver as sim_mod

    case, ovr = spec["case"], dict(spec["overrides"])
    base = {"variant": "tip"} if case == "cantilever" else {}
    extra = {}
    if spec.get("substeps_factor"):
        scene, phys = ov.build(case, ovr, base)
        dt0, n0 = stability.derived(scene, **phys)
        ovr["dem_substeps"] = int(round(spec["substeps_factor"] * n0))
        extra.update(derived_dt=dt0, derived_substeps=n0)

    captured = {}
    original = sim_mod.simulate
    factor = float(spec.get("dt_factor") or 1.0)

    def wrapped(scene, *args, dt=None, **kw):
        if dt is None and factor != 1.0:
            popts = {k: v for k, v in kw.items() if k in Physics.OPTIONS}
            _, p0 = sim_mod.setup(scene, **popts)
            captured["derived_dt"] = float(p0.dt)
            dt = factor * float(p0.dt)
        if factor > 1.0:
            kw["unsafe_dt"] = True
        res = original(scene, *args, dt=dt, **kw)
        captured.update(dt=float(res.params.dt), n_steps=int(res.n_steps),
                        dem_substeps=int(res.physics.dem_substeps),
                        x64=bool(res.physics.x64), compile_s=float(res.compile_s),
                        sim_wall_s=float(res.wall_s), n_fluid=int(res.physics.n_fluid),
                        n_boundary=int(res.physics.n_boundary),
                        n_solid=int(res.physics.n_solid))
        return res

    # every case module that calls the driver, wherever the case lives
    for name, mod in list(sys.modules.items()):
        if name.startswith("fpsi_jax.cases.") and getattr(mod, "simulate", None) is original:
            mod.simulate = wrapped

    out = {"overrides_passed": _plain(ovr), **extra}
    t0, c0 = time.perf_counter(), time.process_time()
    try:
        recs = CASES[case](quick=False, overrides=ovr)
    except Exception as e:  # SimulationError, ParameterError, ...
        out.update(status="failed", message=f"{type(e).__name__}: {e}",
                   wall_s=time.perf_counter() - t0, cpu_s=time.process_time() - c0,
                   run=captured)
        return out
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    r = recs[0]
    prm = r.params
    n_part = prm.get("n_particles", prm.get("n_discs"))
    if case == "elastic_gate":
        error = float(prm["rms_ux_rel_peak"])
        metrics = {k: prm[k] for k in ("rms_ux_rel_peak", "rms_uy_rel_peak", "peak_ux_m",
                                       "exp_peak_ux_m", "peak_ux_rel_error", "t_peak_s",
                                       "t_peak_error_s", "rms_ux_m", "rms_uy_m", "frames")}
    else:
        error = abs(float(r.rel_error))
        metrics = {"value": r.value, "reference": r.reference, "rel_error_signed": r.rel_error}
        for k in ("rel_error_vs_K44", "error_vs_as_built_span", "T_worst",
                  "last_10pct_change"):
            if k in prm:
                metrics[k] = prm[k]
    out.update(status="ok", message="", error=error, metrics=_plain(metrics),
               n_particles=int(n_part), steps=int(prm.get("steps", captured.get("n_steps"))),
               wall_s=wall, cpu_s=cpu, record_wall_s=float(r.wall_s), run=_plain(captured),
               record_params=_plain(prm))
    return out


# --- driver ------------------------------------------------------------------------------
def load(path):
    if os.path.exists(path):
        with open(path) as fh:
            return json.load(fh)
    return {"points": []}


def save(path, data):
    tmp = path + ".tmp"
    with open(tmp, "w") as fh:
        json.dump(data, fh, indent=1)
    os.replace(tmp, path)


def run_point(spec):
    load_before = os.getloadavg()[0]
    t0 = time.perf_counter()
    cmd = [sys.executable, os.path.abspath(__file__), "--worker", json.dumps(spec)]
    try:
        cp = subprocess.run(cmd, capture_output=True, text=True, timeout=spec["timeout"],
                            cwd=os.path.dirname(HERE))
        lines = [ln for ln in cp.stdout.splitlines() if ln.startswith("RESULT ")]
        if lines:
            res = json.loads(lines[-1][len("RESULT "):])
        else:
            res = {"status": "failed",
                   "message": f"worker exit {cp.returncode}: {cp.stderr.strip()[-800:]}"}
    except subprocess.TimeoutExpired:
        res = {"status": "failed", "message": f"timeout after {spec['timeout']} s (dropped)"}
    res["process_wall_s"] = time.perf_counter() - t0
    res["load1_before"] = load_before
    res["load1_after"] = os.getloadavg()[0]
    settings = dict(spec["overrides"])
    if spec.get("dt_factor", 1.0) != 1.0:
        settings["dt_factor"] = spec["dt_factor"]
    if spec.get("substeps_factor"):
        settings["substeps_factor"] = spec["substeps_factor"]
    row = {"case": spec["case"], "label": spec["label"], "settings": settings, **res}
    run = res.get("run") or {}
    for k in ("dt", "dem_substeps", "x64"):
        if k in run:
            row.setdefault(k, run[k])
    return row


# --- analysis ----------------------------------------------------------------------------
def ok_points(points, case):
    return [p for p in points if p["case"] == case and p.get("status") == "ok"
            and p.get("error") is not None and math.isfinite(p["error"])]


def pareto(points, cost="wall_s"):
    """Points not dominated in (cost, error), sorted by cost (wall_s or cpu_s)."""
    front = []
    for p in points:
        dominated = any(q is not p and q[cost] <= p[cost] and q["error"] <= p["error"]
                        and (q[cost] < p[cost] or q["error"] < p["error"])
                        for q in points)
        if not dominated:
            front.append(p)
    return sorted(front, key=lambda p: p[cost])


def short(p):
    return p["label"].split(":", 1)[1]


def settings_text(p):
    s = dict(p["settings"])
    s.pop("dt_factor", None)
    s.pop("substeps_factor", None)
    parts = []
    for k, v in s.items():
        if isinstance(v, float):
            v = f"{v:.4g}"
        parts.append(f"{k}={v}")
    if p.get("x64") is not None and "x64" not in s:
        parts.append(f"x64={p['x64']}")
    if p.get("dt") is not None:
        f = p["settings"].get("dt_factor")
        parts.append(f"dt={p['dt']:.3g}" + (f" (×{f})" if f else ""))
    if p.get("dem_substeps", 1) and p.get("dem_substeps", 1) > 1:
        f = p["settings"].get("substeps_factor")
        parts.append(f"substeps={p['dem_substeps']}" + (f" (×{f})" if f else ""))
    return ", ".join(parts)


def extra_text(p):
    """The case's secondary measure, for the guide line."""
    m = p.get("metrics") or {}
    if "error_vs_as_built_span" in m:
        return f"; vs the as-built span {m['error_vs_as_built_span']:+.2%}"
    if "rel_error_vs_K44" in m:
        return f"; signed {m['rel_error_signed']:+.2%}, vs K44 alone {m['rel_error_vs_K44']:+.2%}"
    if "T_worst" in m:
        return f"; worst at T = {m['T_worst']:.2f}"
    if "rms_uy_rel_peak" in m:
        return (f"; RMS uy / peak {m['rms_uy_rel_peak']:.1%}, peak ux "
                f"{m['peak_ux_rel_error']:+.1%}")
    return ""


def guide(points, case):
    pts = ok_points(points, case)
    if not pts:
        return [f"**{case}**: no successful point."]
    lines = []
    for tgt in TARGETS:
        hit = [p for p in pts if p["error"] <= tgt]
        if hit:
            p = min(hit, key=lambda p: p["wall_s"])
            lines.append(f"**{case}**, {tgt:.0%} error: use `{short(p)}` ({settings_text(p)}): "
                         f"{p['n_particles']} particles, {p['wall_s']:.1f} s wall "
                         f"({p['cpu_s']:.1f} s CPU); error {p['error']:.2%}{extra_text(p)}.")
        else:
            p = min(pts, key=lambda p: p["error"])
            lines.append(f"**{case}**, {tgt:.0%} error: not reached by any setting swept; "
                         f"best reachable {p['error']:.2%} with `{short(p)}` "
                         f"({settings_text(p)}): {p['n_particles']} particles, "
                         f"{p['wall_s']:.1f} s wall ({p['cpu_s']:.1f} s CPU){extra_text(p)}.")
    return lines


def report(path_json, outdir):
    data = load(path_json)
    pts = data["points"]
    cases = [c for c in CASE_ORDER if any(p["case"] == c for p in pts)]
    # CSV: every point
    cols = ["case", "label", "status", "error", "n_particles", "steps", "dt", "dem_substeps",
            "x64", "wall_s", "cpu_s", "record_wall_s", "load1_before", "load1_after",
            "settings", "message"]
    with open(os.path.join(outdir, f"{STEM}.csv"), "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(cols + ["compile_s", "rms_uy_rel_peak", "peak_ux_rel_error"])
        for p in pts:
            m = p.get("metrics") or {}
            row = [p.get(c) if c != "settings" else json.dumps(p["settings"]) for c in cols]
            w.writerow(row + [(p.get("run") or {}).get("compile_s"),
                              m.get("rms_uy_rel_peak"), m.get("peak_ux_rel_error")])
    # plot
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    n = max(1, len(cases))
    ncol = 2 if n > 1 else 1
    nrow = math.ceil(n / ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(6.2 * ncol, 4.8 * nrow), squeeze=False)
    for ax, case in zip(axes.flat, cases):
        ok = ok_points(pts, case)
        front = pareto(ok)
        ax.scatter([p["wall_s"] for p in ok], [max(p["error"], 1e-6) for p in ok],
                   c="0.6", s=25, label="all points", zorder=2)
        rest = sorted((p for p in ok if p not in front), key=lambda p: p["wall_s"])
        for k, p in enumerate(rest):   # alternate below / above: close points stay legible
            ax.annotate(short(p), (p["wall_s"], max(p["error"], 1e-6)), fontsize=6,
                        color="0.45", xytext=(3, -8 if k % 2 == 0 else 4),
                        textcoords="offset points")
        ax.plot([p["wall_s"] for p in front], [max(p["error"], 1e-6) for p in front], "o-",
                c="C3", ms=6, lw=1.5, label="Pareto front", zorder=3)
        for p in front:
            ax.annotate(short(p), (p["wall_s"], max(p["error"], 1e-6)), fontsize=7,
                        color="C3", xytext=(4, 3), textcoords="offset points")
        for tgt, ls in zip(TARGETS, (":", "--")):
            ax.axhline(tgt, c="k", lw=0.8, ls=ls, alpha=0.6, label=f"{tgt:.0%}")
        failed = [p for p in pts if p["case"] == case and p.get("status") != "ok"]
        if failed:
            ax.text(0.02, 0.98, "failed: " + ", ".join(short(p) for p in failed),
                    transform=ax.transAxes, fontsize=6, color="C1", va="top")
        ax.set_xscale("log")
        ax.set_yscale("log")
        from matplotlib.ticker import LogLocator, NullFormatter
        ws = [p["wall_s"] for p in ok] or [1.0]
        ax.set_xlim(min(ws) / 1.6, max(ws) * 2.5)
        ax.xaxis.set_minor_formatter(NullFormatter())
        ax.yaxis.set_minor_formatter(NullFormatter())
        ax.xaxis.set_major_locator(LogLocator(base=10, subs=(1.0, 2.0, 5.0)))
        ax.set_xlabel("wall time [s] (build + compile + run, shared 2-core CPU)")
        ax.set_ylabel(ERROR_NAME[case], fontsize=8)
        ax.set_title(case)
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=7, loc="best")
    for ax in list(axes.flat)[len(cases):]:
        ax.axis("off")
    fig.suptitle("fpsi-jax: error vs wall time (log–log)")
    fig.tight_layout()
    fig.savefig(os.path.join(outdir, f"{STEM}_pareto.png"), dpi=130)
    plt.close(fig)
    # markdown
    L = ["# Run time against error", "",
         "Generated by `experiments/runtime_vs_error.py` from `runtime_vs_error.json`. "
         "Wall time: `perf_counter` around the validation case call (scene build + JIT "
         "compile + run), each point in a fresh process, on a shared 2-core CPU (other jobs "
         "running; see the load averages in the CSV). CPU: `process_time` over the same "
         "span (all threads).", "",
         "Errors: " + "; ".join(f"{c}: {ERROR_NAME[c]}" for c in cases) + ".", "",
         "## Pareto points (not dominated in wall time and error)", "",
         "| case | point | settings | particles | steps | wall s | CPU s | error |",
         "|---|---|---|---:|---:|---:|---:|---:|"]
    for case in cases:
        for p in pareto(ok_points(pts, case)):
            L.append(f"| {case} | `{short(p)}` | {settings_text(p)} | {p['n_particles']} | "
                     f"{p['steps']} | {p['wall_s']:.1f} | {p['cpu_s']:.1f} | "
                     f"{p['error']:.2%} |")
    L += ["", "Wall times of the cheap points are dominated by compilation (2–9 s) and by the "
          "load of other jobs, so wall-time differences under ~20 % are noise. The same "
          "front in CPU seconds (`process_time`, less sensitive to the load):", "",
          "| case | point | particles | wall s | CPU s | error |",
          "|---|---|---:|---:|---:|---:|"]
    for case in cases:
        for p in pareto(ok_points(pts, case), "cpu_s"):
            L.append(f"| {case} | `{short(p)}` | {p['n_particles']} | {p['wall_s']:.1f} | "
                     f"{p['cpu_s']:.1f} | {p['error']:.2%} |")
    L += ["", "## Guide", "",
          "Cheapest swept setting (by wall time) reaching the target, or the best error "
          "reached when none does:", ""]
    for case in cases:
        for ln in guide(pts, case):
            L.append(f"- {ln}")
    L += ["", "## All points", "",
          "| case | point | status | particles | steps | wall s | CPU s | load1 before/after "
          "| error |", "|---|---|---|---:|---:|---:|---:|---|---:|"]
    for p in pts:
        err = f"{p['error']:.2%}" if p.get("status") == "ok" else "—"
        L.append(f"| {p['case']} | `{short(p)}` | {p.get('status')} | "
                 f"{p.get('n_particles', '—')} | {p.get('steps', '—')} | "
                 f"{p.get('wall_s', float('nan')):.1f} | {p.get('cpu_s', float('nan')):.1f} | "
                 f"{p['load1_before']:.1f}/{p['load1_after']:.1f} | {err} |")
    failed = [p for p in pts if p.get("status") != "ok"]
    if failed:
        L += ["", "## Failed points", ""]
        for p in failed:
            L.append(f"- `{p['label']}` ({settings_text(p)}): {p.get('message', '')}")
    gate = [p for p in pts if p["case"] == "elastic_gate" and p.get("status") == "ok"]
    if gate:
        L += ["", "## Elastic gate: the other measures", "",
              "| point | RMS ux / peak | RMS uy / peak | peak ux error | t_peak error [s] |",
              "|---|---:|---:|---:|---:|"]
        for p in gate:
            m = p["metrics"]
            L.append(f"| `{short(p)}` | {m['rms_ux_rel_peak']:.2%} | "
                     f"{m['rms_uy_rel_peak']:.2%} | {m['peak_ux_rel_error']:+.2%} | "
                     f"{m['t_peak_error_s']:+.4f} |")
    with open(os.path.join(outdir, f"{STEM}_pareto.md"), "w") as fh:
        fh.write("\n".join(L) + "\n")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cases", nargs="*", default=list(CASE_ORDER), choices=CASE_ORDER)
    ap.add_argument("--quick", action="store_true", help="tiny smoke sweep")
    ap.add_argument("--resume", action="store_true", help="skip labels already in the JSON")
    ap.add_argument("--retry-failed", action="store_true",
                    help="with --resume: run the failed labels again")
    ap.add_argument("--only", nargs="*", help="run only these labels (case:tag)")
    ap.add_argument("--out", default=OUT)
    ap.add_argument("--report-only", action="store_true")
    ap.add_argument("--worker", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker:
        res = worker(json.loads(args.worker))
        print("RESULT " + json.dumps(res), flush=True)
        return
    os.makedirs(args.out, exist_ok=True)
    path = os.path.join(args.out, f"{STEM}.json")
    if args.report_only:
        report(path, args.out)
        return
    data = load(path) if args.resume else {"points": []}
    done = {p["label"] for p in data["points"]
            if not (args.retry_failed and p.get("status") != "ok")}
    data["points"] = [p for p in data["points"] if p["label"] in done]
    todo = [s for s in plan(args.quick) if s["case"] in args.cases and s["label"] not in done
            and (not args.only or s["label"] in args.only)]
    data.setdefault("started", time.strftime("%Y-%m-%d %H:%M:%S"))
    data["host"] = {"cpus": os.cpu_count(), "python": sys.version.split()[0]}
    t_all = time.perf_counter()
    print(f"{len(todo)} points to run ({len(done)} kept)", flush=True)
    try:
        for i, spec in enumerate(todo):
            print(f"[{i + 1}/{len(todo)}] {spec['label']} {spec['overrides']} "
                  f"dt×{spec['dt_factor']} sub×{spec['substeps_factor']} ...", flush=True)
            row = run_point(spec)
            data["points"].append(row)
            data["sweep_wall_s"] = data.get("sweep_wall_s", 0.0) + row["process_wall_s"]
            save(path, data)
            if row["status"] == "ok":
                print(f"    ok: error {row['error']:.4%}, {row['n_particles']} particles, "
                      f"{row['steps']} steps, wall {row['wall_s']:.1f} s, cpu "
                      f"{row['cpu_s']:.1f} s, load {row['load1_before']:.1f}->"
                      f"{row['load1_after']:.1f}", flush=True)
            else:
                print(f"    FAILED: {row['message'][:300]}", flush=True)
    finally:
        data["finished"] = time.strftime("%Y-%m-%d %H:%M:%S")
        save(path, data)
        report(path, args.out)
        print(f"done in {time.perf_counter() - t_all:.0f} s; wrote {args.out}/{STEM}.*",
              flush=True)


if __name__ == "__main__":
    main()
