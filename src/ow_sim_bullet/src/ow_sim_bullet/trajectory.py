"""Joint trajectories the simulation interpolates itself (the paper's future trajectory controller).

A trajectory names some joints and gives way points at times from its start. Between way points
the set-point is a cubic Hermite spline when every point has velocities, else linear: the
interpolation of :class:`ow_description.trajectory.Spline`, the same the arm services check their
tracking against. Before the first way point the set-point moves linearly from where it was when
the trajectory started; after the last one it holds the last point.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ow_description.trajectory import Spline, Trajectory
from ow_sim_bullet.errors import CommandError

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class JointTrajectory:
    """A validated trajectory.

    Attributes:
        joints: joint names, unique.
        start_time: s of sim time at which time_from_start is 0.
        times: (n,) s from start, strictly increasing, >= 0.
        positions: (n, k) rad.
        velocities: (n, k) rad/s, or None for linear interpolation.
    """

    joints: tuple[str, ...]
    start_time: float
    times: FloatArray
    positions: FloatArray
    velocities: FloatArray | None

    @classmethod
    def from_plan(
        cls, plan: Trajectory, start_time: float, known_joints: Sequence[str]
    ) -> JointTrajectory:
        """A timed plan (the arm services' trajectory, :meth:`OperationPlan.timed`) started at
        ``start_time`` s of sim time: what publishing it on ``/sim/joint_trajectory`` gives,
        for a caller that drives the simulation in process.

        Raises:
            CommandError: as :meth:`build`.
        """
        return cls.build(
            plan.joints,
            start_time,
            plan.times.tolist(),
            plan.positions.tolist(),
            plan.velocities.tolist(),
            known_joints,
        )

    @classmethod
    def build(
        cls,
        joints: Sequence[str],
        start_time: float,
        times: Sequence[float],
        positions: Sequence[Sequence[float]],
        velocities: Sequence[Sequence[float]] | None,
        known_joints: Sequence[str],
    ) -> JointTrajectory:
        """Validate and build a trajectory.

        Args:
            joints: joint names of the columns.
            start_time: s of sim time of time_from_start 0.
            times: s from start of each point.
            positions: rad, one row per point, one column per joint.
            velocities: rad/s, same shape as positions, or None (no velocities on any point).
            known_joints: the joints the simulation has.

        Raises:
            CommandError: unknown or repeated joint, no points, ragged rows, non-finite values
                or times that are negative or not increasing.
        """
        joints = tuple(joints)
        unknown = [j for j in joints if j not in known_joints]
        if unknown:
            msg = f"trajectory names unknown joint(s) {unknown}; joints: {list(known_joints)}"
            raise CommandError(msg)
        if len(set(joints)) != len(joints) or not joints:
            msg = f"trajectory joint names must be unique and non-empty, got {list(joints)}"
            raise CommandError(msg)
        if not math.isfinite(start_time):
            msg = f"trajectory start time {start_time} s is not finite"
            raise CommandError(msg)
        if not times:
            msg = "trajectory has no points"
            raise CommandError(msg)
        t = np.asarray(times, dtype=np.float64)
        q = _matrix(positions, len(t), len(joints), "positions")
        v = None if velocities is None else _matrix(velocities, len(t), len(joints), "velocities")
        if not np.all(np.isfinite(t)) or t[0] < 0 or np.any(np.diff(t) <= 0):
            msg = (
                f"trajectory times from start must be finite, >= 0 and increasing, got {t.tolist()}"
            )
            raise CommandError(msg)
        return cls(joints, float(start_time), t, q, v)

    @property
    def end_time(self) -> float:
        """s of sim time of the last point."""
        return self.start_time + float(self.times[-1])


def _matrix(rows: Sequence[Sequence[float]], n: int, k: int, what: str) -> FloatArray:
    if len(rows) != n or any(len(row) != k for row in rows):
        msg = f"trajectory {what} must have {n} points of {k} values each"
        raise CommandError(msg)
    array = np.asarray(rows, dtype=np.float64).reshape(n, k)
    if not np.all(np.isfinite(array)):
        point = int(np.argwhere(~np.isfinite(array))[0][0])
        msg = f"trajectory {what} of point {point} are not finite: {array[point].tolist()}"
        raise CommandError(msg)
    return array


class ActiveTrajectory:
    """A trajectory being followed, starting from the set-points held when it was accepted.

    Args:
        trajectory: the trajectory.
        start_positions: (k,) rad, set-points of its joints when it was accepted.
        accept_time: s of sim time when it was accepted.
    """

    def __init__(
        self, trajectory: JointTrajectory, start_positions: FloatArray, accept_time: float
    ) -> None:
        self.trajectory = trajectory
        t0 = max(trajectory.start_time, accept_time)
        # Way points before the accept time are kept; the ramp only runs when the first point is
        # still ahead of the accept time.
        times = np.concatenate(([t0 - trajectory.start_time], trajectory.times))
        positions = np.vstack((start_positions, trajectory.positions))
        velocities = (
            None
            if trajectory.velocities is None
            else np.vstack((np.zeros_like(start_positions), trajectory.velocities))
        )
        if trajectory.times[0] <= times[0]:
            times, positions = times[1:], positions[1:]
            if velocities is not None:
                velocities = velocities[1:]
        self._spline = Spline(times, positions, velocities)
        self._start_time = trajectory.start_time
        self._end_time = trajectory.end_time

    def sample(self, now: float) -> tuple[FloatArray, FloatArray]:
        """Set-point positions (k,) rad and velocities (k,) rad/s at sim time ``now`` (s)."""
        return self._spline.sample(now - self._start_time)

    def finished(self, now: float) -> bool:
        """True once sim time ``now`` (s) is past the last point."""
        return now >= self._end_time
