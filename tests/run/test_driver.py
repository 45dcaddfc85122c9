"""The host driver (fpsi_jax.run.driver): unstable runs stop with a diagnosis and leave a
valid, finite file; frames and speed; dt overrides; an overflowing neighbour list is regrown
and its chunk redone; the last short chunk and a second run reuse the compiled program."""
import dataclasses
import json

import h5py
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from fpsi_jax import cases
from fpsi_jax.cases import overrides
from fpsi_jax.model.errors import ParameterError, SimulationError
from fpsi_jax.run import driver, io
from fpsi_jax.run.driver import _advance, setup, simulate
from fpsi_jax.solver import forward, init, neighbors, stages


def test_unstable_run_stops_with_diagnosis_and_keeps_good_frames(tmp_path):
    # c0 = 3 m/s is far below 10 v_max (24 m/s): the column compresses until the density leaves
    # the allowed band -- a deliberately unstable run.
    sc = cases.build("dam_break", dx=0.02, c0=3.0, t_end=0.5)
    out = tmp_path / "bad.h5"
    with pytest.raises(SimulationError) as info:
        simulate(sc, output=str(out), every=0.02, progress=False,
                 observe=lambda s: s.fluid.x[0, 1])
    e = info.value
    msg = str(e)
    # what observe recorded up to the last good chunk comes with the exception
    assert e.observations.shape == e.times.shape and e.probes is None
    assert e.times[-1] < e.time and e.times.size == round(e.times[-1] / (e.times[0]))
    assert np.isfinite(e.observations).all()
    assert "step" in msg and "t =" in msg and "fluid particle" in msg
    assert e.step > 0 and e.particle >= 0 and e.quantity
    run = io.read(out)
    assert run.status == "unstable"
    assert run.frames >= 2                                 # the good frames are there
    assert run.time[-1] < e.time
    assert e.times[-1] == pytest.approx(run.time[-1], rel=1e-6)   # the last good chunk
    for k, a in run.fluid.items():
        assert np.all(np.isfinite(a)), k                   # and no NaN was written
    with h5py.File(out) as f:
        assert "unstable" in f.attrs["message"]
    # where the particle was in the last good frame, the file's last frame
    np.testing.assert_allclose(e.position, run.fluid["x"][-1][e.particle], rtol=1e-6)
    assert f"x = {e.position[0]:.4g}, y = {e.position[1]:.4g} m in the last good" in msg
    assert e.voidage is None and "voidage" not in msg          # no grains in this scene


def test_an_unstable_fluid_particle_among_grains_is_named_with_its_voidage():
    """The message gives the last good frame's position and, among grains, the voidage:
    a fluid particle beside the settling grain marked bad in the scene's first state."""
    import jax.numpy as jnp
    from fpsi_jax.run.driver import raise_if_unstable, setup
    from fpsi_jax.solver import init_state
    sc = cases.build("sedimentation", dx=0.004)
    phys, params = setup(sc)
    st = init_state(sc, phys, params.as_arrays(jnp.float32))
    i = int(np.argmin(np.asarray(st.fpi.eps)))                 # beside the grain
    bad = st.status.replace(bad=jnp.asarray(True), code=jnp.asarray(1, jnp.int32),
                            particle=jnp.asarray(i, jnp.int32), step=jnp.asarray(7, jnp.int32))
    with pytest.raises(SimulationError) as info:
        raise_if_unstable(bad, 1e-4, good=st)
    e = info.value
    assert e.particle == i and e.phase == "fluid"
    np.testing.assert_allclose(e.position, np.asarray(st.fluid.x[i]), rtol=1e-6)
    assert e.voidage == pytest.approx(float(st.fpi.eps[i])) and e.voidage < 0.999
    assert f"voidage {e.voidage:.3g})" in str(e)
    assert ("Packed beds" in str(e)) == (e.voidage < 0.8)      # an isolated grain: no hint


def test_an_unstable_pore_particle_of_a_packed_bed_is_pointed_to_the_floored_set_up():
    """Below the seeds' floor (ε < 0.8) the message names the keys that run a bed floored
    and where the docs discuss it; above it (clear water) it does not."""
    e = SimulationError(3, 0.1, 5, "density left the allowed band", position=(0.1, 0.01),
                        voidage=0.18)
    assert 'voidage = "mapped" with eps_floor = 0.8' in str(e) and "Packed beds" in str(e)
    assert "eps_floor" not in str(SimulationError(3, 0.1, 5, "x", position=(0.1, 0.01),
                                                  voidage=0.95))
    # a remedy the run already has is not offered again
    assert "pore_neighbours" in str(e)
    done = SimulationError(3, 0.1, 5, "x", position=(0.1, 0.01), voidage=0.18,
                           set_up=("no_pore_h",))
    assert "pore_neighbours" not in str(done) and "eps_floor = 0.8" in str(done)
    assert "Packed beds" not in str(SimulationError(3, 0.1, 5, "x", position=(0.1, 0.01),
                                                    voidage=0.18, set_up=("floored",)))


def test_simulate_writes_frames_and_reports_speed(tmp_path, tiny_tank):
    out = tmp_path / "tank.h5"
    res = simulate(tiny_tank, t_end=0.01, every=0.0025, output=str(out), progress=False)
    run = io.read(out)
    chunk = round(0.0025 / float(res.params.dt))
    frames = 1 + -(-res.n_steps // chunk)                  # t = 0, then one per chunk
    assert run.frames == frames >= 5
    np.testing.assert_allclose(run.time[-1], float(res.state.t), rtol=1e-6)
    assert run.fluid["x"].shape == (frames, tiny_tank.fluid.n, 2)
    assert run.status == "finished"
    assert res.n_steps > 0 and res.wall_s > 0


def test_dt_override_is_honoured_and_checked():
    """``--set dt=…`` (overrides.build) sets the step the run uses; above the bound it is
    refused; simulate's own dt argument wins over it."""
    sc, ph = overrides.build("hydrostatic_tank", {"dt": 1e-5, "dx": 0.02})
    assert float(setup(sc, **ph)[1].dt) == pytest.approx(1e-5)
    assert float(setup(sc, 2e-5, **ph)[1].dt) == pytest.approx(2e-5)
    sc, ph = overrides.build("hydrostatic_tank", {"dt": 1.0, "dx": 0.02})
    with pytest.raises(ParameterError, match="exceeds the stability bound"):
        setup(sc, **ph)
    with pytest.raises(ParameterError, match="dt = -1"):
        overrides.build("hydrostatic_tank", {"dt": -1})


# --- neighbour-list overflow: regrow and redo --------------------------------------------
def squeezed_block():
    """A free block of water (no walls, no gravity) whose particles converge on its centre:
    the neighbour count per particle roughly doubles within the run."""
    sc = cases.build("hydrostatic_tank", dx=0.01, depth=0.1, width=0.1, t_end=0.02)
    sc.boundary = None
    sc.params = sc.params.replace(gravity=(0.0, 0.0))
    c = sc.fluid.x.mean(axis=0)
    sc.fluid.v = -12.0 * (sc.fluid.x - c)
    sc.fluid.rho = np.full(sc.fluid.n, 1000.0)
    return sc


def test_a_stale_dem_list_is_redone_with_the_test_at_every_substep():
    """A grain at rest pushed past several half-skins of its DEM list within one step by
    a load that ramps up over that step (so the start's acceleration does not predict
    it): the once-a-step test misses it, the step flags the list stale, and the driver
    redoes the chunk with Physics.dem_list_substeps; the run then equals one made that way
    from the start."""
    from ..small_scenes import grain_scene
    sc = grain_scene(x64=False)
    phys, params = setup(sc)
    half = 0.5 * phys.dem_neighbors.skin
    # ramped over Δt: x(Δt) = aΔt²/6 = 4 half-skins
    sc.solid.f_ext = np.array([[24.0 * half / params.dt ** 2 * float(sc.solid.mass[0]), 0.0]])
    sc.params = sc.params.replace(dem=sc.params.dem.replace(load_ramp=params.dt))
    t_end = 2 * params.dt                     # a hard push: two steps of it, loose density band
    redone = simulate(sc, t_end=t_end, chunk_steps=1, progress=False, rho_tolerance=0.9)
    strict = simulate(sc, t_end=t_end, chunk_steps=1, progress=False, rho_tolerance=0.9,
                      dem_list_substeps=True)
    assert redone.physics.dem_list_substeps and redone.reallocations >= 1
    assert not bool(redone.state.status.dem_stale)
    np.testing.assert_array_equal(np.asarray(redone.state.solid.x),
                                  np.asarray(strict.state.solid.x))


def test_the_sph_and_the_dem_list_rebuilds_are_counted_apart():
    """A grain sinking through water with thin skins on both lists: Status.rebuilds counts
    up at the steps at which the SPH list's reference positions change, Status.dem_rebuilds
    at those of the DEM list, and the Result reports both."""
    from ..small_scenes import grain_scene
    sc = grain_scene(x64=False, rho_grain=2500.0)
    opts = dict(skin=0.02, dem_skin=0.1, h_margin=1.5)     # nothing regrown
    phys, params = setup(sc, **opts)

    def seen(s):
        return (jnp.sum(s.nbrs.reference_position), s.status.rebuilds,
                jnp.sum(s.solid_nbrs.reference_position), s.status.dem_rebuilds)

    res = simulate(sc, t_end=80 * params.dt, progress=False, observe=seen, **opts)
    assert res.reallocations == 0          # a reallocated list starts anew uncounted
    ref, count, dem_ref, dem_count = (np.asarray(o) for o in res.observations)
    np.testing.assert_array_equal(np.diff(count), np.diff(ref) != 0)
    np.testing.assert_array_equal(np.diff(dem_count), np.diff(dem_ref) != 0)
    assert np.sum(np.diff(ref) != 0) >= 3 and np.sum(np.diff(dem_ref) != 0) >= 3
    assert (res.rebuilds, res.dem_rebuilds) == (count[-1], dem_count[-1])


def test_overflow_is_redone_and_equals_a_large_allocation(tmp_path):
    # a thin skin (0.1 h), so the compression outgrows the list within the 24 steps
    out = tmp_path / "tight.h5"
    tight = simulate(squeezed_block(), progress=False, capacity_multiplier=1.0,
                     chunk_steps=20, rho_tolerance=0.9, skin=0.1, output=str(out))
    roomy = simulate(squeezed_block(), progress=False, capacity_multiplier=4.0,
                     chunk_steps=20, rho_tolerance=0.9, skin=0.1)
    assert tight.reallocations >= 1          # the tight list did overflow ...
    assert roomy.reallocations == 0
    assert roomy.regrowth_chunks == 0 and roomy.regrowth_s == 0.0
    grown = tight.physics.neighbors          # ... and grew to what its rebuilds counted
    assert grown.min_neighbors or grown.min_cell_capacity
    assert grown.extra_capacity == 0
    need = np.asarray(tight.state.status.sph_need)
    assert neighbors.capacity(tight.state.nbrs) >= need[0]
    assert tight.state.nbrs.cell_list_capacity >= need[1]
    with h5py.File(out) as f:                # the file knows the grown lists (for a resume)
        saved = json.loads(f.attrs["physics"])["neighbors"]
    assert (saved["min_neighbors"], saved["min_cell_capacity"]) == \
        (grown.min_neighbors, grown.min_cell_capacity)
    assert tight.n_steps == roomy.n_steps
    # ... and the redone chunks give the same answer as a list that never overflowed
    np.testing.assert_allclose(np.asarray(tight.state.fluid.x),
                               np.asarray(roomy.state.fluid.x), rtol=0, atol=1e-6)
    np.testing.assert_allclose(np.asarray(tight.state.fluid.rho),
                               np.asarray(roomy.state.fluid.rho), rtol=1e-5)


def test_chunks_that_regrow_after_the_first_are_timed_apart():
    """The squeezed block in chunks of 4 steps outgrows its list after the first chunk:
    that chunk's recompile and redo are counted and timed (the CLI's summary line says
    so, as they are not stepping), within the stepping time after the first chunk."""
    res = simulate(squeezed_block(), progress=False, capacity_multiplier=1.0,
                   chunk_steps=4, rho_tolerance=0.9, skin=0.1)
    assert res.reallocations >= 1 and res.regrowth_chunks == 1
    assert 0.0 < res.regrowth_s <= res.wall_s - res.compile_s


def test_the_progress_line_says_why_it_stops_when_a_list_grows(capsys):
    """The bar stands still while the step recompiles: its postfix says so, and the
    next chunk's update clears it."""
    simulate(squeezed_block(), progress=True, capacity_multiplier=1.0, chunk_steps=4,
             rho_tolerance=0.9, skin=0.1)
    lines = capsys.readouterr().err.replace("\r", "\n").splitlines()
    assert any("a neighbour list grew: recompiling" in ln for ln in lines)
    from fpsi_jax.run.driver import _Progress
    bar = _Progress("x", 12, 0)
    bar.advance(4, 0)
    bar.regrowing()
    assert "recompiling" in bar.bar.postfix
    bar.advance(4, 0)
    assert not bar.bar.postfix and bar.bar.n == 8
    bar.close()


def test_wall_rows_too_narrow_are_widened_and_redone(monkeypatch):
    """A boundary-row width of one slot (NeighborConfig.wall_width) overflows at the first
    allocation: the driver widens only it to what the rows hold before the first rates are
    computed. The run then equals, bit for bit, one allocated at that width from the start,
    and one at the width setup measures to float32 round-off (sums of another length: a
    corner boundary particle's extrapolated pressure differed by 2.8e-4 relative once)."""
    def sc():
        return cases.build("hydrostatic_tank", dx=0.01, depth=0.1, width=0.1, t_end=0.01)

    def width(w):
        return lambda scene, phys: dataclasses.replace(phys, neighbors=dataclasses.replace(
            phys.neighbors, wall_width=w))
    wide = simulate(sc(), progress=False, chunk_steps=20)
    monkeypatch.setattr(init, "fit_wall_width", width(1))
    tight = simulate(sc(), progress=False, chunk_steps=20)
    assert wide.reallocations == tight.reallocations == 0
    assert tight.physics.neighbors.wall_width > 1
    assert tight.physics.neighbors.min_neighbors == wide.physics.neighbors.min_neighbors
    assert neighbors.capacity(tight.state.nbrs) == neighbors.capacity(wide.state.nbrs)
    assert tight.n_steps == wide.n_steps
    monkeypatch.setattr(init, "fit_wall_width", width(tight.physics.neighbors.wall_width))
    same = simulate(sc(), progress=False, chunk_steps=20)
    for leaf in ("x", "v", "rho"):
        np.testing.assert_array_equal(np.asarray(getattr(tight.state.fluid, leaf)),
                                      np.asarray(getattr(same.state.fluid, leaf)))
    np.testing.assert_array_equal(np.asarray(tight.state.boundary.p),
                                  np.asarray(same.state.boundary.p))
    np.testing.assert_allclose(np.asarray(tight.state.fluid.x), np.asarray(wide.state.fluid.x),
                               rtol=0, atol=1e-6)
    np.testing.assert_allclose(np.asarray(tight.state.fluid.rho),
                               np.asarray(wide.state.fluid.rho), rtol=1e-5)


def test_particle_leaving_the_domain_is_a_clear_error(tmp_path):
    sc = cases.build("hydrostatic_tank", dx=0.02, depth=0.1, width=0.1, t_end=0.05)
    top = int(np.argmax(sc.fluid.x[:, 1] + 1e-3 * sc.fluid.x[:, 0]))
    sc.fluid.v = np.zeros_like(sc.fluid.x)
    sc.fluid.v[top] = (0.0, 20.0)          # shoots out of the top of the domain
    sc.open_sides = ()                     # closed: leaving is an error (open: tests/solver/test_exits.py)
    with pytest.raises(SimulationError,
                       match=f"fluid particle {top}: particle left the domain"):
        simulate(sc, progress=False, output=str(tmp_path / "out.h5"), rho_tolerance=0.9)


# --- compiled chunks ---------------------------------------------------------------------
def test_last_short_chunk_reuses_the_compiled_chunk_and_equals_a_rollout(tiny_tank):
    """The driver's chunks run through forward.advance with a traced step count: a tail
    shorter than a chunk takes the same program (one compile) and the same steps as a plain
    scan rollout, observations included."""
    phys, params = setup(tiny_tank)
    p = params.as_arrays(jnp.float32)
    st = init.init_state(tiny_tank, phys, p)
    obs = lambda s: jnp.max(s.fluid.x[:, 1])
    n_before = _advance._cache_size()
    full, o_full = _advance(phys, st, p, jnp.int32(7), 7, obs)
    tail, o_tail = _advance(phys, st, p, jnp.int32(4), 7, obs)
    assert _advance._cache_size() == n_before + 1
    ref, o_ref = jax.jit(forward.rollout, static_argnums=(0, 3, 4))(phys, st, p, 4, obs)
    np.testing.assert_array_equal(np.asarray(tail.fluid.x), np.asarray(ref.fluid.x))
    assert int(tail.step) == 4 and int(full.step) == 7
    np.testing.assert_array_equal(np.asarray(o_tail)[:4], np.asarray(o_ref))
    np.testing.assert_array_equal(np.asarray(o_tail)[4:], 0.0)
    np.testing.assert_array_equal(np.asarray(o_full)[:4], np.asarray(o_ref))


def test_setup_derives_the_same_step_whatever_precision_ran_before():
    """JAX's x64 flag is process-wide and a float64 run leaves it on: setup sets it to the
    run's precision before deriving the step, so a float32 scene gets the same Δt either
    way (it differed by 3e-9 relative, and the stale-list test below then pushed its grain
    through a wall in one worker of the suite and not in another)."""
    from ..small_scenes import grain_scene
    sc = grain_scene(x64=False)
    dts = []
    for before in (False, True):
        jax.config.update("jax_enable_x64", before)
        dts.append(float(setup(sc)[1].dt))
        assert not jax.config.jax_enable_x64
    assert dts[0] == dts[1]


def test_check_rollout_says_what_simulate_would_have_refused(tiny_tank):
    """A rollout checks nothing: check_rollout passes a good one, names the step and
    particle of one run at 30 times the stable step, and refuses one whose list overflowed."""
    phys, params = setup(tiny_tank)
    p = params.as_arrays(jnp.float32)
    st = init.init_state(tiny_tank, phys, p)
    run = jax.jit(forward.rollout, static_argnums=(0, 3))
    good, _ = run(phys, st, p, 20)
    driver.check_rollout(good, p)
    fast = p.replace(dt=30.0 * p.dt)
    bad, _ = run(phys, st, fast, 200)
    assert bool(bad.status.bad)
    with pytest.raises(SimulationError) as e:
        driver.check_rollout(bad, fast)
    assert e.value.step == int(bad.status.step) and e.value.step <= 200
    cut = good.replace(status=good.status.replace(overflow=jnp.asarray(True),
                                                  redo_step=jnp.asarray(12, jnp.int32)))
    with pytest.raises(RuntimeError, match="overflowed at step 12.*simulate.*physics"):
        driver.check_rollout(cut, p)
    with pytest.raises(ParameterError, match=r"n_steps = 2.5 is not an integer"):
        forward.rollout(phys, st, p, 2.5)


def test_setup_refuses_an_array_where_a_parameter_is_one_number(tiny_tank):
    p = tiny_tank.params
    bad = p.replace(sph=p.sph.replace(mu=np.full(5, 1e-3)))
    with pytest.raises(ParameterError, match=r"sph.mu has shape \(5,\); allowed one number"):
        setup(tiny_tank, params=bad)


def test_the_chunk_compiled_beside_the_set_up_is_the_one_the_run_uses(tiny_tank):
    """simulate compiles its chunk in a second thread while the first rates are evaluated
    (driver.first_state ``beside``): the program compiled there is the one the chunks then
    call, so a fresh run adds one compiled chunk, not two, and the result is the same as
    stepping the set-up's state with that program."""
    n0 = _advance._cache_size()
    res = simulate(tiny_tank, t_end=0.0077, every=0.0077 / 3, progress=False)
    assert _advance._cache_size() == n0 + 1
    phys, params = setup(tiny_tank)
    p = params.as_arrays(stages.dtype(phys))
    phys, st = driver.first_state(tiny_tank, phys, p)
    chunk, done = max(1, round(0.0077 / 3 / float(params.dt))), 0
    while done < res.n_steps:
        n = min(chunk, res.n_steps - done)
        st, _ = _advance(phys, st, p, jnp.int32(n), chunk, None)
        done += n
    np.testing.assert_array_equal(np.asarray(res.state.fluid.x), np.asarray(st.fluid.x))


def test_work_beside_the_set_up_that_fails_is_dropped():
    """What the helper thread raises never reaches the run (the main thread redoes it)."""
    def fail(*_):
        raise RuntimeError("boom")
    with driver._running_beside(fail, 1):
        pass
    with driver._running_beside(None):
        pass


def test_a_second_run_of_the_same_scene_compiles_nothing(tiny_tank):
    """Fresh neighbour lists of the same capacity are the same pytree to jax.jit: a second
    simulate (a sweep, a calibration, validate) reuses the compiled chunk and set-up."""
    simulate(tiny_tank, t_end=0.004, every=0.002, progress=False)
    n_adv, n_init = _advance._cache_size(), init.initial_rates._cache_size()
    res = simulate(tiny_tank, t_end=0.004, every=0.002, progress=False)
    assert res.n_steps > 0
    assert _advance._cache_size() == n_adv
    assert init.initial_rates._cache_size() == n_init


def test_setup_sets_jax_x64_to_the_runs_precision_both_ways():
    """JAX's x64 flag is process-wide: a float32 run set up after a float64 one must not be
    traced with it on (weakly typed constants would promote parts of its step to float64,
    and fpsi validate, which runs every case in one process, gave other figures for the
    cases after the first float64 one)."""
    prev = jax.config.jax_enable_x64
    try:
        sc = cases.build("dry_dam_break")
        setup(sc, x64=True)
        assert jax.config.jax_enable_x64
        phys, p = setup(sc)
        assert not phys.x64
        assert not jax.config.jax_enable_x64
        res = simulate(sc, t_end=20 * float(p.dt), progress=False)
        assert res.state.solid.x.dtype == jnp.float32
        assert jnp.asarray(1.0).dtype == jnp.float32
    finally:
        jax.config.update("jax_enable_x64", prev)


def test_an_h_past_the_cut_off_grows_the_reach_to_the_h_reached_and_the_wall_rows_with_it():
    """grow after h outgrew the cut-off: the cut-off (and h_margin) by at least 1.25, or
    to 1.1 × the kernel support of the largest h the chunk reached (water running into a
    bed's pores grows its h in steps; at most 3×, whatever h a blown-up chunk ends with),
    and the wall rows' width, set once at set-up, by the square of that factor (a wider
    reach with the width as it was overflows the wall rows at every redo)."""
    phys, params = setup(cases.build("dam_break", dx=0.02))
    st = init.init_state(cases.build("dam_break", dx=0.02), phys,
                         params.as_arrays(stages.dtype(phys)))
    nb = phys.neighbors
    assert nb.wall_width > 0
    for h_reached, factor in ((0.5 * nb.r_cut, 1.25), (1.0 * nb.r_cut, 2.2),
                              (np.inf, 1.25), (100.0 * nb.r_cut, 3.0)):
        f = st.fluid
        failed = st.replace(fluid=f.replace(h=f.h.at[0].set(h_reached)),
                            status=st.status.replace(h_exceeded=jnp.asarray(True)))
        grown = driver.grow(phys, failed)
        got = grown.neighbors.r_cut / nb.r_cut
        assert got == pytest.approx(factor, rel=1e-6)
        assert grown.h_margin == pytest.approx(phys.h_margin * factor, rel=1e-6)
        assert grown.neighbors.wall_width == int(np.ceil(nb.wall_width * got ** 2 - 1e-9))
