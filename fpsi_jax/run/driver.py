"""Host driver: compiled chunks of steps, overflow → reallocate and redo, NaN guard,
progress bar and output.

    result = simulate(scene, t_end=0.4, output="results/run.h5", every=0.01)

Between chunks the driver reads the chunk's :class:`~fpsi_jax.state.Status`:

* neighbour overflow (or a smoothing length outgrowing the cut-off): the list is reallocated
  with more room from the state at the start of the chunk and the chunk is redone, so no
  pair is ever dropped;
* a bad particle (non-finite, density out of band, out of the domain): the run stops with
  :class:`SimulationError` naming the step, time, particle and quantity; the output file
  keeps every frame written before (all of them finite).
"""
from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass
from typing import Callable

import jax
import jax.numpy as jnp
import numpy as np

from ..model import limits
from ..model.config import Physics
from ..model.errors import ParameterError, SimulationError, fmt, number
from ..model.params import Params
from ..model.scene import Scene
from ..model.state import STATUS_CODES, State
from ..physics import dem
from ..solver import init, neighbors, stages, timestep
from ..solver import forward as stepper
from . import probes as probing
from .io import Writer


@dataclass
class Result:
    state: State
    physics: Physics
    params: Params
    n_steps: int
    wall_s: float
    compile_s: float
    rebuilds: int
    reallocations: int
    observations: object = None
    output: str | None = None
    first_chunk_steps: int = 0
    probes: dict | None = None       # probe name -> (n_steps, k) values after every step

    @property
    def times(self) -> np.ndarray:
        """Times after each step (the rows of ``observations`` and ``probes``)."""
        return (np.arange(self.n_steps) + 1) * float(self.params.dt)

    @property
    def particle_steps_per_s(self) -> float:
        """Throughput after the first chunk (which includes the compile), all particles."""
        n = self.physics.n_fluid + self.physics.n_boundary + self.physics.n_solid
        steps = self.n_steps - self.first_chunk_steps
        run = self.wall_s - self.compile_s
        return n * steps / run if steps > 0 and run > 0 else float("nan")


def setup(scene: Scene, dt: float | None = None, params: Params | None = None,
          unsafe_dt: bool = False, **physics_overrides):
    """Validate the scene and settings and return (Physics, Params with dt).
    Every check happens here, before anything is compiled. ``unsafe_dt=True`` lets a ``dt``
    above the stability bound through (stability stress tests only: the run may blow up,
    and then stops with :class:`SimulationError` as any other).

    With fluid and discs together the step is multi-rate: ``dt`` is the SPH step (default:
    the SPH bound) and the discs take ``dem_substeps`` sub-steps of dt/n inside it, n the
    fewest that keep dt/n under the DEM bound unless the caller fixes it (``dem_substeps=1``
    is the single-rate run, whose default dt is then the smaller of the two bounds)."""
    scene.validate()
    limits.check(scene.n_particles, f"scene {scene.name!r}")
    phys = Physics.for_scene(scene, **physics_overrides)
    params = (params or scene.params)
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
    if phys.x64:
        jax.config.update("jax_enable_x64", True)
    return phys, params


#: the step counter is int32 inside the compiled step
MAX_STEPS = 2 ** 31 - 1


def check_steps(t_end: float, dt: float) -> int:
    """The number of steps to ``t_end``; ParameterError past what the step counter holds."""
    n = math.ceil(t_end / dt - 1e-9)
    if n > MAX_STEPS:
        raise ParameterError(f"t_end = {fmt(t_end)} s needs {n:.3g} steps of {fmt(dt)} s; "
                             f"allowed at most {MAX_STEPS:,} steps (t_end <= "
                             f"{fmt(MAX_STEPS * dt)} s)")
    return int(n)


_advance = jax.jit(stepper.advance, static_argnums=(0, 4, 5))


def grow(phys: Physics, failed: State) -> Physics:
    """Physics with neighbour lists that fit what ``failed`` (a redone chunk's end state)
    ran out of: more capacity after an overflow, a larger cut-off if h outgrew it."""
    if phys.has_fluid:
        nb = phys.neighbors
        if bool(failed.status.h_exceeded):
            nb = dataclasses.replace(nb, r_cut=nb.r_cut * 1.25)
            phys = dataclasses.replace(phys, h_margin=phys.h_margin * 1.25)
        if neighbors.overflowed(failed.nbrs):
            nb = neighbors.grow(nb, failed.nbrs)
        phys = dataclasses.replace(phys, neighbors=nb)
    if phys.has_solid and neighbors.overflowed(failed.solid_nbrs):
        phys = dataclasses.replace(
            phys, dem_neighbors=neighbors.grow(phys.dem_neighbors, failed.solid_nbrs))
    return phys


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
    return state


def raise_if_unstable(status, dt: float, output: str | None = None,
                      t_good: float | None = None) -> None:
    """Raise :class:`SimulationError` (step, time, particle, quantity) if ``status`` (a
    chunk's :class:`~fpsi_jax.model.state.Status`) records a bad particle."""
    if not bool(status.bad):
        return
    code = int(status.code)
    raise SimulationError(int(status.step), int(status.step) * dt, int(status.particle),
                          STATUS_CODES[code], phase="solid" if code >= 6 else "fluid",
                          output=output, t_good=t_good)


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
                   output: str | None = None, max_regrowths: int = 12):
    """The one chunk / redo / error loop that the driver, calibration and the benchmarks
    share. ``attempt(phys, state) -> (end, result)`` runs a compiled chunk from ``state``;
    ``end`` is the chunk's end State (only its ``status`` is read unless the chunk must be
    redone). When a neighbour list overflowed (or h outgrew the cut-off) before anything
    went bad, the lists are grown for what ``end`` ran out of, ``state`` is reallocated
    and the chunk redone, so no pair is ever dropped; a chunk that went unstable raises
    :class:`SimulationError`. Returns a :class:`Chunk`."""
    for k in range(max_regrowths + 1):
        end, result = attempt(phys, state)
        if end.status.must_redo():
            phys = grow(phys, end)
            state = reallocate(phys, state)
            continue
        raise_if_unstable(end.status, dt, output, t_good=float(state.t))
        return Chunk(phys=phys, state=state, end=end, result=result, regrowths=k)
    raise RuntimeError(f"the neighbour lists still overflowed after {max_regrowths} "
                       "regrowths")


def simulate(scene: Scene, t_end: float | None = None, output: str | None = None,
             every: float | None = None, progress: bool = True, dt: float | None = None,
             params: Params | None = None, observe: Callable | None = None,
             chunk_steps: int | None = None, state: State | None = None,
             unsafe_dt: bool = False, probes=None, **physics_overrides) -> Result:
    """Run ``scene`` to ``t_end`` (default scene.t_end) in compiled chunks.

    output      HDF5 path (an .xdmf sidecar is written next to it); None: no file
    every       seconds between frames (default t_end/100); also the chunk length
    dt          time step; default: the stability bound; larger than the bound is refused
                unless ``unsafe_dt`` (stress tests)
    observe     state → small pytree recorded every step (returned stacked over steps)
    probes      :class:`~fpsi_jax.run.probes.Probe` list recorded every step: returned in
                ``Result.probes``, written to ``/probes`` of the output file and to
                ``<output>_probes.csv`` (up to the last good chunk if the run goes unstable)
    physics_overrides   Physics options (e.g. delta_sph=True, x64=True)
    """
    t_end = number("t_end", scene.t_end if t_end is None else t_end, 0.0, None, lo_open=True)
    every = t_end / 100 if every is None else number("every", every, 0.0, t_end, lo_open=True)
    phys, params = setup(scene, dt, params, unsafe_dt=unsafe_dt, **physics_overrides)
    dt = float(params.dt)
    p = params.as_arrays(stages.dtype(phys))
    n_total = check_steps(t_end, dt)
    chunk = chunk_steps or max(1, int(round(every / dt)))

    probes = probing.check_names(probes)
    user_observe = observe
    if probes:
        record = probing.observer(probes)
        observe = lambda s: (None if user_observe is None else user_observe(s), record(s))
    state = init.init_state(scene, phys, p) if state is None else state
    writer = Writer(output, scene, phys, params, probes) if output else None
    if writer:
        writer.write(state)
    bar = None
    if progress:
        from tqdm.auto import tqdm
        bar = tqdm(total=n_total, desc=scene.name, unit="step", leave=False)
    obs_chunks, done, reallocs, compile_s, first = [], 0, 0, 0.0, 0
    t0 = time.perf_counter()
    try:
        while done < n_total:
            n = min(chunk, n_total - done)

            def attempt(ph, st):
                new, obs = _advance(ph, st, p, jnp.asarray(n, jnp.int32), chunk, observe)
                jax.block_until_ready(new.status.bad)
                return new, obs

            c = run_until_fits(attempt, phys, state, dt, output=output)
            phys, state, reallocs = c.phys, c.end, reallocs + c.regrowths
            if done == 0:
                compile_s = time.perf_counter() - t0   # compile + first chunk
                first = n
            obs = jax.tree_util.tree_map(lambda a: a[:n], c.result)   # rows past n unused
            if observe is not None:
                obs_chunks.append(jax.tree_util.tree_map(np.asarray, obs))
            if writer and probes:
                writer.write_probes((np.arange(done, done + n) + 1) * dt, obs_chunks[-1][1])
            done += n
            if writer:
                writer.write(state)
            if bar:
                bar.update(n)
    except SimulationError as e:
        if writer:
            writer.close("unstable", str(e))
            writer = None
        raise
    finally:
        if bar:
            bar.close()
        if writer:
            writer.close()
        if output and probes:
            probing.write_csv(probing.csv_path(output), probes,
                              (np.arange(done) + 1) * dt, _stack(obs_chunks, probes)[1])
    wall = time.perf_counter() - t0
    observations, probe_values = None, None
    if obs_chunks:
        observations = jax.tree_util.tree_map(lambda *a: np.concatenate(a), *obs_chunks)
        if probes:
            observations, probe_values = observations
    return Result(state=state, physics=phys, params=params, n_steps=done, wall_s=wall,
                  compile_s=compile_s, rebuilds=int(state.status.rebuilds),
                  reallocations=reallocs, observations=observations, output=output,
                  first_chunk_steps=first, probes=probe_values)


def _stack(obs_chunks, probes):
    """(user observations, {probe: (n, k)}) of the chunks so far (empty arrays if none)."""
    if not obs_chunks:
        return None, {p.name: np.zeros((0, len(p.components))) for p in probes}
    return jax.tree_util.tree_map(lambda *a: np.concatenate(a), *obs_chunks)
