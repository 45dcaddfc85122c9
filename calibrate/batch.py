"""Batched rollouts: many parameter sets in one compiled call (``jax.lax.map``, or
``jax.vmap`` on request), sharded over the devices when there are several
(``jax.shard_map``; on CPU try ``XLA_FLAGS=--xla_force_host_platform_device_count=2``).

    losses = batched_losses(cal, zs)               # zs (B, p) → (B,)
    lx = landscape(cal, z_best, "stiffness", np.geomspace(0.8, 1.25, 16))

The neighbour lists are shared: every member of the batch runs with the capacity the
problem was allocated with, and a member that overflows is reported (its loss is NaN),
never silently truncated (one compiled program for the batch needs one worst-case
capacity).
"""
from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from jax.sharding import Mesh, NamedSharding, PartitionSpec as P

from fpsi_jax.model.errors import ParameterError

from .fit import Calibration


def _mesh():
    return Mesh(np.asarray(jax.devices()), ("batch",))


def batched_losses(cal: Calibration, zs, shard: bool = True, vectorize: bool = False):
    """Loss of every row of ``zs`` (B, p) in one compiled call; the batch axis is sharded
    over all devices when there are several and B is a multiple of their number.
    Returns (losses (B,) numpy, observations (B, n_steps, …) numpy, shards used).

    The members run one after another inside the compiled call (``jax.lax.map``; on each
    device for its share when sharded), each with its own neighbour-list rebuilds: B
    members cost about B rollouts. ``vectorize=True`` runs them as one vectorised rollout
    (``jax.vmap``) instead; there a ``lax.cond`` whose predicate differs between members
    evaluates both branches, so every member rebuilds its neighbour lists at every step
    (70-disc cantilever, 29 937 steps, one CPU core: 4.1–4.4 rollouts a member vectorised,
    0.9 in sequence; docs/performance.md)."""
    zs = jnp.asarray(zs, cal.dtype)
    state0, base = cal.problem.state0, cal.problem.params

    def one(z, s0, b):
        loss, (u, st) = cal.loss_fn(z, s0, b)
        ok = ~(st.bad | st.overflow | st.h_exceeded)
        return jnp.where(ok, loss, jnp.nan), u

    def members(zs, s0, b):
        if vectorize:
            return jax.vmap(one, in_axes=(0, None, None))(zs, s0, b)
        return jax.lax.map(lambda z: one(z, s0, b), zs)

    n_dev = jax.device_count()
    used = 1
    if shard and n_dev > 1 and zs.shape[0] % n_dev == 0:
        mesh = _mesh()
        zs = jax.device_put(zs, NamedSharding(mesh, P("batch")))
        rep = NamedSharding(mesh, P())
        state0 = jax.device_put(state0, rep)
        base = jax.device_put(base, rep)
        # check_vma off: the step's lax.conds return values that vary over the batch
        # axis from one branch and constants from the other
        fn = jax.jit(jax.shard_map(members, mesh=mesh, in_specs=(P("batch"), P(), P()),
                                   out_specs=(P("batch"), P("batch")), check_vma=False))
        losses, u = fn(zs, state0, base)
        used = len({d for d in losses.sharding.device_set})
    else:
        losses, u = jax.jit(members)(zs, state0, base)
    return np.asarray(losses), np.asarray(u), used


def landscape(cal: Calibration, z_center, name: str, values, shard: bool = True,
              vectorize: bool = False):
    """Loss along one fitted quantity (physical ``values``), the others held at z_center:
    (values, losses)."""
    if name not in cal.space.names:
        raise ParameterError(f"{name!r} is not a fitted quantity; fitted: "
                             f"{', '.join(cal.space.names)}")
    base_vals = dict(zip(cal.space.names, np.asarray(cal.space.values(
        jnp.asarray(z_center, cal.dtype)), float)))
    zs = np.stack([np.asarray(cal.space.z_of({**base_vals, name: float(v)}))
                   for v in values])
    losses, _, used = batched_losses(cal, zs, shard, vectorize)
    return np.asarray(values, float), losses, used


def plot_landscape(curves: dict, path: str, title: str = ""):
    """One panel per fitted quantity: loss against its value (log–log), optimum marked.
    ``curves``: name → (values, losses, best value)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, len(curves), figsize=(4.2 * len(curves), 3.4))
    axes = np.atleast_1d(axes)
    for ax, (name, (v, l, best)) in zip(axes, curves.items()):
        ax.loglog(v, l, "o-", ms=3)
        ax.axvline(best, color="k", ls=":", lw=0.8, label=f"fitted {best:.4g}")
        ax.set_xlabel(name)
        ax.set_ylabel("loss")
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=7)
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
