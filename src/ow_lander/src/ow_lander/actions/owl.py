"""OceanWATERS' arm and task actions (owl_msgs) on the paper's operations, free of ROS.

A goal arrives as a flat ``{field: value}`` mapping (nested message fields joined with dots:
``pose.position.x``; arrays as lists; see :func:`ow_lander.conversions.goal_to_dict`).
:func:`validate_goal` checks what OceanWATERS (HEAD) checks, with its texts, and what it lets
through by mistake (a NaN), and raises :class:`~ow_lander.errors.GoalError`;
:func:`to_request` turns a valid goal into an :class:`ActionRequest`: the operation of
:class:`~ow_lander.operations.planner.Operations` that carries it out, with its request and what
its end is checked against (:mod:`ow_lander.actions.outcomes`). :func:`arm_state` and
:func:`action_values` build the feedback and result fields from a joint state and the wrist
force/torque.

Frames (OceanWATERS): ``frame`` 0 = base_link, 1 = the tool frame ``l_scoop_tip`` at the start
of the action (a point or pose in it is an offset from the tool; ``relative`` then changes
nothing: the tool is at the origin of its own frame); ``relative`` with frame 0 adds the goal's
position to the tool's position and turns the tool's orientation by the goal's rotation about
the tool's own axes (``R_tool @ R_goal``). Joint indices of ArmMoveJoint(s): 0..5 from the
shoulder to the scoop (:data:`ARM_JOINTS`). Depths, lengths, heights, distances and overdrives
are not checked here (OceanWATERS never checks them): what cannot be planned fails in planning.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import numpy.typing as npt

from ow_description.description import ARM_JOINTS, SCOOP_TIP_FRAME
from ow_description.model import LanderModel
from ow_lander.config import ExecutionConfig
from ow_lander.errors import GoalError
from ow_runtime.names import ARM_ACTIONS

__all__ = [
    "ARM_ACTIONS",
    "CARTESIAN_TOLERANCE",
    "FRAMES",
    "JOINT_TOLERANCE",
    "ActionRequest",
    "ArmState",
    "action_values",
    "angles_reached",
    "arm_state",
    "pose_error",
    "quaternion_from_rotation",
    "rotation_between",
    "rotation_from_quaternion",
    "target_pose",
    "to_request",
    "validate_goal",
]

FloatArray = npt.NDArray[np.float64]

#: m and rad, how close a Cartesian move must end to its target (OceanWATERS).
CARTESIAN_TOLERANCE = (0.01, 0.05)
#: rad, how close each arm joint must end to its target, modulo a turn (OceanWATERS).
JOINT_TOLERANCE = 0.05
#: s of simulation time OceanWATERS' arm_controller allows after a trajectory's last point to
#: reach it (``goal_time``); it checks no tracking error on the way (its trajectory tolerances
#: are 0, "not checked"). Goals run with these constraints (:func:`controller_constraints`).
CONTROLLER_GOAL_TIME_S = 50.0
#: Frames a goal's ``frame`` may name.
FRAMES = {0: "base_link", 1: SCOOP_TIP_FRAME}
#: The scoop bottom's outward normal in the tool frame (ArmFindSurface turns it against the
#: surface normal).
SCOOP_BOTTOM = np.array([0.0, 0.0, 1.0])


@dataclass
class ActionRequest:
    """What carries out one goal, and what its end is checked against.

    Attributes:
        operation: the :meth:`~ow_lander.operations.planner.Operations.plan` operation name.
        request: its request (base_link, m, rad).
        wrench_limits: (N, N m) force and torque thresholds of a guarded action, or None.
        target_pose: (4, 4) ``X_base_tip`` a Cartesian move must end at, or None.
        target_angles: (6,) rad a joint move must end at (modulo a turn), or None.
        surface_point: (3,) m, base_link, ArmFindSurface's estimated surface point, or None.
        surface_normal: (3,) unit, base_link, ArmFindSurface's surface normal, or None.
        setup_point: (3,) m, ArmFindSurface's start of the approach (surface + distance normal).
        approach_end: (3,) m, where ArmFindSurface's approach ends unless a threshold stops it.
        notes: remarks for the log.
    """

    operation: str
    request: dict[str, Any]
    wrench_limits: tuple[float, float] | None = None
    target_pose: FloatArray | None = None
    target_angles: FloatArray | None = None
    surface_point: FloatArray | None = None
    surface_normal: FloatArray | None = None
    setup_point: FloatArray | None = None
    approach_end: FloatArray | None = None
    notes: list[str] = field(default_factory=list)

    @property
    def breaches_at_once(self) -> bool:
        """OceanWATERS' guard trips when ``|F| >= force_threshold`` or ``|T| >=
        torque_threshold``: a threshold <= 0 (the message default is 0) trips at its first
        check, so the guarded motion does not move."""
        return self.wrench_limits is not None and min(self.wrench_limits) <= 0.0


def controller_constraints(config: ExecutionConfig) -> ExecutionConfig:
    """``config`` with OceanWATERS' trajectory constraints for an action goal: no abort on a
    joint lagging its set-point (a dig the terrain holds back carries on, as OceanWATERS'), and
    :data:`CONTROLLER_GOAL_TIME_S` after the last point to arrive."""
    return replace(config, max_tracking_error_rad=math.inf, settle_timeout_s=CONTROLLER_GOAL_TIME_S)


def validate_goal(action: str, goal: Mapping[str, Any]) -> None:
    """Check ``goal`` (flat, see the module docstring) of ``action`` as OceanWATERS does, and
    refuse the NaNs it lets through.

    Raises:
        GoalError: unknown action; a value that is NaN (or infinite, thresholds excepted: an
            infinite threshold never trips); with OceanWATERS' texts: a frame other than 0/1,
            a joint index outside 0..5, not 6 angles, a zero quaternion or normal.
    """
    if action not in ARM_ACTIONS:
        msg = f"unknown action {action!r}; known: {', '.join(ARM_ACTIONS)}"
        raise GoalError(msg)
    for name, value in goal.items():
        values = value if isinstance(value, list | tuple) else [value]
        for i, v in enumerate(values):
            if not isinstance(v, float) or math.isfinite(v):
                continue
            if math.isnan(v) or not name.endswith("_threshold"):
                label = f"{name}[{i}]" if isinstance(value, list | tuple) else name
                msg = f"{label}={v!r} is not finite"
                raise GoalError(msg)
    if "frame" in goal and goal["frame"] not in FRAMES:
        msg = f"Unrecognized frame index {goal['frame']}. Options are {FRAMES}"
        raise GoalError(msg)
    if "joint" in goal and not 0 <= goal["joint"] < len(ARM_JOINTS):
        msg = f"Provided joint index is not within range: joint={goal['joint']}, not in 0..5"
        raise GoalError(msg)
    if "angles" in goal and len(goal["angles"]) != len(ARM_JOINTS):
        msg = (
            "Number of angle positions provided does not much the number of joints in the arm "
            f"move group: angles={list(goal['angles'])} has {len(goal['angles'])} values, "
            f"{len(ARM_JOINTS)} needed"
        )
        raise GoalError(msg)
    if "pose.orientation.w" in goal and _norm(goal, "pose.orientation", "xyzw") == 0.0:
        msg = "Orientation is the zero-quaternion and cannot represent a rotation"
        raise GoalError(msg)
    if "normal.x" in goal and _norm(goal, "normal", "xyz") == 0.0:
        msg = "Normal is the zero-vector and cannot represent a direction"
        raise GoalError(msg)


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


def rotation_between(a: FloatArray, b: FloatArray) -> FloatArray:
    """(3, 3) the smallest rotation taking direction ``a`` (3,) onto ``b`` (3,); for opposite
    directions, the half turn about ``a`` x (the base axis ``a`` is least along), as
    OceanWATERS picks it (so the scoop turned against an upward normal keeps its x along
    base_link's x)."""
    a = np.asarray(a, dtype=np.float64) / np.linalg.norm(a)
    b = np.asarray(b, dtype=np.float64) / np.linalg.norm(b)
    c = float(a @ b)
    if math.isclose(c, -1.0):
        x, y, z = np.abs(a)
        if x < y:
            basis = np.eye(3)[0] if x < z else np.eye(3)[2]
        else:
            basis = np.eye(3)[1] if y < z else np.eye(3)[2]
        axis = np.cross(a, basis)
        axis /= np.linalg.norm(axis)
        return 2 * np.outer(axis, axis) - np.eye(3)
    v = np.cross(a, b)
    K = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    return np.eye(3) + K + K @ K / (1 + c)


def target_pose(goal: Mapping[str, Any], X_base_tip: FloatArray) -> FloatArray:
    """(4, 4) ``X_base_target`` of a Cartesian goal (its ``pose`` in its frame)."""
    X = np.eye(4)
    X[:3, :3] = rotation_from_quaternion(_vector(goal, "pose.orientation", "xyzw"))
    X[:3, 3] = _vector(goal, "pose.position", "xyz")
    if goal["frame"] == 1:
        return X_base_tip @ X
    if goal["relative"]:
        X[:3, 3] += X_base_tip[:3, 3]
        X[:3, :3] = X_base_tip[:3, :3] @ X[:3, :3]
    return X


def pose_error(X_target: FloatArray, X_measured: FloatArray) -> tuple[float, float]:
    """(m, rad): distance and rotation angle between two poses (4, 4)."""
    distance = float(np.linalg.norm(X_target[:3, 3] - X_measured[:3, 3]))
    R = X_target[:3, :3].T @ X_measured[:3, :3]
    angle = math.acos(max(-1.0, min(1.0, (float(np.trace(R)) - 1) / 2)))
    return distance, angle


def angles_reached(
    target: FloatArray, angles: FloatArray, tolerance: float = JOINT_TOLERANCE
) -> bool:
    """Whether every joint of ``angles`` (6,) rad is within ``tolerance`` rad of ``target``
    (6,) rad, a whole turn apart counting as the same (OceanWATERS compares modulo 2 pi)."""
    difference = np.asarray(angles, dtype=np.float64) - np.asarray(target, dtype=np.float64)
    wrapped = (difference + math.pi) % (2 * math.pi) - math.pi
    return bool(np.all(np.abs(wrapped) <= tolerance))


def to_request(
    action: str,
    goal: Mapping[str, Any],
    arm: FloatArray,
    X_base_tip: FloatArray,
) -> ActionRequest:
    """The operation and request carrying out a valid ``goal`` of ``action``, from the arm at
    ``arm`` (6,) rad with the tool at ``X_base_tip`` (4, 4)."""
    limits = _limits(goal)
    if action in ("ArmUnstow", "ArmStow"):
        return ActionRequest(action[3:].lower(), {"delete_prev_traj": False})
    if action == "ArmMoveJoint":
        target = np.array(arm, dtype=np.float64)
        j = int(goal["joint"])
        target[j] = target[j] + goal["angle"] if goal["relative"] else goal["angle"]
        return ActionRequest("move_joints", {"angles": target.tolist()}, target_angles=target)
    if action.startswith("ArmMoveJoints"):
        angles = np.asarray(goal["angles"], dtype=np.float64)
        target = arm + angles if goal["relative"] else angles
        request = {"angles": target.tolist(), "guarded": limits is not None}
        return ActionRequest("move_joints", request, limits, target_angles=target)
    if action.startswith("ArmMoveCartesian"):
        X = target_pose(goal, X_base_tip)
        request = {
            "position": X[:3, 3].tolist(),
            "rotation": X[:3, :3].tolist(),
            "guarded": limits is not None,
        }
        return ActionRequest("move_cartesian", request, limits, target_pose=X)
    if action == "ArmFindSurface":
        return _find_surface(goal, X_base_tip, limits)
    if action == "TaskGrind":
        request = {
            "use_defaults": False,
            "centred": True,
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
    request = {
        "use_defaults": False,
        "centred": True,
        "x": point[0],
        "y": point[1],
        "depth": goal["depth"],
        "ground_position": point[2],
    }
    if action == "TaskScoopCircular":
        request["parallel"] = bool(goal["parallel"])
        return ActionRequest("dig_circular", request)
    request["length"] = goal["length"]  # TaskScoopLinear: the point is the middle of the cut
    return ActionRequest("dig_linear", request)


def _find_surface(
    goal: Mapping[str, Any], X_base_tip: FloatArray, limits: tuple[float, float] | None
) -> ActionRequest:
    """ArmFindSurface: the scoop bottom turned against the surface ``normal`` (base_link in
    every frame), from ``position + distance normal`` straight to ``position - overdrive
    normal``. With a threshold that trips at once, only the move to the setup pose."""
    point = _point(goal, "position", X_base_tip)
    normal = _vector(goal, "normal", "xyz")
    normal /= np.linalg.norm(normal)
    rotation = rotation_between(SCOOP_BOTTOM, -normal)
    setup = point + goal["distance"] * normal
    end = point - goal["overdrive"] * normal
    checks = {
        "surface_point": point,
        "surface_normal": normal,
        "setup_point": setup,
        "approach_end": end,
    }
    if limits is not None and min(limits) <= 0.0:
        request = {"position": setup.tolist(), "rotation": rotation.tolist(), "guarded": False}
        return ActionRequest("move_cartesian", request, limits, **checks)
    request = {
        "use_defaults": False,
        "x": setup[0],
        "y": setup[1],
        "z": setup[2],
        # The paper's guarded move takes the surface normal and descends against it.
        "direction_x": normal[0],
        "direction_y": normal[1],
        "direction_z": normal[2],
        "search_distance": goal["distance"] + goal["overdrive"],
        "rotation": rotation.tolist(),
    }
    return ActionRequest("guarded_move", request, limits, **checks)


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
