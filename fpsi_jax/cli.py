"""Command line: ``fpsi list | run | validate | calibrate``.

Bad input (unknown scene, key or out-of-range value) prints one line naming it and the
allowed values, exits with code 2 and writes nothing.
"""
from __future__ import annotations

import argparse
import json
import os
import sys

from .model.errors import ParameterError, SimulationError


def _plot_run(scene, res, out_png):
    """Dam break: front Z(T) against Koshizuka & Oka; otherwise a particle snapshot."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np
    from .cases import validate

    f = res.state.fluid
    fig, axes = plt.subplots(1, 2 if scene.name == "dam_break" else 1,
                             figsize=(11 if scene.name == "dam_break" else 6, 4.2))
    axes = np.atleast_1d(axes)
    if f is not None:
        x = np.asarray(f.x)
        sc = axes[0].scatter(x[:, 0], x[:, 1], c=np.linalg.norm(np.asarray(f.v), axis=1), s=2,
                             cmap="viridis")
        fig.colorbar(sc, ax=axes[0], label="|v| [m/s]")
    if scene.boundary is not None:
        axes[0].scatter(scene.boundary.x[:, 0], scene.boundary.x[:, 1], s=1, c="0.6")
    if res.state.solid is not None:
        draw_solids(axes[0], scene, res.state)
    axes[0].set_aspect("equal")
    axes[0].set_title(f"{scene.name}, t = {float(res.state.t):.3f} s")
    if scene.name == "dam_break" and res.observations is not None:
        T, Z = validate.dam_break_front(scene, res)
        ref = validate.load_csv("koshizuka_oka1996_surge_front.csv")
        axes[1].plot(T, Z, label=f"fpsi-jax, dx = {scene.builder_kwargs['dx'] * 1e3:g} mm")
        axes[1].plot(ref[:, 0], ref[:, 1], "ko", label="Koshizuka & Oka (1996)")
        axes[1].set_xlabel("T = t sqrt(2g/a)")
        axes[1].set_ylabel("Z = x_front / a")
        axes[1].set_xlim(0, max(3.5, float(ref[:, 0].max()) + 0.2))
        axes[1].legend()
        axes[1].grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(out_png, dpi=120)
    plt.close(fig)


def _plot_gate_run(scene, res, png):
    """Tip ux, uy against the experiment (and other codes) in ``png``, the final state in
    ``<png>_snapshot.png``; prints the error figures."""
    from .cases import validate_fsi
    t, ux, uy = validate_fsi.tip_displacement(scene, res)
    validate_fsi.plot_gate([(f"fpsi-jax ({scene.builder_kwargs['coupling']})", t, ux, uy)],
                           png, f"{scene.name}: gate tip vs Antoci et al. (2007)")
    snap = png[:-4] + "_snapshot.png"
    _plot_run(scene, res, snap)
    print(f"wrote {snap}")
    m = validate_fsi.gate_metrics(t, ux, uy)
    print(f"peak tip ux {m['peak_ux_m'] * 1e3:.1f} mm at {m['t_peak_s']:.3f} s; experiment "
          f"{m['exp_peak_ux_m'] * 1e3:.1f} mm at {m['exp_t_peak_s']:.2f} s: "
          f"{m['peak_ux_rel_error']:+.1%}, {m['t_peak_error_s']:+.3f} s")
    print(f"RMS vs experiment over 0-{min(0.36, t[-1]):.2f} s ({m['frames']} frames): ux "
          f"{m['rms_ux_m'] * 1e3:.2f} mm, uy {m['rms_uy_m'] * 1e3:.2f} mm "
          f"({m['rms_ux_rel_peak']:.1%}, {m['rms_uy_rel_peak']:.1%} of the experiment's peaks)")
    if res.state.bonds is not None:
        import numpy as np
        broken = int((~np.asarray(res.state.bonds.intact)).sum())
        if broken:
            tb = np.asarray(res.state.bonds.t_break)
            print(f"{broken} bonds broken, the first at t = {tb[tb >= 0].min():.4f} s")


def draw_solids(ax, scene, state, color="tab:orange"):
    """Discs as circles (clamped ones grey), intact bonds as lines, walls as thick lines."""
    import numpy as np
    from matplotlib.collections import LineCollection, PatchCollection
    from matplotlib.patches import Circle

    s = state.solid
    x, r = np.asarray(s.x), np.asarray(s.radius)
    fixed = np.asarray(s.fixed)
    circles = [Circle(xy, rad) for xy, rad in zip(x, r)]
    ax.add_collection(PatchCollection(circles, facecolor=np.where(fixed, "0.6", color),
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


def cmd_list(args):
    from . import cases as scenes
    from .cases import validate
    print("scenes:")
    for name, fn in scenes.SCENES.items():
        doc = (fn.__doc__ or "").strip().splitlines()[0]
        print(f"  {name:20s} {doc}")
    print("validation cases:")
    for name, d in validate.DESCRIPTIONS.items():
        print(f"  {name:20s} {d}")
    for command in _plugins().values():
        if hasattr(command, "list_cases"):
            command.list_cases()
    return 0


def cmd_run(args):
    from .cases import overrides as ov
    from .cases import validate
    from .run.simulate import setup, simulate

    scene, phys = ov.build(args.scene, ov.parse_pairs(args.set))
    t_end = scene.t_end if args.t_end is None else args.t_end
    if not t_end > 0:
        raise ParameterError(f"--t-end = {t_end} out of range; allowed (0, inf)")
    unsafe = args.unsafe_dt
    if unsafe and args.dt is None:
        raise ParameterError("--unsafe-dt needs --dt")
    setup(scene, args.dt, unsafe_dt=unsafe, **phys)    # every check before compiling
    gate = scene.name in ("elastic_gate", "gate_failure")
    observe = validate.front_observer if scene.name == "dam_break" else None
    if gate:
        from .cases import validate_fsi
        observe = validate_fsi.tip_observer(scene)
    try:
        res = simulate(scene, t_end=t_end, output=args.out, every=args.every,
                       progress=not args.quiet, dt=args.dt, observe=observe, unsafe_dt=unsafe,
                       **phys)
    except SimulationError as e:
        print(f"error: {e}", file=sys.stderr)
        return 3
    sub = (f" x {res.physics.dem_substeps} DEM sub-steps"
           if res.physics.has_fluid and res.physics.has_solid else "")
    print(f"{scene.name}: {res.n_steps} steps of {float(res.params.dt):.4g} s{sub}, "
          f"{scene.n_particles} particles, wall {res.wall_s:.1f} s "
          f"(compile+first chunk {res.compile_s:.1f} s), "
          f"{res.particle_steps_per_s / 1e6:.2f} M particle-steps/s, "
          f"{res.rebuilds} neighbour rebuilds")
    if args.out:
        print(f"wrote {args.out} and {os.path.splitext(args.out)[0]}.xdmf")
    if args.plot:
        png = os.path.splitext(args.out or f"results/{scene.name}.h5")[0] + ".png"
        os.makedirs(os.path.dirname(os.path.abspath(png)), exist_ok=True)
        if gate:
            _plot_gate_run(scene, res, png)
        else:
            _plot_run(scene, res, png)
        print(f"wrote {png}")
        if scene.name == "dam_break" and res.observations is not None:
            import numpy as np
            T, Z = validate.dam_break_front(scene, res)
            ref = validate.load_csv("koshizuka_oka1996_surge_front.csv")
            ref = ref[(ref[:, 0] > 0) & (ref[:, 0] <= T.max())]
            z = np.interp(ref[:, 0], T, Z)
            print("front vs Koshizuka & Oka:  T      Z_exp   Z_sim   rel.err")
            for t_, zr, zs in zip(ref[:, 0], ref[:, 1], z):
                print(f"                          {t_:5.3f}  {zr:6.3f}  {zs:6.3f}  "
                      f"{(zs - zr) / zr:+.1%}")
    return 0


def cmd_validate(args):
    from .cases import overrides as ov
    from .cases import validate
    recs = validate.run(args.cases, quick=args.quick, overrides=ov.parse_pairs(args.set))
    print(validate.format_table(recs))
    if args.json:
        os.makedirs(os.path.dirname(os.path.abspath(args.json)), exist_ok=True)
        with open(args.json, "w") as fh:
            json.dump([r.as_dict() for r in recs], fh, indent=1, default=str)
    return 0 if all(r.passed for r in recs) else 1


def make_parser():
    p = argparse.ArgumentParser(prog="fpsi", description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="cmd", required=True)
    sub.add_parser("list", help="list scenes and validation cases")
    r = sub.add_parser("run", help="run a scene")
    r.add_argument("scene")
    r.add_argument("--t-end", type=float, default=None, help="physical time [s]")
    r.add_argument("--out", default=None, help="HDF5 output path (.xdmf written beside)")
    r.add_argument("--every", type=float, default=None, help="seconds between frames")
    r.add_argument("--dt", type=float, default=None, help="time step (default: the bound)")
    r.add_argument("--unsafe-dt", action="store_true",
                   help="accept a --dt above the derived bound (experiments/stability.py "
                        "found the cases stable to 4-6x it; a run that blows up still stops "
                        "with the diagnosis)")
    r.add_argument("--set", action="append", metavar="KEY=VALUE",
                   help="override a scene parameter, a Params leaf or a Physics option")
    r.add_argument("--plot", action="store_true", help="write a PNG next to the output")
    r.add_argument("--quiet", action="store_true", help="no progress bar")
    v = sub.add_parser("validate", help="run registered validation cases")
    v.add_argument("cases", nargs="*")
    v.add_argument("--quick", action="store_true", help="coarse, fast versions")
    v.add_argument("--set", action="append", metavar="KEY=VALUE")
    v.add_argument("--json", default=None, help="write the records as JSON")
    for command in _plugins().values():
        command.add_parser(sub)
    return p


PLUGIN_GROUP = "fpsi_jax.commands"


def _plugins() -> dict:
    """Subcommands that other packages add through the ``fpsi_jax.commands`` entry-point
    group (``fpsi calibrate`` comes from the top-level ``calibrate`` package this way, so
    fpsi_jax never imports the package that builds on it). Each entry point names a module
    with ``add_parser(subparsers)`` and ``run(args) -> int`` (and optionally
    ``list_cases()`` for ``fpsi list``)."""
    from importlib.metadata import entry_points
    out = {}
    for ep in entry_points(group=PLUGIN_GROUP):
        out[ep.name] = ep.load()
    return out


def main(argv=None):
    args = make_parser().parse_args(argv)
    commands = {"list": cmd_list, "run": cmd_run, "validate": cmd_validate}
    commands.update({name: mod.run for name, mod in _plugins().items()})
    try:
        return commands[args.cmd](args)
    except ParameterError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
