"""``fpsi run my_case.toml --plot``: every probe against time, with the reference curves the
file names, and a snapshot of the final state."""
from __future__ import annotations

import numpy as np

from ..cases.plotting import pyplot, snapshot
from . import data


def plot_probes(case, res, png: str) -> list[str]:
    """One panel per probe (its components against time; a bed profile against x at the
    end), each reference CSV's matching columns as markers; the snapshot beside it in
    ``<png>_snapshot.png``. Returns the lines to print (files written, RMS vs references)."""
    plt = pyplot()
    probes = case.probes
    lines = []
    snap = png[:-4] + "_snapshot.png"
    snapshot(case.scene, res, snap)
    if not probes:
        return [f"wrote {snap} (the file declares no probe)"]
    n = len(probes)
    fig, axes = plt.subplots(1, n, figsize=(4.6 * n, 3.6), squeeze=False)
    t = res.times
    for ax, p in zip(axes[0], probes):
        v = np.asarray(res.probes[p.name], float)
        other = None                      # a right-hand axis for a second unit
        if p.kind == "bed_profile":
            xc = np.asarray(p.spec["x_centres"])
            ax.step(xc, v[0], where="mid", color="0.5", label="start")
            ax.step(xc, v[-1], where="mid", label=f"t = {t[-1]:.3g} s")
            ax.set_xlabel("x [m]")
            ax.set_ylabel("bed top [m]")
        else:
            # components in another unit than the first (a force probe's moment) on a
            # right-hand axis of their own; a count (broken bonds) from 0 in whole steps
            for k, (c, u) in enumerate(zip(p.components, p.units)):
                if u != p.units[0] and other is None:
                    other = ax.twinx()
                    other.set_ylabel(f"{p.name} [{u}]")
                on = ax if u == p.units[0] else other
                on.plot(t, v[:, k], lw=1.5, color=f"C{k}", label=f"{c} [{u}]")
            ax.set_xlabel("t [s]")
            ax.set_ylabel(f"{p.name} [{p.units[0]}]")
            if p.kind == "broken_bonds":
                from matplotlib.ticker import MaxNLocator
                ax.yaxis.set_major_locator(MaxNLocator(integer=True))
                ax.set_ylim(bottom=0, top=max(1.0, 1.05 * float(np.max(v, initial=0.0))))
        ref = case.references.get(p.name)
        if ref is not None and p.kind != "bed_profile":
            tr, yr, comps = data.match(ref, p)
            for j, k in enumerate(comps):
                ax.plot(tr, yr[:, j], "ko" if j == 0 else "ks", ms=4, mfc="none",
                        label=f"{p.components[k]} reference")
                inside = (tr > 0) & (tr <= t[-1])
                if inside.any():
                    rms = float(np.sqrt(np.mean((np.interp(tr[inside], t, v[:, k])
                                                 - yr[inside, j]) ** 2)))
                    lines.append(f"{p.name}.{p.components[k]}: RMS vs {ref.split('/')[-1]} "
                                 f"{rms:.4g} {p.units[k]} over {int(inside.sum())} samples")
        ax.set_title(f"{p.name} ({p.kind})")
        ax.grid(alpha=0.3)
        handles, names = ax.get_legend_handles_labels()
        if other is not None:
            more = other.get_legend_handles_labels()
            handles, names = handles + more[0], names + more[1]
        ax.legend(handles, names, fontsize=7)
    fig.suptitle(case.scene.name)
    fig.tight_layout()
    fig.savefig(png, dpi=120)
    plt.close(fig)
    return lines + [f"wrote {png}", f"wrote {snap}"]
