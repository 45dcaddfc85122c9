"""Host driver: compiled chunks of steps, overflow → reallocate and redo, NaN guard,
progress bar and output.

    result = simulate(scene, t_end=0.4, output="results/run.h5", every=0.01)

Between chunks the driver reads the chunk's :class:`~fpsi_jax.model.state.Status`:

* neighbour overflow (or a smoothing length outgrowing the cut-off): the list is reallocated
  with more room from the state at the start of the chunk and the chunk is redone, so no
  pair is ever dropped;
* a bad particle (non-finite, density out of band, out of the domain): the run stops with
  :class:`SimulationError` naming the step, time, particle and quantity, and where that
  particle was in the last good frame; the output file keeps every frame written before
  (all of them finite).
"""
from __future__ import annotations

import contextlib
import dataclasses
import math
import signal
import threading
import time
from dataclasses import dataclass
from typing import Callable

import jax
import jax.numpy as jnp
import numpy as np

from ..model import limits
from ..model.config import KERNEL_SUPPORT, Physics
from ..model.options import FpiPressure
from ..model.errors import (FLOORED_VOIDAGE, Interrupted, ParameterError, SimulationError,
                            fmt, number)
from ..model.params import Params
from ..model.scene import Scene
from ..model.state import STATUS_CODES, State
from ..physics import dem
from ..solver import init, neighbors, stages, timestep
from ..solver import forward as stepper
from . import probes as probing
from . import io
from .io import Writer


@dataclass
class Result:
    state: State
    physics: Physics
    params: Params
    n_steps: int
    wall_s: float                    # from the first chunk's start to the end
    compile_s: float                 # the first chunk (with what compiling was left)
    rebuilds: int                    # of the SPH neighbour list
    reallocations: int
    observations: object = None
    output: str | None = None
    first_chunk_steps: int = 0
    probes: dict | None = None       # probe name -> (n_steps, k) values after every step
    steps_run: int | None = None     # steps this call ran (n_steps less a resumed start)
    dem_rebuilds: int = 0            # of the DEM neighbour list
    setup_s: float = 0.0             # before the first chunk: lists, first rates, compile
    regrowth_s: float = 0.0          # chunks after the first that grew a list (each growth
    regrowth_chunks: int = 0         # a recompile and the chunk redone; wall_s includes it)

    @property
    def times(self) -> np.ndarray:
        """Times after each step this call ran (the rows of ``observations`` and
        ``probes``; a resumed run's from where it resumed)."""
        first = self.n_steps - (self.n_steps if self.steps_run is None else self.steps_run)
        return (np.arange(first, self.n_steps) + 1) * float(self.params.dt)

    @property
    def throughput_includes_compile(self) -> bool:
        """Every step fell in the first chunk, so the throughput counts the compile too."""
        ran = self.n_steps if self.steps_run is None else self.steps_run
        return ran <= self.first_chunk_steps

    @property
    def particle_steps_per_s(self) -> float:
        """Throughput after the first chunk (which includes the compile), all particles;
        with every step in the first chunk, over the whole wall time (compile included)."""
        n = self.physics.n_fluid + self.physics.n_boundary + self.physics.n_solid
        ran = self.n_steps if self.steps_run is None else self.steps_run
        if self.throughput_includes_compile:
            return n * ran / self.wall_s if self.wall_s > 0 else 0.0
        return n * (ran - self.first_chunk_steps) / (self.wall_s - self.compile_s)

    @property
    def excluded(self) -> int:
        """Particles that left through an open side by the end of the run."""
        return excluded(self.state)


def setup(scene: Scene, dt: float | None = None, params: Params | None = None,
          unsafe_dt: bool = False, **physics_overrides):
    """Validate the scene and settings and return (Physics, Params with dt).
    Every check happens here, before anything is compiled. ``unsafe_dt=True`` lets a ``dt``
    above the stability bound through (stability stress tests only: the run may blow up,
    and then stops with :class:`SimulationError` as any other).

    With fluid and discs together the step is multi-rate: ``dt`` is the SPH step (default:
    the SPH bound) and the discs take ``dem_substeps`` sub-steps of dt/n inside it, n the
    fewest that keep dt/n under the DEM bound unless the caller fixes it (``dem_substeps=1``
    is the single-rate run, whose default dt is then the smaller of the two bounds).

    Sets JAX's process-wide x64 flag to the run's precision (``Physics.x64``): on for a
    float64 run, off for a float32 one."""
    scene.validate()
    limits.check(scene.n_particles, f"scene {scene.name!r}")
    phys = Physics.for_scene(scene, **physics_overrides)
    # JAX's x64 flag is process-wide: set it to this run's precision both ways, before the
    # step is derived (its bounds are JAX sums: a float32 scene set up after a float64 run
    # got a step 3e-9 different, and a marginal run went another way), and so that a
    # float32 run after a float64 one (fpsi validate runs every case in one process) is not
    # traced with x64 on, where weakly typed constants promote parts of the step to float64
    jax.config.update("jax_enable_x64", bool(phys.x64))
    params = (params or scene.params)
    for name, value in params.flat().items():    # the bounds below read numbers
        if name != "gravity" and np.ndim(value) != 0:
            raise ParameterError(f"{name} has shape {np.shape(value)}; allowed one number")
    opts = {**scene.options, **physics_overrides}
    given = opts.get("dem_substeps") is not None
    n_sub = int(opts["dem_substeps"]) if given else 1
    dt = scene.dt if dt is None else dt
    if dt is None:
        if phys.has_fluid and phys.has_solid and not given:
            dt = timestep.sph_dt(scene, params, phys=phys)
            n_sub = timestep.substeps_for(scene, dt, params, phys=phys)
        else:
            dt = timestep.stable_dt(scene, params, substeps=n_sub, phys=phys)
    elif phys.has_fluid and phys.has_solid and not given:
        n_sub = timestep.substeps_for(scene, float(dt), params, phys=phys)
    if not unsafe_dt:
        timestep.check_dt(scene, float(dt), params, substeps=n_sub,
                          auto_substeps=phys.has_fluid and phys.has_solid and not given,
                          phys=phys)
    elif not float(dt) > 0:
        raise ParameterError(f"dt = {dt} out of range; allowed (0, inf) with unsafe_dt")
    phys = dataclasses.replace(phys, dem_substeps=n_sub)
    params = params.replace(dt=float(dt)).validate()
    return init.fit_wall_width(scene, init.room_for_breakage(phys, params)), params


#: the step counter is int32 inside the compiled step
MAX_STEPS = 2 ** 31 - 1


def check_steps(t_end: float, dt: float) -> int:
    """The number of steps to ``t_end``, ⌈t_end/Δt⌉ (the last ends at or just past
    t_end); ParameterError past what the step counter holds."""
    n = math.ceil(t_end / dt - 1e-9)
    if n > MAX_STEPS:
        raise ParameterError(f"t_end = {fmt(t_end)} s needs {n:.3g} steps of {fmt(dt)} s; "
                             f"allowed at most {MAX_STEPS:,} steps (t_end <= "
                             f"{fmt(MAX_STEPS * dt)} s)")
    return int(n)


_advance = jax.jit(stepper.advance, static_argnums=(0, 4, 5))


def grow(phys: Physics, failed: State) -> Physics:
    """Physics with neighbour lists that fit what ``failed`` (a redone chunk's end state)
    ran out of: more capacity after an overflow, a larger cut-off if h outgrew it, the DEM
    list's skin test at every sub-step if a disc passed half its skin between the
    once-a-step tests (Physics.dem_list_substeps)."""
    if phys.has_fluid:
        nb = phys.neighbors
        if bool(failed.status.h_exceeded):
            # Room for the largest finite h the chunk reached (its steps past the one that
            # outgrew the cut-off are inexact but tell how far h goes: water running into a
            # bed's pores, Physics.pore_neighbours), at least 1.25× and at most 3× (a chunk
            # that also blew up can end with any h). The wall rows' width, set at set-up,
            # grows with the reach's area: the wider reach would overflow it at every redo.
            h = np.asarray(failed.fluid.h, float)
            h_reached = float(np.max(h, where=np.isfinite(h), initial=0.0))
            grown = min(3.0, max(1.25, 1.1 * KERNEL_SUPPORT * h_reached / nb.r_cut))
            nb = dataclasses.replace(nb, r_cut=nb.r_cut * grown, wall_width=int(
                math.ceil(nb.wall_width * grown ** 2)) if nb.wall_width else nb.wall_width)
            phys = dataclasses.replace(phys, h_margin=phys.h_margin * grown)
        if neighbors.overflowed(failed.nbrs):
            nb = neighbors.grow(nb, failed.nbrs, np.asarray(failed.status.sph_need))
        phys = dataclasses.replace(phys, neighbors=nb)
    if phys.has_solid and failed.status.dem_stale is not None and bool(failed.status.dem_stale):
        phys = dataclasses.replace(phys, dem_list_substeps=True)
    if phys.has_solid and neighbors.overflowed(failed.solid_nbrs):
        phys = dataclasses.replace(phys, dem_neighbors=neighbors.grow(
            phys.dem_neighbors, failed.solid_nbrs, np.asarray(failed.status.dem_need),
            both=True))
    return phys


def first_state(scene: Scene, phys: Physics, params: Params, max_regrowths: int = 12,
                beside: Callable | None = None):
    """(Physics, the initial State) with lists that hold the first positions: a list whose
    allocation overflowed (only the wall rows' width can, NeighborConfig.wall_width, when
    ``phys`` was not measured on these positions by :func:`setup`) is grown and allocated
    afresh before the first rates are evaluated.

    ``beside(phys, state)``, if given, runs in a second thread while the first rates are
    compiled and evaluated, on the allocated state (which has the shapes of every later
    state): :func:`simulate` compiles its chunk there. Compiling a program is one core's
    work, so on a machine with two cores the two compilations overlap (a coupled scene's
    set-up and chunk take 4–10 s each)."""
    for _ in range(max_regrowths + 1):
        state = init.allocated_state(scene, phys)
        if state.nbrs is None or not neighbors.overflowed(state.nbrs):
            with _running_beside(beside, phys, state):
                return phys, init.initial_rates(phys, state, params)
        phys = grow(phys, state)
    raise RuntimeError(f"the first neighbour lists still overflowed after {max_regrowths} "
                       "regrowths")


@contextlib.contextmanager
def _running_beside(fn, *args):
    """Context: ``fn(*args)`` in a daemon thread from entry, joined at exit. What it raises
    is dropped: it only prepares work (a compilation) that the main thread does again, and
    fails the same way there, if it must."""
    def quietly():
        try:
            fn(*args)
        except Exception:       # noqa: BLE001 (see the docstring)
            pass

    thread = None
    if fn is not None:
        thread = threading.Thread(target=quietly, daemon=True)
        thread.start()
    try:
        yield
    finally:
        if thread is not None:
            thread.join()


def reallocate(phys: Physics, state: State) -> State:
    """``state`` with its neighbour lists allocated afresh for ``phys`` (the contact shear
    history is re-addressed to the new list by pair)."""
    if phys.has_fluid:
        state = state.replace(nbrs=neighbors.allocate(phys.neighbors,
                                                      stages.sph_positions(state)))
    if phys.has_solid:
        new = neighbors.allocate(phys.dem_neighbors, state.solid.x)
        shear = dem.remap_history(state.solid_nbrs.idx, state.solid.shear, new.idx)
        state = state.replace(solid_nbrs=new, solid=state.solid.replace(shear=shear))
        state = stages.with_walls_near(phys, state)
    return state


def raise_if_unstable(status, dt: float, output: str | None = None,
                      t_good: float | None = None, good: State | None = None,
                      phys: Physics | None = None) -> None:
    """Raise :class:`SimulationError` (step, time, particle, quantity) if ``status`` (a
    chunk's :class:`~fpsi_jax.model.state.Status`) records a bad particle; with ``good``,
    the chunk's start State (the last good frame), also where that particle was then and,
    for a fluid particle among grains, its voidage: what to look at in the output."""
    if not bool(status.bad):
        return
    code = int(status.code)
    i, phase = int(status.particle), "solid" if code >= 6 else "fluid"
    position = voidage = None
    if good is not None:
        body = good.solid if phase == "solid" else good.fluid
        if body is not None and 0 <= i < body.x.shape[0]:
            position = tuple(float(v) for v in np.asarray(body.x[i]))
            if phase == "fluid" and good.fpi is not None:
                voidage = float(good.fpi.eps[i])
    set_up = () if phys is None else (
        ("floored",) * (phys.eps_floor >= FLOORED_VOIDAGE)
        + ("no_pore_h",) * (phys.pore_neighbours >= 1.0
                            or phys.fpi_pressure is not FpiPressure.SHARED))
    raise SimulationError(int(status.step), int(status.step) * dt, i, STATUS_CODES[code],
                          phase=phase, output=output, t_good=t_good, position=position,
                          voidage=voidage, set_up=set_up)


def check_rollout(end: State, params: Params) -> None:
    """What :func:`simulate` checks after every chunk, for the end state of a
    :func:`fpsi_jax.solver.rollout` (outside ``jax.grad``/``jit``, on concrete values):
    :class:`SimulationError` (step, time, particle, quantity) when a particle went bad,
    RuntimeError when a neighbour list overflowed (some pairs were left out from the
    step it names on, so the rollout is not the model's; ``simulate`` grows the list and
    redoes the chunk)."""
    st = end.status
    raise_if_unstable(st, float(params.dt))
    if bool(st.overflow):
        raise RuntimeError(f"a neighbour list overflowed at step {int(st.redo_step)} of this "
                           "rollout: pairs were left out from there on; take the lists as a "
                           "forward run grows them, phys = simulate(scene, t_end=...)"
                           ".physics, then init_state(scene, phys, p) and rollout(phys, ...)")


@dataclass
class Chunk:
    """A chunk that ran with every pair: the Physics and start State it finally used (grown
    and reallocated ``regrowths`` times), its end State and what ``attempt`` returned."""
    phys: Physics
    state: State
    end: State
    result: object
    regrowths: int


def run_until_fits(attempt: Callable, phys: Physics, state: State, dt: float, *,
                   output: str | None = None, max_regrowths: int = 12,
                   on_regrowth: Callable | None = None):
    """The one chunk / redo / error loop that the driver, calibration and the benchmarks
    share. ``attempt(phys, state) -> (end, result)`` runs a compiled chunk from ``state``;
    ``end`` is the chunk's end State (only its ``status`` is read unless the chunk must be
    redone). When a neighbour list overflowed (or h outgrew the cut-off) before anything
    went bad, the lists are grown for what ``end`` ran out of, ``state`` is reallocated
    and the chunk redone, so no pair is ever dropped (``on_regrowth()``, if given, is called
    first: the progress line says why it stops); a chunk that went unstable raises
    :class:`SimulationError`. Returns a :class:`Chunk`."""
    for k in range(max_regrowths + 1):
        end, result = attempt(phys, state)
        if end.status.must_redo():
            if on_regrowth is not None:
                on_regrowth()
            phys = grow(phys, end)
            state = reallocate(phys, state)
            continue
        raise_if_unstable(end.status, dt, output, t_good=float(state.t), good=state,
                          phys=phys)
        return Chunk(phys=phys, state=state, end=end, result=result, regrowths=k)
    raise RuntimeError(f"the neighbour lists still overflowed after {max_regrowths} "
                       "regrowths")


def simulate(scene: Scene, t_end: float | None = None, output: str | None = None,
             every: float | None = None, progress: bool = True, dt: float | None = None,
             params: Params | None = None, observe: Callable | None = None,
             chunk_steps: int | None = None, state: State | None = None,
             unsafe_dt: bool = False, probes=None, resume: str | None = None,
             overwrite: bool = False, run_info: dict | None = None,
             **physics_overrides) -> Result:
    """Run ``scene`` to ``t_end`` (default scene.t_end: ⌈t_end/Δt⌉ steps, the last ending at
    or just past it; ``Result.times``) in compiled chunks. Runs on the host
    (chunks, list regrowth, checks, output), so it is not differentiable: ``jax.grad``
    goes through :func:`fpsi_jax.solver.rollout` (README, Quickstart: Python).

    output      HDF5 path (an .xdmf sidecar is written next to it); None: no file. An
                existing file is refused unless ``overwrite`` (and only if fpsi-jax wrote it)
    every       seconds between frames (default t_end/100); also the chunk length
    dt          time step; default: the stability bound; larger than the bound is refused
                unless ``unsafe_dt`` (stress tests)
    observe     state → small pytree recorded every step (returned stacked over steps)
    probes      :class:`~fpsi_jax.run.probes.Probe` list recorded every step: returned in
                ``Result.probes``, written to ``/probes`` of the output file and to
                ``<output>_probes.csv`` (up to the last good chunk if the run goes unstable)
    resume      an output file of a stopped run of the same scene and settings: the run
                continues from its last complete frame (every leaf of the state restored,
                neighbour lists and contact history included; bitwise what the
                uninterrupted run gives on CPU) and appends to that file
    run_info    JSON-able record of how the run was started, kept in the file (``fpsi run``
                stores its arguments there for ``--resume``)
    physics_overrides   Physics options (e.g. delta_sph=True, x64=True)

    A run that goes unstable or is interrupted raises with what it recorded up to its last
    good chunk on the exception: ``observations``, ``probes`` (as in :class:`Result`) and
    ``times`` (the steps' end times), None where nothing was recorded.

    SIGINT and SIGTERM stop the run at the end of the current chunk with
    :class:`~fpsi_jax.model.errors.Interrupted` (the file says ``status = interrupted``); a
    write error stops it with :class:`~fpsi_jax.run.io.OutputError` (``status = failed``).
    """
    t_end = number("t_end", scene.t_end if t_end is None else t_end, 0.0, None, lo_open=True)
    every = t_end / 100 if every is None else number("every", every, 0.0, t_end, lo_open=True)
    ck = None
    if resume is not None:
        ck = io.load_checkpoint(resume)
        output = str(resume)
    elif output:
        io.check_output(output, overwrite)
    rows = probing.wall_force_rows(probes)
    if rows and "wall_force" not in physics_overrides:   # an obstacle force probe's rows
        had = scene.options.get("wall_force") or rows
        physics_overrides["wall_force"] = (min(rows[0], had[0]), max(rows[1], had[1]))
    if probing.wall_reaction(probes):           # an obstacle force probe's DEM walls
        physics_overrides.setdefault("wall_reaction", True)
    held = probing.held_discs(probes)
    if held and "disc_reaction" not in physics_overrides:   # a force probe on held discs
        had = tuple(scene.options.get("disc_reaction") or ())
        physics_overrides["disc_reaction"] = tuple(sorted(set(had) | set(held)))
    phys, params = setup(scene, dt, params, unsafe_dt=unsafe_dt, **physics_overrides)
    dt = float(params.dt)
    p = params.as_arrays(stages.dtype(phys))
    n_total = check_steps(t_end, dt)
    chunk = chunk_steps or max(1, int(round(every / dt)))
    t_setup = time.perf_counter()

    probes = probing.check_names(probes)
    user_observe = observe
    if probes:
        record = probing.observer(probes)
        observe = lambda s: (None if user_observe is None else user_observe(s), record(s))
    if ck is not None:
        phys = grown_like(phys, ck.physics)
        state = io.restore(init.init_state(scene, phys, p), ck)
        io.truncate_probes(output, float(state.t))
    elif state is None:
        def compile_chunk(ph, st):        # the chunks' program, run for 0 steps
            jax.block_until_ready(_advance(ph, st, p, jnp.asarray(0, jnp.int32), chunk,
                                           observe))

        phys, state = first_state(scene, phys, p, beside=compile_chunk)
    done = start = int(state.step)
    writer = None
    if output:
        writer = Writer(output, scene, phys, params, probes, run_info=run_info,
                        resume=ck is not None)
    obs_chunks, reallocs, compile_s, first, regrowth_s, regrowth_chunks = [], 0, 0.0, 0, 0.0, 0
    t0 = time.perf_counter()
    bar = _Progress(scene.name, n_total, done) if progress else None
    stop = _StopSignals()
    status, message = "finished", ""
    try:
        if writer and ck is None:
            writer.write(state)
        while done < n_total:
            n = min(chunk, n_total - done)

            def attempt(ph, st):
                new, obs = _advance(ph, st, p, jnp.asarray(n, jnp.int32), chunk, observe)
                jax.block_until_ready(new.status.bad)
                return new, obs

            t_chunk = time.perf_counter()
            c = run_until_fits(attempt, phys, state, dt, output=output,
                               on_regrowth=bar.regrowing if bar else None)
            phys, state, reallocs = c.phys, c.end, reallocs + c.regrowths
            if not first:
                compile_s = time.perf_counter() - t0   # compile + first chunk
                first = n
            elif c.regrowths:
                regrowth_s += time.perf_counter() - t_chunk
                regrowth_chunks += 1
            obs = jax.tree_util.tree_map(lambda a: a[:n], c.result)   # rows past n unused
            if observe is not None:
                obs_chunks.append(jax.tree_util.tree_map(np.asarray, obs))
            if writer and probes:
                writer.write_probes((np.arange(done, done + n) + 1) * dt, obs_chunks[-1][1])
            done += n
            if writer:
                if c.regrowths:
                    writer.set_physics(phys)
                writer.write(state)
            if bar:
                bar.advance(n, excluded(state))
            if stop.signal and done < n_total:
                err = Interrupted(stop.signal, done, done * dt,
                                  writer.frames if writer else 0, output)
                status, message = "interrupted", str(err)
                raise err
    except SimulationError as e:
        status, message = "unstable", str(e)
        _keep_history(e, obs_chunks, probes, done, dt, start)
        raise
    except Interrupted as e:
        _keep_history(e, obs_chunks, probes, done, dt, start)
        raise
    except io.OutputError as e:
        status, message = "failed", str(e)
        raise
    except BaseException as e:            # anything else: the file says it did not finish
        if status == "finished":
            status, message = "failed", f"{type(e).__name__}: {e}"
        raise
    finally:
        stop.restore()
        if bar:
            bar.close()
        if writer:
            writer.close(status, message)
        if output and probes:
            _write_probe_csv(output, probes)
    wall = time.perf_counter() - t0
    observations, probe_values = _stacked(obs_chunks, probes)
    return Result(state=state, physics=phys, params=params, n_steps=done, wall_s=wall,
                  compile_s=compile_s, setup_s=t0 - t_setup,
                  rebuilds=int(state.status.rebuilds), dem_rebuilds=int(state.status.dem_rebuilds),
                  reallocations=reallocs, observations=observations, output=output,
                  first_chunk_steps=first, probes=probe_values, regrowth_s=regrowth_s,
                  regrowth_chunks=regrowth_chunks,
                  steps_run=done - (ck and int(ck.leaves[".step"]) or 0))


def _stacked(obs_chunks, probes):
    """(observations, probe values) stacked over the chunks' steps, None where none."""
    if not obs_chunks:
        return None, None
    observations = jax.tree_util.tree_map(lambda *a: np.concatenate(a), *obs_chunks)
    return tuple(observations) if probes else (observations, None)


def _keep_history(err, obs_chunks, probes, done, dt, start):
    """What a stopped run recorded, on its exception (``simulate``'s docstring)."""
    err.observations, err.probes = _stacked(obs_chunks, probes)
    err.times = (np.arange(start, done) + 1) * dt if obs_chunks else None


@dataclass
class Stopped:
    """What the file of a run that stopped early holds, as far as plots read a
    :class:`Result`: the state at its last complete frame and the probes up to it."""
    state: State
    times: np.ndarray
    probes: dict


def stopped(scene: Scene, output: str, dt: float | None = None, unsafe_dt: bool = False,
            **physics_overrides) -> Stopped:
    """The last good frame of ``output``, a run of ``scene`` with these settings that went
    unstable or was interrupted (its checkpoint, as ``simulate(resume=...)`` restores it),
    and its probes up to that frame: what ``fpsi run --plot`` draws for such a run."""
    ck = io.load_checkpoint(output)
    phys, params = setup(scene, dt, unsafe_dt=unsafe_dt, **physics_overrides)
    phys = grown_like(phys, ck.physics)
    p = params.as_arrays(stages.dtype(phys))
    state = io.restore(init.init_state(scene, phys, p), ck)
    times, values = io.read_probes(output)
    return Stopped(state=state, times=times, probes=values)


def grown_like(phys: Physics, saved: dict) -> Physics:
    """``phys`` with the neighbour-list sizes of ``saved`` (a run's Physics as JSON, as it
    had grown when it was checkpointed)."""
    for key in ("neighbors", "dem_neighbors"):
        cfg, old = getattr(phys, key), saved.get(key)
        if cfg is not None and old:
            cfg = dataclasses.replace(cfg, r_cut=float(old["r_cut"]),
                                      extra_capacity=int(old["extra_capacity"]),
                                      min_neighbors=int(old.get("min_neighbors", 0)),
                                      min_cell_capacity=int(old.get("min_cell_capacity", 0)),
                                      wall_width=int(old.get("wall_width", cfg.wall_width)))
            phys = dataclasses.replace(phys, **{key: cfg})
    return dataclasses.replace(phys, h_margin=float(saved.get("h_margin", phys.h_margin)),
                               dem_list_substeps=bool(saved.get("dem_list_substeps",
                                                                phys.dem_list_substeps)))


def excluded(state: State) -> int:
    """Particles (fluid and discs) that have left through an open side."""
    return sum(int(np.sum(np.asarray(b.t_out) >= 0)) for b in (state.fluid, state.solid)
               if b is not None and b.t_out is not None)


class _StopSignals:
    """SIGINT and SIGTERM set ``signal`` (their name) instead of stopping the process, so
    the driver stops at the end of the chunk; the old handlers come back on restore()."""

    def __init__(self):
        self.signal, self.old = None, {}
        if threading.current_thread() is not threading.main_thread():
            return
        for sig in (signal.SIGINT, signal.SIGTERM):
            self.old[sig] = signal.signal(sig, self._set)

    def _set(self, signum, frame):
        self.signal = signal.Signals(signum).name

    def restore(self):
        for sig, handler in self.old.items():
            signal.signal(sig, handler)
        self.old = {}


class _Progress:
    """The progress line: 'compiling' until the first chunk is back, then a bar whose rate
    and ETA count only the steps after it; the excluded particles as a postfix."""

    def __init__(self, name, total, done):
        from tqdm.auto import tqdm
        self.tqdm, self.name, self.total = tqdm, name, total
        self.bar = tqdm(total=None, desc=f"{name}: compiling", unit="", leave=False,
                        bar_format="{desc} {elapsed}")
        self.first, self.done = True, done

    def advance(self, n, n_out):
        self.done += n
        if self.first:
            self.bar.close()
            self.bar = self.tqdm(total=self.total, initial=self.done, desc=self.name,
                                 unit="step", leave=False)
            self.first = False
        if n_out:
            self.bar.set_postfix(left=n_out, refresh=False)
        else:
            self.bar.set_postfix_str("", refresh=False)
        if self.bar.n < self.done:
            self.bar.update(self.done - self.bar.n)

    def regrowing(self):
        """Say why the bar stops: a list grew, the step is recompiled, the chunk redone."""
        if not self.first:
            self.bar.set_postfix_str("a neighbour list grew: recompiling", refresh=True)

    def close(self):
        self.bar.close()


def _write_probe_csv(output, probes):
    """``<output>_probes.csv`` from the file's /probes (every row, resumed runs too)."""
    import h5py
    with h5py.File(output, "r", locking=False) as f:
        g = f["probes"]
        values = {pr.name: g[pr.name][:] for pr in probes}
        times = g["time"][:]
    probing.write_csv(probing.csv_path(output), probes, times, values)


def _stack(obs_chunks, probes):
    """(user observations, {probe: (n, k)}) of the chunks so far (empty arrays if none)."""
    if not obs_chunks:
        return None, {p.name: np.zeros((0, len(p.components))) for p in probes}
    return jax.tree_util.tree_map(lambda *a: np.concatenate(a), *obs_chunks)
