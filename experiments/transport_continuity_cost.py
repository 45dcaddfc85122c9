"""The cost of continuity at the drift velocity (Physics.transport_continuity) a step:
whole runs of one scene with the option on and off, alternated in one process after a
compiling round, the wall time of the stepping.

    taskset -c 1 python experiments/transport_continuity_cost.py dam_break 0.4 3
    taskset -c 1 python experiments/transport_continuity_cost.py dam_break 0.05 2 '{"dx": 0.00145}'
    taskset -c 1 python experiments/transport_continuity_cost.py elastic_gate 0.1 2

Appends {scene, t_end, kwargs, on: [[stepping s, rebuilds, M particle-steps/s], ...],
off: [...]} to experiments/results/transport_continuity_cost.json.
"""
from __future__ import annotations

import json
import os
import sys

from fpsi_jax import cases
from fpsi_jax.run.driver import simulate

OUT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "results",
                   "transport_continuity_cost.json")


def main(name, t_end, reps, kw):
    scene = cases.build(name, **kw)
    out = {"scene": name, "t_end": t_end, "kwargs": kw, "on": [], "off": []}
    for r in range(reps + 1):
        for k in ("on", "off"):
            res = simulate(scene, t_end=t_end, progress=False,
                           transport_continuity=(k == "on"))
            if r:                                   # the first round compiles
                out[k].append([round(res.wall_s - res.compile_s, 2), res.rebuilds,
                               round(res.particle_steps_per_s / 1e6, 3)])
    print(json.dumps(out))
    rows = json.load(open(OUT)) if os.path.exists(OUT) else []
    rows.append(out)
    with open(OUT, "w") as fh:
        json.dump(rows, fh, indent=1)


if __name__ == "__main__":
    main(sys.argv[1], float(sys.argv[2]), int(sys.argv[3]),
         json.loads(sys.argv[4]) if len(sys.argv) > 4 else {})
