"""The mission's steps through OceanWATERS' actions (``interface: actions``), free of ROS.

:func:`action_goal` maps a step of :data:`ow_mission.mission.STEPS` and its service request to
the action (owl_msgs, served by ``arm_services``) and goal fields that do the same;
:func:`step_response` turns how the goal ended into a response the step's
:meth:`~ow_mission.mission.StepResult.take_response` reads, so the report has the same fields
(the ground found from ArmFindSurface's final pose). Goal fields are plain values; points are
(3,) tuples (m, base_link), filled into the goal message by
:func:`ow_lander.conversions.fill_fields`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from ow_lander.operations.workspace import GRIND_PASS_SHIFT, grind_axes, shoulder_yaw_for
from ow_mission.errors import ConfigError

#: N and N m, ArmFindSurface's thresholds (the force ground detector's 10 N rise).
FIND_SURFACE_FORCE_N = 10.0
FIND_SURFACE_TORQUE_NM = 10.0
#: The normal of the flat surface searched (ArmFindSurface's ``normal`` is the surface's, as in
#: OceanWATERS: the search runs against it, straight down).
UP = (0.0, 0.0, 1.0)
#: ArmFindSurface's status text when the search ended without contact (OceanWATERS: a success).
NO_SURFACE = "No surface was found"


def _linear_middle(x: float, y: float, length: float) -> tuple[float, float]:
    """The middle of a radial cut of ``length`` m starting at (x, y) m: TaskScoopLinear takes
    the middle, the service the start (the heading is aimed at the middle, so iterate)."""
    mx, my = x, y
    for _ in range(5):
        yaw = shoulder_yaw_for(mx, my, -math.pi, math.pi)
        mx, my = x + length / 2 * math.cos(yaw), y + length / 2 * math.sin(yaw)
    return mx, my


def _grind_centre(x: float, y: float, length: float, parallel: bool) -> tuple[float, float]:
    """The centre between the two passes of a grind whose first pass starts at (x, y) m:
    TaskGrind takes the centre, the service the start (the heading is aimed at the centre, so
    iterate)."""
    cx, cy = x, y
    for _ in range(8):
        along, shift = grind_axes(shoulder_yaw_for(cx, cy, -math.pi, math.pi), parallel)
        cx = x + along[0] * length / 2 + shift[0] * GRIND_PASS_SHIFT / 2
        cy = y + along[1] * length / 2 + shift[1] * GRIND_PASS_SHIFT / 2
    return cx, cy


def action_goal(step: str, request: Mapping[str, Any], dig: str) -> tuple[str, dict[str, Any]]:
    """The action and goal fields of mission step ``step`` whose service request is
    ``request`` (``dig``: the mission's "linear" or "circular").

    Raises:
        ConfigError: a step without an action.
    """
    r = request
    if step in ("unstow", "stow"):
        return f"Arm{step.capitalize()}", {}
    if step == "guarded_move":
        # The same search: from (x, y, z) down by search_distance, about its middle.
        start_z, distance = float(r["z"]), float(r["search_distance"])
        approach = distance / 2
        return "ArmFindSurface", {
            "frame": 0,
            "relative": False,
            "position": (r["x"], r["y"], start_z - approach),
            "normal": UP,
            "distance": approach,
            "overdrive": distance - approach,
            "force_threshold": FIND_SURFACE_FORCE_N,
            "torque_threshold": FIND_SURFACE_TORQUE_NM,
        }
    if step.startswith("grind"):
        parallel = bool(r["parallel"])
        x, y = _grind_centre(float(r["x"]), float(r["y"]), float(r["length"]), parallel)
        return "TaskGrind", {
            "x_start": x,
            "y_start": y,
            "depth": r["depth"],
            "length": r["length"],
            "parallel": 1.0 if parallel else 0.0,
            "ground_position": r["ground_position"],
        }
    if step.startswith("dig"):
        goal = {"frame": 0, "relative": False, "depth": r["depth"]}
        if dig == "linear":
            x, y = _linear_middle(r["x"], r["y"], r["length"])
            point = (x, y, r["ground_position"])
            return "TaskScoopLinear", {**goal, "point": point, "length": r["length"]}
        point = (r["x"], r["y"], r["ground_position"])
        return "TaskScoopCircular", {**goal, "point": point, "parallel": r["parallel"]}
    if step == "discard_spoil":
        point = (r["x"], r["y"], r["z"])
        return "TaskDiscardSample", {"frame": 0, "relative": False, "point": point, "height": 0.0}
    if step == "deliver_sample":
        return "TaskDeliverSample", {}
    msg = f"mission step {step!r} has no action"
    raise ConfigError(msg)


@dataclass
class Position:
    """A point (m, base_link) as a response field."""

    x: float = 0.0
    y: float = 0.0
    z: float = 0.0


@dataclass
class StepResponse:
    """What a goal's end gives a step, in the services' response fields."""

    success: bool
    message: str
    planning_time: float = 0.0
    ground_found: bool = False
    ground_position: Position = field(default_factory=Position)


def step_response(action: str, succeeded: bool, text: str, result: Any) -> StepResponse:
    """The response of a goal of ``action`` that ended ``succeeded`` (or not) with status
    ``text`` and ``result`` (the action's result message, or None). ArmFindSurface succeeds
    when it finds nothing too (OceanWATERS' convention): no ground then."""
    response = StepResponse(succeeded, f"{action}: {text}")
    if action == "ArmFindSurface" and succeeded and result is not None and NO_SURFACE not in text:
        p = result.final_pose.position
        response.ground_found = True
        response.ground_position = Position(float(p.x), float(p.y), float(p.z))
    return response
