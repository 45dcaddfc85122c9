"""Dry dam break of 33 aluminium discs (Zhang et al. 2009): centre of mass vs the 4
low-confidence experimental points, run speed, and a strip of snapshots.

    taskset -c 0 .venv/bin/python experiments/dry_dam_break.py [--t-end 0.5] [--out results/dry_dam_break.h5]

Runs cases.build('dry_dam_break') (physical stiffness k_n = E = 69 GPa/m, dt at the DEM
bound, float32) with the CoM (mean of state.solid.x) observed every step, writes the HDF5
to results/ (git-ignored) and, in experiments/results/: dry_dam_break_com.csv (CoM sim and
experiment at t = 0, 0.1, 0.3, 0.5 s and their differences), dry_dam_break_com.png and
dry_dam_break_snapshots.png (t = 0, 0.1, ..., 0.5 s, discs at their true radius, walls).
taskset: on a shared 2-core VM unpinned processes ran at ~50k or ~100k steps/s at random
(see bench_dem.py); pinned to one core they were consistently fast.
"""
from __future__ import annotations

import argparse
import os

import jax.numpy as jnp
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.collections import LineCollection, PatchCollection  # noqa: E402
from matplotlib.patches import Circle  # noqa: E402

from fpsi_jax import cases  # noqa: E402
from fpsi_jax.cases.registry import load_csv  # noqa: E402
from fpsi_jax.run import io  # noqa: E402
from fpsi_jax.run.driver import simulate  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
EXP = "zhang2009_dry_cylinder_collapse_center_of_mass_experiment.csv"


def com(state):
    return jnp.mean(state.solid.x, axis=0)


def snapshots(path, times, png):
    run = io.read(path)                  # time-first arrays; walls are constant (top level)
    walls = np.stack([run.walls["a"], run.walls["b"]], axis=1)
    r = run.solid["radius"]
    box = walls.reshape(-1, 2)
    fig, axes = plt.subplots(len(times), 1, figsize=(8, 1.45 * len(times)), sharex=True)
    for ax, t in zip(axes, times):
        k = int(np.argmin(np.abs(run.time - t)))
        ax.add_collection(PatchCollection([Circle(xy, rad) for xy, rad in
                                           zip(run.solid["x"][k], r)],
                                          facecolor="tab:orange", edgecolor="k", lw=0.3))
        ax.add_collection(LineCollection(walls, colors="k", linewidths=2))
        ax.set_xlim(box[:, 0].min() - 0.004, box[:, 0].max() + 0.004)
        ax.set_ylim(-0.004, 0.056)
        ax.set_aspect("equal")
        ax.text(0.6, 0.9, f"t = {run.time[k]:.3f} s", transform=ax.transAxes, ha="left",
                va="top", fontsize=9)
        ax.set_ylabel("y [m]")
    axes[-1].set_xlabel("x [m]")
    axes[0].set_title("dry dam break, 33 Al discs d = 1 cm, 0.26 m box (walls in black)",
                      fontsize=10)
    fig.tight_layout()
    fig.savefig(png, dpi=150)
    plt.close(fig)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--t-end", type=float, default=0.5)
    ap.add_argument("--out", default="results/dry_dam_break.h5")
    args = ap.parse_args()
    scene = cases.build("dry_dam_break")
    res = simulate(scene, t_end=args.t_end, output=args.out, every=0.01, progress=False,
                   observe=com, overwrite=True)        # replaces this script's own output
    dt = float(res.params.dt)
    n = scene.solid.n
    run_s = res.wall_s - res.compile_s
    steps_after = res.n_steps - res.first_chunk_steps
    print(f"run: {res.n_steps} steps of dt = {dt:.4g} s to t = {float(res.state.t):.4f} s, "
          f"{n} discs, {scene.walls.n} walls, float{'64' if res.physics.x64 else '32'}")
    print(f"set-up and compilation {res.setup_s:.1f} s, stepping {res.wall_s:.1f} s (first "
          f"chunk of {res.first_chunk_steps} steps {res.compile_s:.1f} s); after it {steps_after / run_s:.0f} steps/s, "
          f"{res.particle_steps_per_s / 1e6:.3f} M particle-steps/s; overall "
          f"{res.n_steps / res.wall_s:.0f} steps/s; {res.dem_rebuilds} neighbour rebuilds, "
          f"{res.reallocations} reallocations")

    x0 = np.asarray(scene.solid.x).mean(axis=0)
    t = np.r_[0.0, dt * np.arange(1, res.n_steps + 1)]
    c = np.vstack([x0, res.observations])
    ref = load_csv(EXP)
    tn, xe, ye = ref[:, 0], ref[:, 5], ref[:, 6]
    xs, ys = np.interp(tn, t, c[:, 0]), np.interp(tn, t, c[:, 1])
    table = np.c_[tn, xs, ys, xe, ye, xs - xe, ys - ye]
    os.makedirs(os.path.join(HERE, "results"), exist_ok=True)
    np.savetxt(os.path.join(HERE, "results", "dry_dam_break_com.csv"), table, delimiter=",",
               fmt="%.6g", comments="",
               header="t_s,x_com_sim_m,y_com_sim_m,x_com_exp_m,y_com_exp_m,"
                      "dx_sim_minus_exp_m,dy_sim_minus_exp_m")
    print("   t     x_sim    x_exp    dx[mm]   y_sim    y_exp    dy[mm]")
    for tt, a, b, e, f, dx_, dy_ in table:
        print(f"{tt:5.2f}  {a:.5f}  {e:.5f}  {1e3 * dx_:+6.2f}   {b:.5f}  {f:.5f}  "
              f"{1e3 * dy_:+6.2f}")

    fig, axes = plt.subplots(1, 2, figsize=(9, 3.5))
    every = max(1, len(t) // 5000)
    for ax, k, lab, te in ((axes[0], 0, "x", ref[:, 1]), (axes[1], 1, "y", ref[:, 3])):
        ax.plot(t[::every], c[::every, k], label="fpsi-jax DEM")
        ax.plot(te, ref[:, 5 + k], "o", color="tab:red",
                label="Zhang et al. 2009, low-confidence data")
        ax.set_xlabel("t [s]")
        ax.set_ylabel(f"{lab}_com [m]")
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    fig.suptitle("dry dam break: centre of mass of the 33 discs", fontsize=10)
    fig.tight_layout()
    fig.savefig(os.path.join(HERE, "results", "dry_dam_break_com.png"), dpi=150)
    plt.close(fig)
    snapshots(args.out, [0.0, 0.1, 0.2, 0.3, 0.4, 0.5],
              os.path.join(HERE, "results", "dry_dam_break_snapshots.png"))


if __name__ == "__main__":
    main()
