"""Where the arm's operations put the tools on the ground: the shoulder yaw that aims the arm's
working plane at a point, and the spacing of the grind's passes. No ROS, no planner (pinocchio,
OMPL): the mission's steps and its report read them, in processes that plan nothing.
"""

from __future__ import annotations

import math

from ow_lander.errors import PlanningError

#: m, shoulder yaw axis in base_link (OceanWATERS X_SHOU, Y_SHOU).
SHOULDER_XY = (0.79, 0.175)
#: m, lateral offset of the arm's working plane from the shoulder axis (Y_SHOU - HAND_Y_OFFSET).
ARM_PLANE_OFFSET = 0.15
#: m, lateral distance between the two grinding passes (OceanWATERS: 0.08 m / 0.08 rad).
GRIND_PASS_SHIFT = 0.08


def grind_axes(yaw: float, parallel: bool) -> tuple[tuple[float, float], tuple[float, float]]:
    """(along, shift): unit (x, y) directions of a grind's passes and of the step from the first
    pass to the second, for the shoulder yaw ``yaw`` rad at the trench. A radial trench
    (``parallel``) runs along the heading with the second pass to its left; one across the arm
    runs to the right of the heading with the second pass further out from the lander."""
    heading = (math.cos(yaw), math.sin(yaw))
    right = (math.sin(yaw), -math.cos(yaw))
    return (heading, (-right[0], -right[1])) if parallel else (right, heading)


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
