"""Soak: every shipped scene run to three times its default end time.

For each registered scene (and each example scene file with ``--files``) this runs
``simulate`` to 3 × t_end and reports the time reached, the particles that left through an
open side (and their mass), the largest particle speed over the run and the mechanical energy
of the particles still in the computation,

    E = Σ ½ m |v|² + Σ ½ I ω² − Σ m g·x      (per unit thickness, J/m)

at the start and the end (fluid and discs; the bonds' elastic energy is not included). A
run that goes unstable is reported with its diagnosis, not hidden.

    python experiments/soak.py                  # every scene at its default resolution
    python experiments/soak.py --coarse         # the coarse versions the tests use
    python experiments/soak.py dam_break elastic_gate --factor 3

The dam break runs to at least 2 s. Scenes without a coarse version (COARSE) are the same
run in both modes.

Writes experiments/results/soak[_coarse].csv (one row per scene; rows of scenes not run
this time are kept).
"""
from __future__ import annotations

import argparse
import csv
import glob
import os
import sys
import time

import numpy as np

from fpsi_jax import cases
from fpsi_jax.cases.elastic_gate import GATE_COARSE
from fpsi_jax.model.errors import SimulationError
from fpsi_jax.run import observers
from fpsi_jax.run.driver import simulate

RESULTS = os.path.join(os.path.dirname(__file__), "results")

#: scenes that must run longer than factor × t_end: the dam break to 2 s (the run-up jet,
#: its fall and the sloshing after it)
AT_LEAST = {"dam_break": 2.0}

#: coarse keyword arguments per scene (the tests' versions); scenes not named run as built
COARSE = {
    "hydrostatic_tank": dict(dx=0.02),
    "dam_break": dict(dx=0.01),
    "hydrostatic_plate": dict(dx=0.0035, d=0.0025, dx_boundary=0.0025),
    "elastic_gate": dict(GATE_COARSE),
    "gate_failure": dict(GATE_COARSE),
}


def soak(name, scene, factor):
    t_end = max(factor * scene.t_end, AT_LEAST.get(name, 0.0))
    row = {"scene": name, "particles": scene.n_particles, "t_end_default": scene.t_end,
           "t_target": t_end, "open_sides": " ".join(map(str, scene.open_sides)) or "-"}
    t0 = time.perf_counter()
    try:
        res = simulate(scene, t_end=t_end, progress=False, observe=observers.energy_and_speed(scene.params.gravity))
        obs = np.asarray(res.observations, float)
        row.update(t_reached=res.n_steps * float(res.params.dt), status="ok", message="")
        state = res.state
    except SimulationError as e:
        row.update(t_reached=e.time, status="unstable", message=str(e))
        obs, state = None, None
    row["wall_s"] = round(time.perf_counter() - t0, 1)
    if obs is not None and len(obs):
        row.update(E_start=obs[0, 0], E_end=obs[-1, 0], max_speed=obs[:, 1].max())
        left = [(b, np.asarray(b.t_out) >= 0) for b in (state.fluid, state.solid)
                if b is not None and b.t_out is not None]
        row["excluded"] = int(sum(k.sum() for _, k in left))
        row["mass_out"] = float(sum(np.asarray(b.mass)[k].sum() for b, k in left))
    return row


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenes", nargs="*", help="scene names (default: all registered)")
    ap.add_argument("--coarse", action="store_true", help="the tests' coarse versions")
    ap.add_argument("--factor", type=float, default=3.0, help="multiple of t_end")
    ap.add_argument("--files", action="store_true", help="also examples/*.toml")
    args = ap.parse_args(argv)
    names = args.scenes or list(cases.SCENES)
    out = os.path.join(RESULTS, "soak_coarse.csv" if args.coarse else "soak.csv")
    kept = []          # rows of scenes not run now stay in the file
    if os.path.exists(out):
        with open(out, newline="") as fh:
            kept = [r for r in csv.DictReader(fh) if r["scene"] not in names]
    rows = []
    jobs = [(n, lambda n=n: cases.build(n, **(COARSE.get(n, {}) if args.coarse else {})))
            for n in names if n in cases.SCENES]
    if args.files:
        from fpsi_jax import scenefile
        for path in sorted(glob.glob(os.path.join(os.path.dirname(__file__), "..",
                                                  "examples", "*.toml"))):
            jobs.append((os.path.basename(path), lambda p=path: scenefile.load(p).scene))
    for name, make in jobs:
        row = soak(name, make(), args.factor)
        rows.append(row)
        print({k: (round(v, 4) if isinstance(v, float) else v) for k, v in row.items()},
              flush=True)
        keys = sorted({k for r in rows + kept for k in r},
                      key=lambda k: list(row).index(k) if k in row else 99)
        os.makedirs(RESULTS, exist_ok=True)
        with open(out, "w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=keys)
            w.writeheader()
            w.writerows(kept + rows)
    bad = [r["scene"] for r in rows if r["status"] != "ok"]
    print(f"wrote {out}; {len(rows) - len(bad)}/{len(rows)} reached {args.factor:g} x t_end"
          + (f"; unstable: {', '.join(bad)}" if bad else ""))
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
