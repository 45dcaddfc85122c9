"""Command line: ``fpsi list | run | validate | calibrate``.

Bad input (unknown scene, key or out-of-range value) prints one line naming it and the
allowed values, exits with code 2 and writes nothing.
"""
from __future__ import annotations

import argparse
import json
import os
import sys

from . import _xla
from .model.config import H_MARGIN_DEFAULT
from .model.errors import Interrupted, ParameterError, SimulationError, number


def cmd_list(args):
    from . import cases
    if args.name is not None:
        return list_keys(args.name)
    print("scenes:")
    for name, fn in cases.SCENES.items():
        doc = (fn.__doc__ or "").strip().splitlines()[0]
        print(f"  {name:20s} {doc}")
    print("validation cases:")
    for name, d in cases.DESCRIPTIONS.items():
        print(f"  {name:20s} {d}")
    for command in _plugins().values():
        if hasattr(command, "list_cases"):
            command.list_cases()
    return 0


def list_keys(name: str) -> int:
    """``fpsi list NAME``: the keys ``--set`` takes for a registered scene, a validation case
    (its scene's keys, with the builder's defaults) or a scene file, with their values."""
    from . import cases
    from .cases import overrides as ov
    if is_scene_file(name):
        from . import scenefile
        scene, scene_name = scenefile.load(name).scene, None
    else:
        scene_name = cases.SCENE_OF.get(name, name)
        if scene_name not in cases.SCENES:
            known = sorted(set(cases.SCENES) | set(cases.SCENE_OF))
            raise ParameterError(f"{name!r} is no scene, validation case or scene file (.toml); "
                                 f"allowed: {', '.join(known)}")
        scene = cases.build(scene_name)
    print(f"--set KEY=VALUE keys of {name}:")
    if name in cases.SCENE_OF and not is_scene_file(name):
        print(f"(the validation case builds scene {scene_name!r} with its own values of some "
              "of these; shown are the builder's defaults)")
    print("\n".join(ov.key_table(scene, scene_name)))
    return 0


def set_pairs(pairs, known=None) -> dict:
    """``--set key=value`` pairs (cases.overrides.parse_pairs); a value written with a unit,
    as a scene file takes it ("500 kPa"), is refused with its SI number: --set values
    are SI numbers, and the key alone does not say what it measures. ``known(key)``, where
    given, says which keys the run takes: another is left for the unknown-key error, not
    told how to write its value."""
    from .cases import overrides as ov
    from .scenefile.reader import QUANTITY_UNITS, split_quantity
    out = ov.parse_pairs(pairs)
    for key, value in out.items():
        if known is not None and not known(key):
            continue
        parts = split_quantity(value) if isinstance(value, str) else None
        if parts is not None and parts[1] in QUANTITY_UNITS:
            unit, factor = QUANTITY_UNITS[parts[1]]
            si = parts[0] * factor
            raise ParameterError(f"--set {key} = {value!r}: --set takes SI numbers without "
                                 f"units; write {key}={si:g} (in {unit})")
    return out


def is_scene_file(name: str) -> bool:
    return name.lower().endswith(".toml")


def _resume_args(args):
    """``args`` filled from the run record of the file named by --resume."""
    import h5py
    from .run import io
    path = args.resume
    if not io.ours(path):
        raise ParameterError(f"--resume = {path!r} is not a run written by fpsi-jax")
    with h5py.File(path, "r", locking=False) as f:
        info = json.loads(f.attrs.get("run", "{}") or "{}")
    if not info.get("scene"):
        raise ParameterError(f"--resume = {path!r} was not written by fpsi run (no run record)")
    if args.scene not in (None, info["scene"]):
        raise ParameterError(f"--resume: {path!r} is a run of {info['scene']!r}, not "
                             f"{args.scene!r}")
    plot = args.plot                    # --plot on the resume asks for one too
    for key in ("scene", "set", "t_end", "every", "dt", "unsafe_dt", "plot"):
        setattr(args, key, info.get(key))
    args.plot = bool(plot or args.plot)
    args.out = path
    return args


def cmd_run(args):
    from . import cases
    from .cases import overrides as ov
    from .cases.plotting import default_plot
    from .run import io
    from .run.driver import check_steps, setup, simulate

    if args.resume:
        args = _resume_args(args)
    elif args.scene is None:
        raise ParameterError("fpsi run needs a scene (fpsi list) or --resume FILE")
    if args.out and not args.resume:
        io.check_output(args.out, args.overwrite)             # before anything is built
    case = None
    if is_scene_file(args.scene):
        from . import scenefile
        case = scenefile.load(args.scene)
        scene, probes = case.scene, case.probes
        phys = ov.apply(scene, set_pairs(args.set, ov.known_to(scene)),
                        f"scene file {args.scene!r}", listing=args.scene)
        out = args.out or case.output["file"] or f"results/{scene.name}.h5"
        every = args.every if args.every is not None else case.output["every"]
        want_plot = args.plot or case.output["plot"]
        observe = None
    else:
        scene, phys = ov.build(args.scene, set_pairs(args.set))
        out, every, want_plot, probes = args.out, args.every, args.plot, None
        observer = cases.OBSERVERS.get(scene.name)
        observe = observer(scene) if observer is not None else None
    if out and not args.resume:
        io.check_output(out, args.overwrite)
    png = os.path.splitext(out or f"results/{scene.name}.h5")[0] + ".png"
    if want_plot:
        io.check_output(png, kind="png")
    t_end = scene.t_end if args.t_end is None else args.t_end
    t_end = number("--t-end", t_end, 0.0, None, lo_open=True)
    unsafe = args.unsafe_dt
    if unsafe and args.dt is None:
        raise ParameterError("--unsafe-dt needs --dt")
    if args.dt is not None:
        number("--dt", args.dt, 0.0, None, lo_open=True)
    if every is not None and args.every is None and args.t_end is not None and every > t_end:
        every = t_end           # a run shortened by --t-end writes its one frame at the end
    if every is not None:       # named as the user gave it: an option or the scene file's key
        number("--every" if args.every is not None
               else f"{args.scene}: [output]: key 'every'", every, 0.0, t_end, lo_open=True)
    _, params = setup(scene, args.dt, unsafe_dt=unsafe, **phys)  # every check before compiling
    check_steps(t_end, float(params.dt))
    info = {"scene": args.scene, "set": args.set or [], "t_end": t_end, "every": every,
            "dt": args.dt, "unsafe_dt": unsafe, "plot": want_plot}
    try:
        res = simulate(scene, t_end=t_end, output=out, every=every,
                       progress=not args.quiet, dt=args.dt, observe=observe, unsafe_dt=unsafe,
                       probes=probes, overwrite=args.overwrite, run_info=info,
                       resume=args.resume, **phys)
    except SimulationError as e:
        print(f"error: {e}", file=sys.stderr)
        if want_plot:
            _plot_stopped(case, scene, out, png, args, unsafe, phys)
        return 3
    except io.OutputError as e:
        print(f"error: {e}", file=sys.stderr)
        return 4
    except Interrupted as e:
        print(f"stopped: {e}", file=sys.stderr)
        if want_plot:
            _plot_stopped(case, scene, out, png, args, unsafe, phys)
        return 130 if e.signal == "SIGINT" else 143
    sub = (f" x {res.physics.dem_substeps} DEM sub-steps"
           if res.physics.has_fluid and res.physics.has_solid else "")
    speed = (f"{res.particle_steps_per_s / 1e6:.3g} M particle-steps/s"
             + (" (compile included: every step was in the first chunk)"
                if res.throughput_includes_compile else ""))
    left = f", {res.excluded} particles left through open sides" if res.excluded else ""
    k = res.regrowth_chunks
    regrew = (f"; {res.regrowth_s:.1f} s recompiling and redoing {k} chunk"
              f"{'s' if k > 1 else ''} whose neighbour lists grew" if k else "")
    if k and res.physics.has_fluid and res.physics.h_margin > H_MARGIN_DEFAULT + 1e-9:
        regrew += (f", the SPH cut-off to {res.physics.h_margin:.2f} h0 for a growing "
                   "smoothing length")
    lists = ([f"{res.rebuilds} SPH"] if res.physics.has_fluid else []) + (
        [f"{res.dem_rebuilds} DEM"] if res.physics.has_solid else [])
    print(f"{scene.name}: {res.n_steps} steps of {float(res.params.dt):.4g} s{sub}, "
          f"{scene.n_particles} particles{left}, set-up and compilation {res.setup_s:.1f} s, "
          f"stepping {res.wall_s:.1f} s (first chunk {res.compile_s:.1f} s{regrew}), {speed}, "
          f"{' and '.join(lists)} neighbour-list rebuilds")
    if out:
        extra = f" and {os.path.splitext(out)[0]}_probes.csv" if probes else ""
        print(f"wrote {out}, {io.sidecar(out)}{extra}")
    if want_plot and args.resume:           # the run's steps are in the file, not in res
        _plot_stopped(case, scene, out, png, args, unsafe, phys, finished=True)
    elif want_plot:
        os.makedirs(os.path.dirname(os.path.abspath(png)), exist_ok=True)
        if case is not None:
            from .scenefile.plot import plot_probes
            lines = plot_probes(case, res, png)
        else:
            lines = cases.PLOTS.get(scene.name, default_plot)(scene, res, png)
        for line in lines:
            print(line)
    return 0


def _plot_stopped(case, scene, out, png, args, unsafe, phys, finished=False):
    """``--plot`` for a run that stopped early, or (``finished``) one resumed from its file:
    its probes and snapshot up to the last good frame of the file (a registered case with a
    plot of its own gets none: those plots read the whole run from one process)."""
    from . import cases
    from .cases.plotting import default_plot
    from .run.driver import stopped

    if not out or not os.path.exists(out) or (case is None and scene.name in cases.PLOTS):
        why = ("the run was resumed: its own plot reads the whole run from one process "
               "(fpsi run without --resume draws it)" if finished
               else "the run stopped before its end")
        print(f"no plot: {why}", file=sys.stderr)
        return
    try:
        res = stopped(scene, out, args.dt, unsafe, **phys)
    except Exception as e:                      # the file is still the user's to open
        print(f"no plot: {e}", file=sys.stderr)
        return
    os.makedirs(os.path.dirname(os.path.abspath(png)), exist_ok=True)
    if case is not None and len(res.times):
        from .scenefile.plot import plot_probes
        lines = plot_probes(case, res, png)
    elif case is None:
        lines = default_plot(scene, res, png)
    else:                                  # stopped within its first chunk: no probe row
        from .cases.plotting import snapshot
        snap = png[:-4] + "_snapshot.png"
        snapshot(scene, res, snap)
        lines = [f"wrote {snap}"]
        if os.path.exists(png):            # an earlier run's probes: not this run's
            os.remove(png)
            lines.append(f"removed {png} (an earlier run's; no probe row was recorded "
                         "before the stop)")
    for line in lines:
        print(f"{line} (up to the last good frame, t = {float(res.state.t):.6g} s)"
              if line.startswith("wrote") and not finished else line)


def cmd_validate(args):
    from .cases import overrides as ov
    from .cases import validate
    from .run import io
    if args.json:
        io.check_output(args.json, kind="json")          # before the cases run
    recs = validate.run(args.cases, quick=args.quick, overrides=set_pairs(args.set))
    print(validate.format_table(recs))
    if args.json:
        os.makedirs(os.path.dirname(os.path.abspath(args.json)), exist_ok=True)
        with open(args.json, "w") as fh:
            json.dump([r.as_dict() for r in recs], fh, indent=1, default=str)
    return 0 if all(r.passed for r in recs) else 1


class _Parser(argparse.ArgumentParser):
    """argparse with bad arguments reported on one line (exit code 2), as every other bad
    input is, instead of the usage block followed by the error."""

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def seconds(text: str) -> float:
    """A time on the command line: seconds as a number, or with a unit as a scene file takes
    it ("0.5 ms", "2 s")."""
    from .scenefile.reader import QUANTITY_UNITS, split_quantity
    try:
        return float(text)
    except ValueError:
        pass
    parts = split_quantity(text)
    unit = QUANTITY_UNITS.get(parts[1]) if parts is not None else None
    if unit is None or unit[0] != "s":
        raise argparse.ArgumentTypeError(f"{text!r} is not a time: seconds as a number "
                                         "(0.0005) or with a unit ('0.5 ms')")
    return parts[0] * unit[1]


def make_parser():
    p = _Parser(prog="fpsi", description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="cmd", required=True)
    ls = sub.add_parser("list", help="list scenes and validation cases, or the keys --set "
                        "takes for one of them or a scene file")
    ls.add_argument("name", nargs="?", default=None,
                    help="a scene, validation case or scene file: list its --set keys")
    r = sub.add_parser("run", help="run a scene", epilog=(
        "exit codes: 0 done; 2 bad input (nothing written); 3 the run went unstable (the "
        "file keeps every good frame); 4 the output could not be written (e.g. a full "
        "disk; frames so far intact); 130/143 stopped by SIGINT/SIGTERM at the end of a "
        "chunk (continue with --resume FILE)"))
    r.add_argument("scene", nargs="?", default=None,
                   help="a registered scene (fpsi list) or a scene file "
                   "(my_case.toml; docs/scene-file.md); omitted with --resume")
    r.add_argument("--t-end", type=seconds, default=None, help="physical time [s] (or "
                   "with a unit: '500 ms')")
    r.add_argument("--out", default=None, help="HDF5 output path, .h5 (.xdmf written beside)")
    r.add_argument("--overwrite", action="store_true",
                   help="replace an existing output file (only one fpsi-jax wrote)")
    r.add_argument("--resume", default=None, metavar="FILE",
                   help="continue a stopped run from the last complete frame of its file")
    r.add_argument("--every", type=seconds, default=None, help="seconds between frames")
    r.add_argument("--dt", type=seconds, default=None, help="time step (default: the bound)")
    r.add_argument("--unsafe-dt", action="store_true",
                   help="accept a --dt above the derived bound (experiments/stability.py "
                        "found the cases stable to 1.5-2.9x it; a run that blows up still stops "
                        "with the diagnosis)")
    r.add_argument("--set", action="append", metavar="KEY=VALUE",
                   help="override a scene parameter (registered scenes), a Params leaf or a "
                        "Physics option")
    r.add_argument("--plot", action="store_true", help="write a PNG next to the output")
    r.add_argument("--max-particles", type=int, default=None, metavar="N",
                   help="allow scenes of up to N particles (default: what this machine's "
                        "memory holds, about 8 kB a particle)")
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
    _xla.configure_cache()        # compiled programs on disk (FPSI_NO_COMPILE_CACHE=1: off)
    given = list(sys.argv[1:] if argv is None else argv)
    args = make_parser().parse_args(given)
    # the subcommand's own arguments, as typed (records such as calibrate's JSON keep them)
    args.argv = given[given.index(args.cmd) + 1:] if args.cmd in given else []
    commands = {"list": cmd_list, "run": cmd_run, "validate": cmd_validate}
    commands.update({name: mod.run for name, mod in _plugins().items()})
    try:
        limit = getattr(args, "max_particles", None)
        if limit is not None:
            if limit < 1:
                raise ParameterError(f"--max-particles = {limit} out of range; allowed [1, inf)")
            from .model import limits
            with limits.allow(limit):
                return commands[args.cmd](args)
        return commands[args.cmd](args)
    except ParameterError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("stopped: interrupted before the run started; nothing written", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
