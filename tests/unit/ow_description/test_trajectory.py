"""Time parameterisation, CSV round trip and the trajectory store (no ROS)."""

import numpy as np
import pytest

from ow_description.description import DEFAULT_GROUND_Z
from ow_description.errors import TrajectoryError
from ow_description.trajectory import (
    PathSegment,
    Speed,
    TrajectoryStore,
    read_csv,
    time_parameterize,
)
from ow_lander.execution.ground_detection import ForceDetector, GroundDetector

JOINTS = ("a", "b")
VMAX = np.array([0.2, 0.4])
AMAX = np.array([0.2, 0.2])


SCALES = {Speed.FREE: 1.0, Speed.DIG: 0.25, Speed.GUARDED: 0.5}


def _timed(segments, period=0.05, scales=None):
    return time_parameterize(segments, JOINTS, VMAX, AMAX, period, "test", scales)


@pytest.mark.parametrize(
    "waypoints",
    [
        [[0.0, 0.0], [1.0, 0.5]],
        [[0.0, 0.0], [0.01, 0.0]],
        [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]],
        [[0.0, 0.0], [0.3, 0.3], [0.6, 0.61], [0.9, 0.9]],
    ],
)
def test_limits_respected_and_waypoints_reached(waypoints):
    traj = _timed([PathSegment("s", np.array(waypoints))])
    assert np.allclose(traj.positions[0], waypoints[0])
    assert np.allclose(traj.positions[-1], waypoints[-1])
    assert np.all(np.abs(traj.velocities) <= VMAX * (1 + 1e-9))
    finite_difference = np.diff(traj.positions, axis=0) / np.diff(traj.times)[:, None]
    assert np.all(np.abs(finite_difference) <= VMAX * 1.001)
    assert np.all(np.diff(traj.times) > 0)
    assert np.allclose(traj.velocities[-1], 0.0)


def test_a_segment_moves_at_the_scale_of_its_speed_class():
    path = np.array([[0.0, 0.0], [1.0, 0.0]])
    fast = _timed([PathSegment("s", path)], scales=SCALES)
    slow = _timed([PathSegment("s", path, Speed.DIG)], scales=SCALES)
    assert slow.duration > 2 * fast.duration
    assert np.max(np.abs(fast.velocities[:, 0])) == pytest.approx(VMAX[0])
    assert np.max(np.abs(slow.velocities[:, 0])) == pytest.approx(0.25 * VMAX[0])
    # Without scales every class moves at the full limits.
    assert _timed([PathSegment("s", path, Speed.DIG)]).duration == pytest.approx(fast.duration)


def test_corner_stops_the_arm():
    traj = _timed([PathSegment("s", np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]]))])
    corner = np.argmin(np.linalg.norm(traj.positions - [1.0, 0.0], axis=1))
    assert np.allclose(traj.velocities[corner], 0.0, atol=1e-9)


def test_csv_round_trip_and_sampling(tmp_path):
    traj = _timed(
        [
            PathSegment("approach", np.array([[0.0, 0.0], [0.5, 0.2]])),
            PathSegment("cut", np.array([[0.5, 0.2], [0.5, 0.6]])),
        ]
    )
    store = TrajectoryStore(tmp_path)
    path = store.save(traj)
    back = read_csv(path)
    assert back.joints == JOINTS and back.operation == "test"
    assert np.allclose(back.positions, traj.positions, atol=1e-6)
    assert back.segments == traj.segments
    # Half-way between two rows: the cubic Hermite's midpoint of their positions and velocities.
    t = 0.5 * (back.times[3] + back.times[4])
    h = back.times[4] - back.times[3]
    midpoint = 0.5 * (back.positions[3] + back.positions[4])
    assert np.allclose(back.sample(t), midpoint + h / 8 * (back.velocities[3] - back.velocities[4]))
    assert back.segment_span("cut")[1] == pytest.approx(back.duration)


def test_store_deletes_only_its_own_files(tmp_path):
    store = TrajectoryStore(tmp_path)
    mine = store.save(_timed([PathSegment("s", np.array([[0.0, 0.0], [0.1, 0.1]]))]))
    theirs = tmp_path / "notes.csv"
    theirs.write_text("keep")
    assert store.latest() == mine
    assert store.delete_written() == 1
    assert theirs.exists() and not mine.exists()
    with pytest.raises(TrajectoryError, match="no trajectory written"):
        store.latest()


@pytest.mark.parametrize(
    ("name", "message"),
    [
        ("", "no trajectory file name"),
        ("missing.csv", "unknown trajectory file"),
        ("../escape.csv", "not in the trajectory directory"),
        ("/etc/passwd", "not in"),
    ],
)
def test_store_resolve_refuses(tmp_path, name, message):
    with pytest.raises(TrajectoryError, match=message):
        TrajectoryStore(tmp_path / "t").resolve(name)


def test_malformed_csv_is_rejected(tmp_path):
    path = tmp_path / "bad.csv"
    path.write_text("time,segment,a,v_a\n0,s,1\n")
    with pytest.raises(TrajectoryError, match="columns"):
        read_csv(path)


def test_ground_detector_fires_when_descent_stops():
    detector = GroundDetector()
    z, t = 0.3, 0.0
    for _ in range(20):
        t += 0.1
        z -= 0.005
        assert not detector.update(t, np.array([2.0, 0.0, z]))
    for _ in range(10):
        t += 0.1
        if detector.update(t, np.array([2.0, 0.0, z])):
            break
    assert detector.contact is not None
    assert detector.contact[2] == pytest.approx(z)


def test_steady_span_is_the_cruise_between_the_ramps():
    trajectory = _timed(
        [
            PathSegment("approach", np.array([[0.0, 0.0], [0.1, 0.0]])),
            PathSegment("guarded", np.array([[0.1, 0.0], [0.5, 0.0]]), Speed.GUARDED),
        ],
        scales=SCALES,
    )
    first, last = trajectory.segment_span("guarded")
    steady, braking = trajectory.steady_span("guarded")
    rows = (trajectory.times >= first) & (trajectory.times <= last)
    peak = trajectory.velocities[rows, 0].max()
    assert peak == pytest.approx(0.1)  # half the velocity limit
    i = int(np.searchsorted(trajectory.times, steady))
    # The first row at the cruise speed, after a ramp from rest; the last before braking.
    assert first < steady < last
    assert trajectory.velocities[i, 0] == pytest.approx(peak, rel=0.02)
    assert trajectory.velocities[i - 1, 0] < trajectory.velocities[i, 0] - 0.002
    j = int(np.searchsorted(trajectory.times, braking))
    assert steady < braking < last
    assert trajectory.velocities[j, 0] == pytest.approx(peak, rel=0.02)
    assert trajectory.velocities[j + 1, 0] < trajectory.velocities[j, 0] - 0.002
    # A settle pause before the descent is not part of it.
    paused = trajectory.with_pause(first, 2.0)
    assert paused.steady_span("guarded")[0] == pytest.approx(steady + 2.0)
    assert trajectory.steady_span("cut") is None


def _descent(detector, speeds, dt=1 / 30):
    """Feed a tip descending at each speed (m/s, positive down) in turn; the contact z or None."""
    z, t = 0.0, 0.0
    for v in speeds:
        t += dt
        z -= v * dt
        if detector.update(t, np.array([1.7, 0.0, z])):
            return detector.contact[2]
    return None


def test_a_threshold_from_the_steady_descent_sees_ground_that_gives():
    # Ground that yields slows a 2.6 cm/s descent to 1 cm/s: found when the window is steady...
    steady = [0.026] * 30 + [0.010] * 30
    assert _descent(GroundDetector(), steady) is not None
    # ...but a threshold taken on the acceleration ramp sits near zero velocity and misses it
    # (why the node arms the detector on Trajectory.steady_span).
    ramp = [0.026 * k / 8 for k in range(1, 8)]
    assert _descent(GroundDetector(), ramp + steady) is None


def test_force_detector_fires_on_a_rise_over_the_tare():
    detector = ForceDetector(threshold=10.0)
    tare = np.array([0.5, -0.2, 1.0])  # what the sensor read when the descent became steady
    for k in range(10):
        assert not detector.update(
            tare + np.array([0.0, 0.0, 0.9 * k]), np.array([1.7, 0.0, -0.1 - k])
        )
    ground = np.array([1.7, 0.0, DEFAULT_GROUND_Z])
    assert detector.update(tare + np.array([0.0, 0.0, 10.0]), ground)
    assert detector.contact[2] == pytest.approx(DEFAULT_GROUND_Z)
    # Once found it stays found, whatever follows.
    assert detector.update(tare, np.array([0.0, 0.0, 0.0]))
    assert detector.contact[2] == pytest.approx(DEFAULT_GROUND_Z)
