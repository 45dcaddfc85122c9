"""Figures shared by the cases: the particle snapshot every scene gets from ``fpsi run
--plot`` (fluid coloured by speed, boundary particles, discs, bonds and walls)."""
from __future__ import annotations

import numpy as np


def pyplot():
    """matplotlib.pyplot on the non-interactive Agg backend."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def draw_solids(ax, scene, state, color="tab:orange"):
    """Discs as circles (clamped ones grey; none parked after leaving through an open
    side), intact bonds as lines, walls as thick lines."""
    from matplotlib.collections import LineCollection, PatchCollection
    from matplotlib.patches import Circle

    s = state.solid
    x, r = np.asarray(s.x), np.asarray(s.radius)
    fixed = np.asarray(s.fixed)
    here = np.ones(len(x), bool) if s.t_out is None else np.asarray(s.t_out) < 0
    circles = [Circle(xy, rad) for xy, rad in zip(x[here], r[here])]
    ax.add_collection(PatchCollection(circles, facecolor=np.where(fixed[here], "0.6", color),
                                      edgecolor="k", linewidth=0.2))
    if state.bonds is not None:
        b = state.bonds
        ok = np.asarray(b.intact)
        seg = np.stack([x[np.asarray(b.i)[ok]], x[np.asarray(b.j)[ok]]], axis=1)
        ax.add_collection(LineCollection(seg, colors="k", linewidths=0.3))
    if scene.walls is not None:
        seg = np.stack([scene.walls.a, scene.walls.b], axis=1)
        ax.add_collection(LineCollection(seg, colors="k", linewidths=2))
    ax.autoscale_view()


def draw_snapshot(fig, ax, scene, res):
    """The final state of a run on ``ax``: fluid particles coloured by speed (those still
    in the computation: not the ones parked after leaving through an open side), boundary
    particles grey, discs, bonds and walls (:func:`draw_solids`)."""
    f = res.state.fluid
    if f is not None:
        keep = slice(None) if f.t_out is None else np.asarray(f.t_out) < 0
        x, v = np.asarray(f.x)[keep], np.asarray(f.v)[keep]
        sc = ax.scatter(x[:, 0], x[:, 1], c=np.linalg.norm(v, axis=1), s=2, cmap="viridis")
        fig.colorbar(sc, ax=ax, label="|v| [m/s]")
    if scene.boundary is not None:
        ax.scatter(scene.boundary.x[:, 0], scene.boundary.x[:, 1], s=1, c="0.6")
    if res.state.solid is not None:
        draw_solids(ax, scene, res.state)
    ax.set_aspect("equal")
    ax.set_title(f"{scene.name}, t = {float(res.state.t):.3f} s")


def snapshot(scene, res, png):
    """Write the final state of a run (:func:`draw_snapshot`) to ``png``."""
    plt = pyplot()
    fig, ax = plt.subplots(1, 1, figsize=(6, 4.2))
    draw_snapshot(fig, ax, scene, res)
    fig.tight_layout()
    fig.savefig(png, dpi=120)
    plt.close(fig)


def default_plot(scene, res, png):
    """``fpsi run --plot`` for a scene without a plot of its own: the snapshot."""
    snapshot(scene, res, png)
    return [f"wrote {png}"]
