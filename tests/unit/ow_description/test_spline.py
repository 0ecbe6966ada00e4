"""The one trajectory interpolation: the cubic Hermite spline the simulation follows and the arm
services check tracking against (no ROS)."""

import numpy as np
import pytest

from ow_description.trajectory import PathSegment, Spline, Trajectory, time_parameterize
from ow_sim_bullet.trajectory import ActiveTrajectory, JointTrajectory

JOINTS = ("a", "b", "c")


def _random_rows(seed: int, n: int = 12):
    rng = np.random.default_rng(seed)
    times = np.concatenate([[0.0], np.cumsum(rng.uniform(0.05, 0.5, n - 1))])
    return times, rng.normal(size=(n, len(JOINTS))), rng.normal(size=(n, len(JOINTS)))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_hermite_hits_every_row_with_its_velocity(seed):
    times, positions, velocities = _random_rows(seed)
    spline = Spline(times, positions, velocities)
    for i in range(1, len(times) - 1):
        position, velocity = spline.sample(float(times[i]))
        assert np.array_equal(position, positions[i])
        assert np.allclose(velocity, velocities[i], rtol=1e-12, atol=1e-12)
        # Continuous: arriving from the previous row gives the same position and velocity.
        before, slope = spline.sample(float(times[i]) - 1e-9)
        assert np.allclose(before, positions[i], atol=1e-7)
        assert np.allclose(slope, velocities[i], atol=1e-6)
    # Held outside the rows, at rest.
    for t, row in ((-1.0, 0), (0.0, 0), (times[-1], -1), (times[-1] + 1.0, -1)):
        position, velocity = spline.sample(float(t))
        assert np.array_equal(position, positions[row])
        assert np.array_equal(velocity, np.zeros(len(JOINTS)))


def test_without_velocities_the_spline_is_linear():
    spline = Spline(np.array([0.0, 2.0]), np.array([[0.0, 1.0], [2.0, 3.0]]), None)
    position, velocity = spline.sample(0.5)
    assert np.allclose(position, [0.5, 1.5]) and np.allclose(velocity, [1.0, 1.0])


def test_hermite_between_rows_follows_the_velocities():
    spline = Spline(np.array([0.0, 2.0]), np.array([[0.0], [2.0]]), np.array([[0.0], [0.0]]))
    # Rest to rest: slower than the straight line at first, then faster, the same at mid-time.
    assert spline.sample(0.5)[0][0] < 0.5
    assert spline.sample(1.0)[0][0] == pytest.approx(1.0)
    assert spline.sample(1.0)[1][0] == pytest.approx(1.5)


def _plan_trajectory():
    segments = [
        PathSegment("approach", np.array([[0.0, 0.0, 0.0], [0.4, -0.2, 0.1]])),
        PathSegment("cut", np.array([[0.4, -0.2, 0.1], [0.5, 0.3, 0.1], [0.9, 0.3, -0.2]])),
    ]
    return time_parameterize(segments, JOINTS, np.full(3, 0.3), np.full(3, 0.2), 0.1, "test")


@pytest.mark.parametrize("start_time", [0.0, 123.456])
def test_trajectory_sample_is_what_the_simulation_follows(start_time):
    trajectory: Trajectory = _plan_trajectory()
    sim = JointTrajectory.build(
        JOINTS,
        start_time,
        trajectory.times.tolist(),
        trajectory.positions.tolist(),
        trajectory.velocities.tolist(),
        JOINTS,
    )
    active = ActiveTrajectory(sim, trajectory.positions[0], accept_time=start_time)
    rng = np.random.default_rng(5)
    for t in rng.uniform(-1.0, trajectory.duration + 1.0, 500):
        followed = active.sample(start_time + float(t))[0]
        if start_time == 0.0:
            assert np.array_equal(trajectory.sample(float(t)), followed)
        else:  # start + t - start rounds t
            assert np.allclose(trajectory.sample(float(t)), followed, atol=1e-12)


def _hermite(times, positions, velocities, t):
    """The cubic Hermite formula as written in every textbook, term by term, in numpy."""
    i = int(np.searchsorted(times, t, side="right")) - 1
    h = float(times[i + 1] - times[i])
    s = (t - float(times[i])) / h
    p0, p1 = positions[i], positions[i + 1]
    v0, v1 = velocities[i] * h, velocities[i + 1] * h
    position = (
        (2 * s**3 - 3 * s**2 + 1) * p0
        + (s**3 - 2 * s**2 + s) * v0
        + (-2 * s**3 + 3 * s**2) * p1
        + (s**3 - s**2) * v1
    )
    velocity = (
        (6 * s**2 - 6 * s) * p0
        + (3 * s**2 - 4 * s + 1) * v0
        + (-6 * s**2 + 6 * s) * p1
        + (3 * s**2 - 2 * s) * v1
    ) / h
    return position, velocity


@pytest.mark.parametrize("seed", [3, 4])
def test_hermite_is_the_formula_bit_for_bit_in_any_order_of_samples(seed):
    """Samples that go forward, back and jump between intervals give the formula's very
    doubles: a faster evaluation must not change a run by one bit."""
    times, positions, velocities = _random_rows(seed, n=30)
    spline = Spline(times, positions, velocities)
    rng = np.random.default_rng(seed)
    inside = rng.uniform(times[0] + 1e-9, times[-1] - 1e-9, 3000)
    for t in np.concatenate((np.sort(inside), inside)):
        position, velocity = spline.sample(float(t))
        expected_position, expected_velocity = _hermite(times, positions, velocities, float(t))
        assert np.array_equal(position, expected_position)
        assert np.array_equal(velocity, expected_velocity)
