"""The arm's working plane: the shoulder yaw that aims it at a point of the workspace. No ROS,
no planner: the mission checks its trench with it before the stack starts.
"""

from __future__ import annotations

import math

from ow_lander.errors import PlanningError

#: m, shoulder yaw axis in base_link (OceanWATERS X_SHOU, Y_SHOU).
SHOULDER_XY = (0.79, 0.175)
#: m, lateral offset of the arm's working plane from the shoulder axis (Y_SHOU - HAND_Y_OFFSET).
ARM_PLANE_OFFSET = 0.15


def shoulder_yaw_for(x: float, y: float, lower: float, upper: float) -> float:
    """rad, shoulder yaw aiming the arm's working plane at (x, y) (OceanWATERS alpha + beta).

    Raises:
        PlanningError: the point is inside the shoulder's offset circle or the yaw is outside
            [lower, upper].
    """
    dx, dy = x - SHOULDER_XY[0], y - SHOULDER_XY[1]
    h = math.hypot(dx, dy)
    if h <= ARM_PLANE_OFFSET:
        msg = (
            f"(x, y)=({x:.3f}, {y:.3f}) m is {h:.3f} m from the shoulder axis, closer than the "
            f"arm plane offset {ARM_PLANE_OFFSET} m"
        )
        raise PlanningError(msg)
    yaw = math.atan2(dy, dx) + math.asin(ARM_PLANE_OFFSET / h)
    if not lower <= yaw <= upper:
        msg = (
            f"(x, y)=({x:.3f}, {y:.3f}) m needs shoulder yaw {yaw:.3f} rad, outside the joint "
            f"limits [{lower:.2f}, {upper:.2f}] rad"
        )
        raise PlanningError(msg)
    return yaw
