"""Speed of the DEM solver: steps/s and particle-steps/s for the bonded cantilever (static
tip-load case, float64) at d = 1.25 mm (268 discs, 465 bonds) and d = 2.5 mm, and for the
dry dam break (33 free discs, 3 walls, float32), with compile time and neighbour rebuilds.

    .venv/bin/python experiments/bench_dem.py [--steps 20000] [--dam-steps 50000] [--repeats 3]
    taskset -c 0 .venv/bin/python experiments/bench_dem.py        # as recorded (pinned)

Writes experiments/results/bench_dem.json. Each case: compile (timed alone), one warm-up
chunk of the same length (excluded: the first chunk), then ``--repeats`` timed chunks that
continue the run; steps/s is the median over them (best and all are recorded too). A chunk
whose neighbour lists overflow is grown and redone (``run_until_fits``, as the driver
does); the redone chunk is the recompiled program's warm-up and the timing starts again
from its end.
Particle count = all discs, clamped ones included. The float32 case runs first because the
float64 scenes switch jax_enable_x64 on for the rest of the process.

Timings on the shared 2-core VM this was written on are noisy from one process to the
next: unpinned, the dam break ran at either ~52k or ~100k steps/s (about half the processes
each), the cantilevers at 5.7k-6.3k (d = 1.25 mm) and 72k-91k (d = 2.5 mm) steps/s. Under
``taskset -c 0`` (set before Python starts) the dam break was ~100k every time (17 of 17 processes);
pinning from inside the process after ``import jax`` did not help. Cause not established.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import statistics

import jax

from fpsi_jax import cases, solver
from fpsi_jax.run.driver import setup

from _bench import compile_and_warm_up, timed_chunks

HERE = os.path.dirname(os.path.abspath(__file__))


def bench(name, steps, repeats, **kw):
    sc = cases.build(name, **kw)
    phys, params = setup(sc)
    p = params.as_arrays(solver.dtype(phys))
    st = solver.init_state(sc, phys, p)
    # warm-up chunk (excluded from the timing)
    phys, st, chunk, compile_s = compile_and_warm_up(phys, st, p, steps)
    phys, start, st, walls, regrowths = timed_chunks(chunk, phys, st, repeats,
                                                     same_start=False)
    n = sc.solid.n
    wall = statistics.median(walls)
    return {"case": name, "kwargs": kw, "n_discs": n, "n_clamped": int(sc.solid.fixed.sum()),
            "n_bonds": sc.bonds.n if sc.bonds is not None else 0,
            "n_walls": sc.walls.n if sc.walls is not None else 0,
            "dtype": str(st.solid.x.dtype), "dt": float(params.dt),
            "neighbour_capacity": int(st.solid_nbrs.idx.shape[1]), "steps": steps,
            "repeats": repeats, "t_timed_from": float(start.t),
            "t_timed_to": float(st.t), "compile_s": compile_s, "wall_s": wall,
            "wall_s_all": walls, "steps_per_s": steps / wall,
            "steps_per_s_best": steps / min(walls), "particle_steps_per_s": n * steps / wall,
            "rebuilds": int(st.status.dem_rebuilds) - int(start.status.dem_rebuilds),
            "regrowths_while_timing": regrowths, "steps_timed": steps * repeats}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--steps", type=int, default=20000, help="chunk length, cantilever")
    ap.add_argument("--dam-steps", type=int, default=50000, help="chunk length, dam break")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--out", default="bench_dem.json", help="file in experiments/results")
    args = ap.parse_args()
    cases = [("dry_dam_break", args.dam_steps, {}), ("cantilever", args.steps, {}),
             ("cantilever", args.steps, {"d": 0.0025})]
    rows = []
    for name, steps, kw in cases:
        r = bench(name, steps, args.repeats, **kw)
        rows.append(r)
        print(f"{name:13s} {str(kw):14s} N={r['n_discs']:3d} bonds={r['n_bonds']:3d} "
              f"{r['dtype']}  {r['steps_per_s']:8.0f} steps/s (best {r['steps_per_s_best']:.0f})"
              f"  {r['particle_steps_per_s'] / 1e6:.2f} M particle-steps/s  "
              f"rebuilds {r['rebuilds']}/{r['steps_timed']}  compile {r['compile_s']:.1f} s",
              flush=True)
    out = {"machine": {"cpu_count": os.cpu_count(), "platform": platform.platform(),
                       "processor": platform.processor(), "jax": jax.__version__,
                       "backend": jax.default_backend(),
                       "note": "2-core VM shared with another user's test run while measured; "
                               "process-to-process spread up to 2x (see module docstring)",
                       "affinity": sorted(os.sched_getaffinity(0)),
                       "loadavg_at_end": os.getloadavg()},
           "rows": rows}
    os.makedirs(os.path.join(HERE, "results"), exist_ok=True)
    with open(os.path.join(HERE, "results", args.out), "w") as fh:
        json.dump(out, fh, indent=1)


if __name__ == "__main__":
    main()
