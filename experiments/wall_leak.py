"""Fluid through a fixed wall, with and without the wall backstop (README "Wall backstop").

    .venv/bin/python experiments/wall_leak.py        # ~6 min: two 0.45 s coarse-tank gates

The elastic gate in a 0.5 m tank (``tank_length=0.5``, seed resolution otherwise): the
water that passes the gate reaches the floor–end-wall corner slowly, and without the
backstop a particle creeps through the four wall layers and leaves the domain. For each
setting the run's end (or the SimulationError), the first frame with a fluid particle past
a wall face, and how many were past at most. Writes experiments/results/wall_leak.json.
"""
import json
import os
import tempfile
import time

import numpy as np

from fpsi_jax import cases
from fpsi_jax.model.errors import SimulationError
from fpsi_jax.run import io
from fpsi_jax.run.driver import simulate

HERE = os.path.dirname(os.path.abspath(__file__))
T_END, EVERY, TANK = 0.45, 0.002, 0.5


def one(wall_repulsion, folder):
    scene = cases.build("elastic_gate", tank_length=TANK)
    out = os.path.join(folder, f"leak_{wall_repulsion}.h5")
    t0 = time.perf_counter()
    error = None
    try:
        simulate(scene, t_end=T_END, output=out, every=EVERY, progress=False, overwrite=True,
                 wall_repulsion=wall_repulsion)
    except SimulationError as e:
        error = str(e).splitlines()[0]
    wall = time.perf_counter() - t0
    run = io.read(out)
    x, t = run.fluid["x"], run.time
    past = (x[:, :, 0] > TANK) | (x[:, :, 0] < 0.0) | (x[:, :, 1] < 0.0)
    first = float(t[np.argmax(past.any(axis=1))]) if past.any() else None
    return {"wall_repulsion": wall_repulsion, "t_reached": float(t[-1]), "error": error,
            "first_frame_past_a_wall_face_s": first,
            "most_particles_past_a_face": int(past.sum(axis=1).max()),
            "lowest_fluid_y_m": float(x[:, :, 1].min()), "wall_s": wall,
            "n_fluid": int(x.shape[1])}


def main():
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        for w in (True, False):
            rows.append(one(w, folder))
            print(json.dumps(rows[-1]), flush=True)
    os.makedirs(os.path.join(HERE, "results"), exist_ok=True)
    with open(os.path.join(HERE, "results", "wall_leak.json"), "w") as fh:
        json.dump({"generated": time.strftime("%Y-%m-%d %H:%M:%S"), "scene": "elastic_gate",
                   "tank_length": TANK, "t_end": T_END, "every": EVERY, "runs": rows}, fh,
                  indent=1)


if __name__ == "__main__":
    main()
