"""The one trajectory interpolation: the cubic Hermite spline the simulation follows and the arm
services check tracking against (no ROS)."""

import numpy as np
import pytest

from ow_lander.trajectory import PathSegment, Spline, Trajectory, time_parameterize
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
