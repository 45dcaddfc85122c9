"""The cost of a gradient against a forward rollout, and what checkpointing buys.

    python experiments/calibration_cost.py                    # cantilever + coarse gate 0.2 s
    python experiments/calibration_cost.py --cases gate_seed  # the full 0.4 s gate, seed res.
    python experiments/calibration_cost.py --cases gate_seed_remat  # ... every step remat

For each case, in a fresh process each (so peak memory is that one computation's): the wall
time of a forward rollout of the loss and of its reverse-mode gradient (both compiled
first, then timed on a second call), the peak resident memory of the process, and XLA's
own figure for the compiled program's temporary buffers (memory_analysis) with the
checkpointed rollout and without it (one plain scan over all steps: what reverse mode
needs without checkpointing; compiled, not run). Writes
experiments/results/calibration_cost.json.
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time

OUT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "results")
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def build(case):
    import dataclasses

    from calibrate import cases
    from calibrate.fit import Calibration
    if case == "cantilever":          # K6.3.3's strip at the seed's d = 1.25 mm, 2 periods
        c = cases.cantilever_synthetic(d=0.00125, periods=2.0)
    elif case == "gate_coarse":
        c = cases.elastic_gate(resolution="coarse", t_fit=0.2)
    elif case == "gate_coarse_full":
        c = cases.elastic_gate(resolution="coarse", t_fit=0.4)
    elif case == "gate_seed":
        c = cases.elastic_gate(resolution="seed", t_fit=0.4)
    elif case.endswith("_remat"):        # the same with every step checkpointed too
        c = build(case[:-len("_remat")])
        cal = c.calibration
        pr = dataclasses.replace(cal.problem, remat_step=True)
        c = dataclasses.replace(c, calibration=Calibration(pr, cal.space, cal.targets))
    else:
        raise SystemExit(f"unknown case {case}")
    return c


def measure(case, what):
    import dataclasses

    import jax
    from calibrate.fit import Calibration
    c = build(case)
    cal = c.calibration
    pr = cal.problem
    z = jax.numpy.asarray(cal.space.z0, cal.dtype)
    args = (z, pr.state0, pr.params)
    rec = {"case": case, "what": what, "n_steps": pr.n_steps, "chunk": pr.chunk,
           "dt": pr.dt, "meta": c.meta}
    if what in ("forward", "grad"):
        fn = (jax.jit(lambda *a: cal.loss_fn(*a)[0]) if what == "forward"
              else jax.jit(jax.grad(lambda *a: cal.loss_fn(*a)[0])))
        t0 = time.perf_counter()
        jax.block_until_ready(fn(*args))
        rec["first_call_s"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        out = jax.block_until_ready(fn(*args))
        rec["wall_s"] = time.perf_counter() - t0
        rec["value"] = [float(v) for v in jax.numpy.atleast_1d(out)]
        rec["peak_rss_gb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6
    else:   # compile only: XLA's temporary-buffer figure, checkpointed or one plain scan
        if what == "grad_plain_compile":
            cal = Calibration(dataclasses.replace(pr, chunk=pr.n_steps), cal.space,
                              cal.targets)
            rec["chunk"] = pr.n_steps
        fn = jax.jit(jax.grad(lambda *a: cal.loss_fn(*a)[0]))
        t0 = time.perf_counter()
        comp = fn.lower(*args).compile()
        rec["compile_s"] = time.perf_counter() - t0
        ma = comp.memory_analysis()
        rec["xla_temp_gb"] = ma.temp_size_in_bytes / 1e9
        rec["xla_args_gb"] = ma.argument_size_in_bytes / 1e9
    return rec


def main(args):
    os.makedirs(OUT, exist_ok=True)
    path = os.path.join(OUT, "calibration_cost.json")
    results = json.load(open(path)) if os.path.exists(path) else {}
    for case in args.cases:
        rows = dict(results.get(case, {}))      # keep what other --what runs measured
        for what in args.what:
            env = dict(os.environ, PYTHONPATH=ROOT)
            p = subprocess.run([sys.executable, __file__, "--one", case, what], env=env,
                               capture_output=True, text=True)
            if p.returncode != 0:
                rows[what] = {"error": p.stderr[-1500:]}
            else:
                rows[what] = json.loads(p.stdout.strip().splitlines()[-1])
            print(case, what, json.dumps({k: v for k, v in rows[what].items()
                                          if k != "meta"}), flush=True)
        if "forward" in rows and "grad" in rows and "wall_s" in rows["grad"]:
            rows["grad_over_forward"] = rows["grad"]["wall_s"] / rows["forward"]["wall_s"]
        results[case] = rows
        with open(path, "w") as fh:
            json.dump(results, fh, indent=1)
    print(json.dumps({c: r.get("grad_over_forward") for c, r in results.items()}))


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "--one":
        print(json.dumps(measure(sys.argv[2], sys.argv[3]), default=float))
        sys.exit(0)
    ap = argparse.ArgumentParser()
    ap.add_argument("--cases", nargs="*", default=["cantilever", "gate_coarse"])
    ap.add_argument("--what", nargs="*",
                    default=["forward", "grad", "grad_compile", "grad_plain_compile"])
    main(ap.parse_args())
