"""Host driver: unstable runs stop with a diagnosis and leave a valid, finite file."""
import h5py
import jax
import numpy as np
import pytest

from fpsi_jax import io, scenes
from fpsi_jax.simulate import SimulationError, simulate


def test_unstable_run_stops_with_diagnosis_and_keeps_good_frames(tmp_path):
    # c0 = 3 m/s is far below 10 v_max (24 m/s): the column compresses until the density leaves
    # the allowed band -- a deliberately unstable run.
    sc = scenes.build("dam_break", dx=0.02, c0=3.0, t_end=0.5)
    out = tmp_path / "bad.h5"
    with pytest.raises(SimulationError) as info:
        simulate(sc, output=str(out), every=0.02, progress=False)
    e = info.value
    msg = str(e)
    assert "step" in msg and "t =" in msg and "fluid particle" in msg
    assert e.step > 0 and e.particle >= 0 and e.quantity
    run = io.read(out)
    assert run.status == "unstable"
    assert run.frames >= 2                                 # the good frames are there
    assert run.time[-1] < e.time
    for k, a in run.fluid.items():
        assert np.all(np.isfinite(a)), k                   # and no NaN was written
    with h5py.File(out) as f:
        assert "unstable" in f.attrs["message"]


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
    from fpsi_jax import overrides
    from fpsi_jax.params import ParameterError
    from fpsi_jax.simulate import setup
    sc, ph = overrides.build("hydrostatic_tank", {"dt": 1e-5, "dx": 0.02})
    assert float(setup(sc, **ph)[1].dt) == pytest.approx(1e-5)
    assert float(setup(sc, 2e-5, **ph)[1].dt) == pytest.approx(2e-5)
    sc, ph = overrides.build("hydrostatic_tank", {"dt": 1.0, "dx": 0.02})
    with pytest.raises(ParameterError, match="exceeds the stability bound"):
        setup(sc, **ph)
    with pytest.raises(ParameterError, match="dt = -1"):
        overrides.build("hydrostatic_tank", {"dt": -1})


def test_last_short_chunk_reuses_the_compiled_chunk_and_equals_a_rollout(tiny_tank):
    """The driver's chunks run through integrate.advance with a traced step count: a tail
    shorter than a chunk takes the same program (one compile) and the same steps as a plain
    scan rollout, observations included."""
    import jax
    import jax.numpy as jnp

    from fpsi_jax import integrate
    from fpsi_jax.simulate import _advance, setup

    phys, params = setup(tiny_tank)
    p = params.as_arrays(jnp.float32)
    st = integrate.init_state(tiny_tank, phys, p)
    obs = lambda s: jnp.max(s.fluid.x[:, 1])
    n_before = _advance._cache_size()
    full, o_full = _advance(phys, st, p, jnp.int32(7), 7, obs)
    tail, o_tail = _advance(phys, st, p, jnp.int32(4), 7, obs)
    assert _advance._cache_size() == n_before + 1
    ref, o_ref = jax.jit(integrate.rollout, static_argnums=(0, 3, 4))(phys, st, p, 4, obs)
    np.testing.assert_array_equal(np.asarray(tail.fluid.x), np.asarray(ref.fluid.x))
    assert int(tail.step) == 4 and int(full.step) == 7
    np.testing.assert_array_equal(np.asarray(o_tail)[:4], np.asarray(o_ref))
    np.testing.assert_array_equal(np.asarray(o_tail)[4:], 0.0)
    np.testing.assert_array_equal(np.asarray(o_full)[:4], np.asarray(o_ref))


@pytest.mark.parametrize("bad_step, overflow, h_exceeded, redo_step, expected", [
    (-1, True, False, 5, True),     # a plain overflow: regrow and redo
    (3, False, True, 4, False),     # bad at 3, h outgrew the cut-off at 3 (inexact from 4)
    (3, True, False, 3, True),      # bad in the very step whose list overflowed: redo
    (6, True, False, 5, True),      # bad after the overflow: maybe its consequence, redo
    (3, False, False, -1, False),   # bad, nothing overflowed: diagnose
])
def test_a_run_bad_before_its_lists_overflowed_is_diagnosed_not_regrown(
        bad_step, overflow, h_exceeded, redo_step, expected):
    import jax.numpy as jnp

    from fpsi_jax.state import Status
    st = Status.ok().replace(bad=jnp.asarray(bad_step >= 0), step=jnp.int32(bad_step),
                             overflow=jnp.asarray(overflow),
                             h_exceeded=jnp.asarray(h_exceeded),
                             redo_step=jnp.int32(redo_step))
    assert st.must_redo() is expected


def test_redo_step_marks_the_first_inexact_step():
    """Overflow: that very step dropped pairs; h past the cut-off: the next one would."""
    import dataclasses

    import jax.numpy as jnp

    from fpsi_jax import integrate
    from fpsi_jax.simulate import setup
    sc = scenes.build("hydrostatic_tank", dx=0.02, depth=0.1, width=0.1)
    phys, params = setup(sc)
    p = params.as_arrays(jnp.float32)
    s0 = integrate.init_state(sc, phys, p)
    step = jax.jit(integrate.step, static_argnums=0)
    s1 = step(phys, s0, p)
    assert int(s1.status.redo_step) == -1
    # a cut-off that the initial h already exceeds: h_exceeded at step 1, inexact from 2
    tight = dataclasses.replace(phys, neighbors=dataclasses.replace(
        phys.neighbors, r_cut=float(sc.fluid.h.max())))
    s1 = step(tight, s0, p)
    assert bool(s1.status.h_exceeded) and int(s1.status.redo_step) == 2


def test_a_second_run_of_the_same_scene_compiles_nothing(tiny_tank):
    """Fresh neighbour lists of the same capacity are the same pytree to jax.jit: a second
    simulate (a sweep, a calibration, validate) reuses the compiled chunk and set-up."""
    from fpsi_jax import integrate
    from fpsi_jax.simulate import _advance
    simulate(tiny_tank, t_end=0.004, every=0.002, progress=False)
    n_adv, n_init = _advance._cache_size(), integrate._initial_rates._cache_size()
    res = simulate(tiny_tank, t_end=0.004, every=0.002, progress=False)
    assert res.n_steps > 0
    assert _advance._cache_size() == n_adv
    assert integrate._initial_rates._cache_size() == n_init
