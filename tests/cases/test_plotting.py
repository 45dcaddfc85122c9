"""The snapshot drawing (cases.plotting): what it puts on the axes."""
from types import SimpleNamespace as NS

import matplotlib
import numpy as np

from fpsi_jax.cases.plotting import draw_snapshot

matplotlib.use("Agg")


def test_snapshot_leaves_out_particles_and_discs_parked_after_leaving():
    """Fluid particles and discs that left through an open side (t_out ≥ 0) are parked far
    away: the snapshot draws only the ones still in the computation."""
    import matplotlib.pyplot as plt

    fluid = NS(x=np.array([[0.1, 0.1], [0.2, 0.1], [5.0, 5.0]]), v=np.zeros((3, 2)),
               t_out=np.array([-1.0, -1.0, 0.3]))
    solid = NS(x=np.array([[0.3, 0.1], [9.0, 9.0]]), radius=np.full(2, 0.01),
               fixed=np.zeros(2, bool), t_out=np.array([-1.0, 0.2]))
    state = NS(fluid=fluid, solid=solid, bonds=None, t=0.5)
    scene = NS(boundary=None, walls=None, name="parked")
    fig, ax = plt.subplots()
    draw_snapshot(fig, ax, scene, NS(state=state))
    assert len(ax.collections[0].get_offsets()) == 2          # the fluid's scatter
    assert len(ax.collections[1].get_paths()) == 1            # the discs
    plt.close(fig)
