"""The planner's objective: mechanical work against gravity along joint-space paths. No ROS.

The work is the energy the joint motors spend on a quasi-static motion under Europa's gravity:
the sum over joints of |tau_g(q) * dq| along the path. The objective adds
``path_length_weight`` times the joint-space path length. OMPL's
MechanicalWorkOptimizationObjective is not used: it ignores the robot's dynamics and reduces to
path length.

Paths are polylines of arm states ``(n, 6) rad`` in
:data:`~ow_description.description.ARM_JOINTS` order; the other joints keep the values of a base
configuration ``base: (9,)`` in pinocchio order (see :mod:`ow_description.model`).
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ow_description.model import LanderModel

FloatArray = npt.NDArray[np.float64]

#: rad, joint step of the work integral reported for plans (gravity torque at step midpoints).
WORK_STEP_RAD = 0.02
#: rad, coarser step of the same integral inside RRT*'s objective (called ~20 times an iteration).
OBJECTIVE_STEP_RAD = 0.25


class GravityWork:
    """Work against gravity and the planner's objective for one :class:`LanderModel` (not
    thread-safe, like the model).

    Args:
        model: dynamics model (gravity torques).
        path_length_weight: J/rad, weight of the joint-space path length in :meth:`cost`.
    """

    def __init__(self, model: LanderModel, path_length_weight: float) -> None:
        self.model = model
        self.path_length_weight = path_length_weight
        self.idx = model.arm_idx

    def work(self, waypoints: FloatArray, base: FloatArray, step: float = WORK_STEP_RAD) -> float:
        """J, mechanical work against gravity along the polyline (n, 6): the sum over joints and
        steps of |tau_g(q_mid) * dq|, steps of at most ``step`` rad."""
        total = 0.0
        points = np.asarray(waypoints, dtype=np.float64)
        for a, b in itertools.pairwise(points):
            total += self.work_between(a, b, base, step)
        return total

    def work_between(
        self, a: FloatArray, b: FloatArray, base: FloatArray, step: float = WORK_STEP_RAD
    ) -> float:
        """J, :meth:`work` of the straight joint motion ``a`` -> ``b`` ((6,) rad each)."""
        delta = b - a
        n = max(1, math.ceil(float(np.abs(delta).max()) / step))
        qs = np.empty((n, len(base)))
        qs[:] = base
        qs[:, self.idx] = a + (np.arange(n)[:, None] + 0.5) * (delta / n)
        model, data = self.model.model, self.model.data
        torque = np.empty_like(qs)
        for i, q in enumerate(qs):
            torque[i] = pin.computeGeneralizedGravity(model, data, q)
        # sum over steps and joints of |tau * delta / n| = sum over joints of
        # |delta / n| * (sum over steps of |tau|).
        return float(np.abs(torque[:, self.idx]).sum(axis=0) @ np.abs(delta / n))

    def cost(self, waypoints: FloatArray, base: FloatArray, step: float = WORK_STEP_RAD) -> float:
        """The objective of a polyline (n, 6): work (J) + weight * joint path length (rad)."""
        points = np.asarray(waypoints, dtype=np.float64)
        length = float(np.linalg.norm(np.diff(points, axis=0), axis=1).sum())
        return self.work(points, base, step) + self.path_length_weight * length
