"""OceanWATERS' arm and task actions (owl_msgs) on the paper's operations, free of ROS.

A goal arrives as a flat ``{field: value}`` mapping (nested message fields joined with dots:
``pose.position.x``; arrays as lists; see :func:`ow_lander.conversions.goal_to_dict`).
:func:`validate_goal` checks every field before anything moves and raises
:class:`~ow_lander.errors.GoalError` naming the field, its value and the limit;
:func:`to_request` turns a valid goal into an :class:`ActionRequest`: the operation of
:class:`~ow_lander.operations.planner.Operations` that carries it out, with its request.
:func:`arm_state` and :func:`action_values` build the feedback and result fields from a joint
state and the wrist force/torque.

Frames (OceanWATERS): ``frame`` 0 = base_link, 1 = the tool frame ``l_scoop_tip`` at the start
of the action (a point or pose in it is an offset from the tool); ``relative`` with frame 0 adds
the goal's position to the tool's position (and turns its orientation by the goal's rotation).
Joint indices of ArmMoveJoint(s): 0..5 from the shoulder to the scoop (:data:`ARM_JOINTS`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from ow_description.description import ARM_JOINTS, SCOOP_TIP_FRAME
from ow_description.model import LanderModel
from ow_lander.errors import GoalError
from ow_runtime.names import ARM_ACTIONS

FloatArray = npt.NDArray[np.float64]

#: m and rad, how close a Cartesian move must end to its target (OceanWATERS).
CARTESIAN_TOLERANCE = (0.01, 0.05)
#: Frames a goal's ``frame`` may name.
FRAMES = {0: "base_link", 1: SCOOP_TIP_FRAME}


@dataclass
class ActionRequest:
    """What carries out one goal.

    Attributes:
        operation: the :meth:`~ow_lander.operations.planner.Operations.plan` operation name.
        request: its request (base_link, m, rad).
        wrench_limits: (N, N m) force and torque thresholds of a guarded action, or None.
        target_pose: (4, 4) ``X_base_tip`` a Cartesian move must end at (checked), or None.
        surface_point: (3,) m, base_link, ArmFindSurface's expected surface point, or None.
    """

    operation: str
    request: dict[str, Any]
    wrench_limits: tuple[float, float] | None = None
    target_pose: FloatArray | None = None
    surface_point: FloatArray | None = None
    notes: list[str] = field(default_factory=list)


def _fail(name: str, value: Any, limit: str) -> GoalError:
    return GoalError(f"{name}={value!r} {limit}")


def validate_goal(action: str, goal: Mapping[str, Any]) -> None:
    """Check every field of ``goal`` (flat, see the module docstring) of ``action``.

    Raises:
        GoalError: unknown action, a value not finite, a joint index outside 0..5, a frame
            other than 0/1, not 6 angles, a zero normal or quaternion, a threshold or distance
            not positive (the message names the field, its value and the limit).
    """
    if action not in ARM_ACTIONS:
        msg = f"unknown action {action!r}; known: {', '.join(ARM_ACTIONS)}"
        raise GoalError(msg)
    for name, value in goal.items():
        values = value if isinstance(value, list | tuple) else [value]
        for i, v in enumerate(values):
            if isinstance(v, float) and not math.isfinite(v):
                label = f"{name}[{i}]" if isinstance(value, list | tuple) else name
                raise _fail(label, v, "is not finite")
    if "joint" in goal and not 0 <= goal["joint"] < len(ARM_JOINTS):
        raise _fail("joint", goal["joint"], "is outside the joint indices 0..5")
    if "frame" in goal and goal["frame"] not in FRAMES:
        raise _fail("frame", goal["frame"], "is neither 0 (base_link) nor 1 (tool)")
    if "angles" in goal and len(goal["angles"]) != len(ARM_JOINTS):
        raise _fail("angles", list(goal["angles"]), "must have 6 values (shoulder to scoop)")
    for name in ("force_threshold", "torque_threshold", "distance"):
        if name in goal and not goal[name] > 0:
            raise _fail(name, goal[name], "must be > 0")
    for name in ("overdrive", "height"):
        if name in goal and goal[name] < 0:
            raise _fail(name, goal[name], "must be >= 0")
    if "normal.x" in goal and _norm(goal, "normal", "xyz") < 1e-6:
        raise _fail("normal", _vector(goal, "normal", "xyz").tolist(), "is a zero vector")
    if "pose.orientation.w" in goal and _norm(goal, "pose.orientation", "xyzw") < 1e-6:
        value = _vector(goal, "pose.orientation", "xyzw").tolist()
        raise _fail("pose.orientation", value, "is a zero quaternion")


def _vector(goal: Mapping[str, Any], prefix: str, axes: str) -> FloatArray:
    return np.array([float(goal[f"{prefix}.{a}"]) for a in axes])


def _norm(goal: Mapping[str, Any], prefix: str, axes: str) -> float:
    return float(np.linalg.norm(_vector(goal, prefix, axes)))


def _point(goal: Mapping[str, Any], prefix: str, X_base_tip: FloatArray) -> FloatArray:
    """(3,) m in base_link: the goal's point ``prefix`` in its frame (see module docstring)."""
    p = _vector(goal, prefix, "xyz")
    if goal["frame"] == 1:
        return X_base_tip[:3, :3] @ p + X_base_tip[:3, 3]
    return p + X_base_tip[:3, 3] if goal["relative"] else p


def rotation_from_quaternion(q: FloatArray) -> FloatArray:
    """(3, 3) rotation of quaternion ``q`` = (x, y, z, w), normalised first."""
    x, y, z, w = np.asarray(q, dtype=np.float64) / np.linalg.norm(q)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def quaternion_from_rotation(R: FloatArray) -> FloatArray:
    """(4,) quaternion (x, y, z, w), w >= 0, of rotation ``R`` (3, 3)."""
    w = math.sqrt(max(0.0, 1 + R[0, 0] + R[1, 1] + R[2, 2])) / 2
    x = math.copysign(math.sqrt(max(0.0, 1 + R[0, 0] - R[1, 1] - R[2, 2])) / 2, R[2, 1] - R[1, 2])
    y = math.copysign(math.sqrt(max(0.0, 1 - R[0, 0] + R[1, 1] - R[2, 2])) / 2, R[0, 2] - R[2, 0])
    z = math.copysign(math.sqrt(max(0.0, 1 - R[0, 0] - R[1, 1] + R[2, 2])) / 2, R[1, 0] - R[0, 1])
    return np.array([x, y, z, w])


def target_pose(goal: Mapping[str, Any], X_base_tip: FloatArray) -> FloatArray:
    """(4, 4) ``X_base_target`` of a Cartesian goal (its ``pose`` in its frame)."""
    X = np.eye(4)
    X[:3, :3] = rotation_from_quaternion(_vector(goal, "pose.orientation", "xyzw"))
    X[:3, 3] = _vector(goal, "pose.position", "xyz")
    if goal["frame"] == 1:
        return X_base_tip @ X
    if goal["relative"]:
        X[:3, 3] += X_base_tip[:3, 3]
        X[:3, :3] = X[:3, :3] @ X_base_tip[:3, :3]
    return X


def pose_error(X_target: FloatArray, X_measured: FloatArray) -> tuple[float, float]:
    """(m, rad): distance and rotation angle between two poses (4, 4)."""
    distance = float(np.linalg.norm(X_target[:3, 3] - X_measured[:3, 3]))
    R = X_target[:3, :3].T @ X_measured[:3, :3]
    angle = math.acos(max(-1.0, min(1.0, (float(np.trace(R)) - 1) / 2)))
    return distance, angle


def to_request(
    action: str,
    goal: Mapping[str, Any],
    arm: FloatArray,
    X_base_tip: FloatArray,
    yaw: Callable[[float, float], float],
) -> ActionRequest:
    """The operation and request carrying out a valid ``goal`` of ``action``, from the arm at
    ``arm`` (6,) rad with the tool at ``X_base_tip`` (4, 4); ``yaw(x, y)`` is the shoulder yaw
    (rad) aiming the arm at a point (the heading of a linear cut)."""
    if action in ("ArmUnstow", "ArmStow"):
        return ActionRequest(action[3:].lower(), {"delete_prev_traj": False})
    if action == "ArmMoveJoint":
        target = np.array(arm, dtype=np.float64)
        j = int(goal["joint"])
        target[j] = target[j] + goal["angle"] if goal["relative"] else goal["angle"]
        return ActionRequest("move_joints", {"angles": target.tolist()})
    limits = _limits(goal)
    if action.startswith("ArmMoveJoints"):
        angles = np.asarray(goal["angles"], dtype=np.float64)
        target = arm + angles if goal["relative"] else angles
        request = {"angles": target.tolist(), "guarded": limits is not None}
        return ActionRequest("move_joints", request, limits)
    if action.startswith("ArmMoveCartesian"):
        X = target_pose(goal, X_base_tip)
        request = {
            "position": X[:3, 3].tolist(),
            "rotation": X[:3, :3].tolist(),
            "guarded": limits is not None,
        }
        return ActionRequest("move_cartesian", request, limits, target_pose=X)
    if action == "ArmFindSurface":
        point = _point(goal, "position", X_base_tip)
        normal = _vector(goal, "normal", "xyz")
        normal /= np.linalg.norm(normal)
        start = point - goal["distance"] * normal
        # The paper's guarded move takes the surface normal (up): the opposite of the approach.
        request = {
            "use_defaults": False,
            "x": start[0],
            "y": start[1],
            "z": start[2],
            "direction_x": -normal[0],
            "direction_y": -normal[1],
            "direction_z": -normal[2],
            "search_distance": goal["distance"] + goal["overdrive"],
        }
        return ActionRequest("guarded_move", request, limits, surface_point=point)
    if action == "TaskGrind":
        request = {
            "use_defaults": False,
            "x": goal["x_start"],
            "y": goal["y_start"],
            "depth": goal["depth"],
            "length": goal["length"],
            "parallel": goal["parallel"] != 0,
            "ground_position": goal["ground_position"],
        }
        return ActionRequest("grind", request)
    if action == "TaskDeliverSample":
        return ActionRequest("deliver_sample", {"use_defaults": True})
    point = _point(goal, "point", X_base_tip)
    if action == "TaskDiscardSample":
        x, y, z = point + np.array([0.0, 0.0, goal["height"]])
        return ActionRequest("discard", {"use_defaults": False, "x": x, "y": y, "z": z})
    request = {"use_defaults": False, "depth": goal["depth"], "ground_position": point[2]}
    if action == "TaskScoopCircular":
        request.update(x=point[0], y=point[1], parallel=bool(goal["parallel"]))
        return ActionRequest("dig_circular", request)
    # TaskScoopLinear: OceanWATERS' point is the middle of the cut, ours its start.
    heading = yaw(float(point[0]), float(point[1]))
    half = goal["length"] / 2
    x, y = point[0] - half * math.cos(heading), point[1] - half * math.sin(heading)
    request.update(x=x, y=y, length=goal["length"])
    return ActionRequest("dig_linear", request)


def _limits(goal: Mapping[str, Any]) -> tuple[float, float] | None:
    if "force_threshold" not in goal:
        return None
    return float(goal["force_threshold"]), float(goal["torque_threshold"])


@dataclass(frozen=True)
class ArmState:
    """The arm as the actions report it.

    Attributes:
        angles: (6,) rad, arm joints from the shoulder to the scoop.
        X_base_tip: (4, 4), ``l_scoop_tip`` in base_link.
        force: N, magnitude of the wrist force.
        torque: N m, magnitude of the wrist torque.
    """

    angles: FloatArray
    X_base_tip: FloatArray
    force: float
    torque: float


def arm_state(
    model: LanderModel, joints: Mapping[str, float], force: FloatArray, torque: FloatArray
) -> ArmState:
    """The :class:`ArmState` of a joint state (rad by name) and a wrist reading (N, N m)."""
    angles = np.array([joints[j] for j in ARM_JOINTS])
    known = {j: v for j, v in joints.items() if j in model.joint_names}
    X = model.fk(model.q_from(known), SCOOP_TIP_FRAME)
    return ArmState(angles, X, float(np.linalg.norm(force)), float(np.linalg.norm(torque)))


def action_values(state: ArmState, surface_point: FloatArray | None = None) -> dict[str, Any]:
    """Every feedback and result value an action may carry, by field name (OceanWATERS'
    names: the node fills the fields its message has). Poses as ((3,) m, (4,) x y z w)."""
    position = state.X_base_tip[:3, 3]
    pose = (position.tolist(), quaternion_from_rotation(state.X_base_tip[:3, :3]).tolist())
    distance = 0.0 if surface_point is None else float(np.linalg.norm(position - surface_point))
    angles = state.angles.tolist()
    values: dict[str, Any] = {"angles": angles, "final_angles": angles, "pose": pose}
    values.update(final_pose=pose, current=pose[0], final=pose[0], distance=distance)
    values.update(final_distance=distance, force=state.force, torque=state.torque)
    values.update(final_force=state.force, final_torque=state.torque)
    return values
