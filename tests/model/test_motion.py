"""Prescribed motions of kinematic groups (model/motion.py): the velocity the sub-steps
move a group at, against hand values and the derivative of the prescribed displacement."""
import math

import numpy as np
import pytest

from fpsi_jax.model import motion

INF = float("inf")


def v_at(m, t):
    return np.asarray(motion.velocity(m, t), float)


def test_a_window_moves_only_between_its_start_and_stop():
    m = motion.Window(0, 3, 0.5, -0.2, 0.1, 0.3)
    assert np.all(v_at(m, 0.05) == 0.0) and np.all(v_at(m, 0.3) == 0.0)
    assert v_at(m, 0.1) == pytest.approx([0.5, -0.2])
    assert v_at(m, 0.2999) == pytest.approx([0.5, -0.2])
    assert motion.displacement(m, 1.0) == pytest.approx([0.1, -0.04])


def test_an_oscillation_has_the_derivative_of_its_stroke():
    """X = r(τ) A (sin(ωτ + φ) − sin φ): V equals central differences of X through the
    ramp and after it; at full stroke V = A ω cos(ωτ + φ) (hand value); X(t_on) = 0."""
    m = motion.Oscillation(0, 2, 0.02, 0.01, 0.8, 0.4, 0.5, 0.1, INF)
    assert motion.displacement(m, 0.1) == pytest.approx([0.0, 0.0], abs=1e-15)
    h = 1e-6
    for t in (0.15, 0.35, 0.59, 0.75, 1.3):
        fd = (motion.displacement(m, t + h) - motion.displacement(m, t - h)) / (2 * h)
        assert v_at(m, t) == pytest.approx(fd, rel=1e-4, abs=1e-7)
    w = 2 * math.pi / 0.8
    assert v_at(m, 1.3) == pytest.approx(np.array([0.02, 0.01]) * w * math.cos(w * 1.2 + 0.4),
                                         rel=1e-5)
    assert np.all(v_at(m, 0.05) == 0.0)          # before its start


def test_a_ramped_oscillation_starts_from_rest():
    m = motion.Oscillation(0, 1, 0.05, 0.0, 1.0, 0.0, 2.0, 0.0, INF)
    assert v_at(m, 0.0) == pytest.approx([0.0, 0.0], abs=1e-12)
    assert motion.displacement(m, 1.0) == pytest.approx([0.0, 0.0], abs=1e-12)  # sin 2π


def test_a_track_moves_at_the_slope_of_each_segment_and_stands_outside():
    m = motion.Track(0, 4, (0.2, 0.4, 1.0), (0.0, 0.01, 0.01), (0.0, 0.0, -0.03))
    assert np.all(v_at(m, 0.1) == 0.0) and np.all(v_at(m, 1.0) == 0.0)
    assert v_at(m, 0.3) == pytest.approx([0.05, 0.0])
    assert v_at(m, 0.7) == pytest.approx([0.0, -0.05])
    assert motion.displacement(m, 2.0) == pytest.approx([0.01, -0.03])


def test_canonical_reads_json_lists_by_length_and_refuses_the_rest():
    fixed = np.ones(5, bool)
    assert isinstance(motion.canonical([0, 2, 1.0, 0.0, 0.0, INF], 5, fixed), motion.Window)
    assert isinstance(motion.canonical([0, 2, 0.1, 0, 1, 0, 0, 0, INF], 5, fixed),
                      motion.Oscillation)
    assert isinstance(motion.canonical([0, 2, [0, 1], [0, 1], [0, 0]], 5, fixed), motion.Track)
    for bad in ([0, 2, 1.0], [0, 6, 1.0, 0.0, 0.0, INF], [0, 2, [0, 1], [0], [0, 0]],
                [0, 2, 0.1, 0, -1, 0, 0, 0, INF], "gate"):
        with pytest.raises(Exception, match="kinematic_motion entry"):
            motion.canonical(bad, 5, fixed)


@pytest.mark.parametrize("m", [
    motion.Window(0, 1, 0.5, -0.2, 0.1, 0.3),
    motion.Oscillation(0, 1, 0.02, 0.01, 0.08, 0.4, 0.05, 0.1, 0.5),
    motion.Track(0, 1, (0.2, 0.21, 0.4, 0.41), (0.0, 0.01, 0.01, 0.0), (0.0, 0.0, -0.03, 0.0)),
])
def test_the_mean_velocity_of_a_sub_step_moves_the_group_exactly_along_its_path(m):
    """(X(t0 + Δt) − X(t0))/Δt for sub-steps across every start, stop, ramp end and
    corner (two corners inside one sub-step for the track), float64."""
    import jax
    with jax.enable_x64(True):
        for t0 in np.linspace(0.0, 0.6, 37):
            for dt in (0.003, 0.017):
                want = (motion.displacement(m, t0 + dt) - motion.displacement(m, t0)) / dt
                got = np.asarray(motion.mean_velocity(m, t0, dt, np.float64))
                assert got == pytest.approx(want, rel=1e-9, abs=1e-12)


def test_the_mean_velocity_keeps_small_sub_steps_at_late_float32_times():
    """At t = 100 s float32 resolves 7.6 µs: a 10 µs sub-step inside a window still
    moves at exactly its velocity, and a stroke's mean is its velocity to 1e-4."""
    w = motion.Window(0, 1, 0.5, 0.0, 1.0, 1e3)
    assert np.asarray(motion.mean_velocity(w, 100.0, 1e-5))[0] == np.float32(0.5)
    o = motion.Oscillation(0, 1, 0.05, 0.0, 2.0, 0.0, 1.0, 0.0, INF)
    got = float(np.asarray(motion.mean_velocity(o, 100.25, 1e-5))[0])
    assert got == pytest.approx(float(v_at(o, 100.25 + 5e-6)[0]), rel=1e-4)


@pytest.mark.parametrize("m", [
    motion.Oscillation(0, 1, 0.02, 0.01, 0.8, 0.4, 0.5, 0.1, INF),
    motion.Track(0, 1, tuple(np.linspace(0.2, 1.0, 81)),
                 tuple(0.01 * np.sin(np.linspace(0.2, 1.0, 81) * 6.0)),
                 tuple(np.zeros(81))),
])
def test_the_acceleration_is_the_second_derivative_of_the_stroke(m):
    """What the moving wall's extrapolated pressure takes (g − a_w): an oscillation's
    d²X/dt² through its ramp (central differences of V), a smooth track's to the
    track's own resolution (a sampled sine: −36 X within 2 %)."""
    import jax
    with jax.enable_x64(True):
        h = 1e-6
        for t in (0.25, 0.45, 0.62, 0.9):
            a = np.asarray(motion.acceleration(m, t, np.float64))
            if isinstance(m, motion.Oscillation):
                fd = (np.asarray(motion.velocity(m, t + h, np.float64))
                      - np.asarray(motion.velocity(m, t - h, np.float64))) / (2 * h)
                assert a == pytest.approx(fd, rel=1e-4, abs=1e-8)
            else:
                assert a[0] == pytest.approx(-36 * 0.01 * np.sin(6 * t), rel=0.02, abs=1e-4)
        assert np.all(np.asarray(motion.acceleration(motion.Window(0, 1, 1.0, 0, 0, 1), 0.5))
                      == 0.0)
