"""Messages to and from the pure types of ow_lander (HeightMap, joint states, requests,
trajectories, operation markers, guarded-move results). Message classes only: no rospy."""

from __future__ import annotations

import json
import struct
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import genpy
import numpy as np
from geometry_msgs.msg import Point, Pose, Quaternion, Vector3
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from ow_description.description import BASE_FRAME
from ow_msgs.msg import GroundDetectorSignal, GuardedMoveResult, Operation

if TYPE_CHECKING:  # annotations only: reading messages does not load the model (pinocchio)
    from ow_description.trajectory import Trajectory
    from ow_lander.execution.monitor import DetectorSignal, ExecutionResult


_U32 = struct.Struct("<I")
_STAMP = struct.Struct("<II")
#: bytes of a geometry_msgs/Transform: translation (3) and rotation (4) float64.
_TRANSFORM_BYTES = 7 * 8


def tf_message_stamps(data: bytes | memoryview) -> list[float]:
    """The header stamps (s, as ``genpy.Time.to_sec``) of a serialised tf2_msgs/TFMessage's
    transforms, in order, read without building the message (twelve transforms: 3.8 us
    against 45.8 us for genpy's deserialisation).

    Raises:
        ValueError: ``data`` is not a whole TFMessage.
    """
    try:
        (count,) = _U32.unpack_from(data, 0)
        offset = 4
        stamps = []
        for _ in range(count):
            # Header: seq, stamp (secs, nsecs), frame_id; then child_frame_id, the transform.
            secs, nsecs = _STAMP.unpack_from(data, offset + 4)
            stamps.append(float(secs) + float(nsecs) / 1e9)
            (frame_length,) = _U32.unpack_from(data, offset + 12)
            offset += 16 + frame_length
            (child_length,) = _U32.unpack_from(data, offset)
            offset += 4 + child_length + _TRANSFORM_BYTES
    except struct.error as error:
        msg = f"not a tf2_msgs/TFMessage of {len(data)} bytes: {error}"
        raise ValueError(msg) from error
    if offset != len(data):
        msg = f"not a tf2_msgs/TFMessage: {count} transforms end at byte {offset} of {len(data)}"
        raise ValueError(msg)
    return stamps


def request_to_dict(request: Any) -> dict[str, Any]:
    """A service request's fields as ``{name: value}`` (floats as Python floats)."""
    out: dict[str, Any] = {}
    for name in request.__slots__:
        value = getattr(request, name)
        out[name] = float(value) if isinstance(value, float) else value
    return out


def joint_positions(names: list[str], positions: Any) -> dict[str, float]:
    """``{joint: position}`` of a ``sensor_msgs/JointState`` (by name, never by order)."""
    return {name: float(p) for name, p in zip(names, positions, strict=False)}


def jsonable(values: Mapping[str, Any]) -> dict[str, Any]:
    """Parameters with numpy and float32 values turned into plain JSON numbers."""
    out: dict[str, Any] = {}
    for key, value in values.items():
        if isinstance(value, bool | str) or value is None:
            out[key] = value
        elif isinstance(value, int | float | np.floating | np.integer):
            out[key] = round(float(value), 6)
        else:
            out[key] = str(value)
    return out


def trajectory_msg(trajectory: Trajectory, t_start: float, token: str = "") -> JointTrajectory:
    """A ``trajectory_msgs/JointTrajectory`` of ``trajectory`` starting at ``t_start`` s (sim; 0:
    when the simulation queues it): every row with its positions (rad) and velocities (rad/s);
    ``token`` in the header's frame_id, echoed by the simulation's receipt."""
    msg = JointTrajectory()
    msg.header.stamp = genpy.Time.from_sec(t_start)
    msg.header.frame_id = token
    msg.joint_names = list(trajectory.joints)
    for t, position, velocity in zip(
        trajectory.times, trajectory.positions, trajectory.velocities, strict=True
    ):
        point = JointTrajectoryPoint()
        point.positions = position.tolist()
        point.velocities = velocity.tolist()
        point.time_from_start = genpy.Duration.from_sec(float(t))
        msg.points.append(point)
    return msg


def operation_msg(
    stamp: genpy.Time,
    op_id: int,
    name: str,
    event: int,
    parameters: Mapping[str, Any],
    response: Any = None,
) -> Operation:
    """An ``ow_msgs/Operation`` START or END marker; an END marker carries the ``response``'s
    success, message and trajectory file (if it has one). The parameters go as JSON."""
    msg = Operation()
    msg.header.stamp = stamp
    msg.header.frame_id = BASE_FRAME
    msg.id = op_id
    msg.name = name
    msg.event = event
    msg.parameters = json.dumps(jsonable(parameters), sort_keys=True)
    if response is not None:
        msg.success = bool(response.success)
        msg.message = str(response.message)
        msg.trajectory_file = str(getattr(response, "trajectory_file", ""))
    return msg


def guarded_move_result_msg(result: ExecutionResult, stamp: genpy.Time) -> GuardedMoveResult:
    """The ``ow_msgs/GuardedMoveResult`` of a guarded descent's ``result``, stamped ``stamp``."""
    msg = GuardedMoveResult()
    msg.header.stamp = stamp
    msg.header.frame_id = BASE_FRAME
    msg.success = result.ground_found
    msg.position = Point(*map(float, result.ground_position))
    msg.frame = BASE_FRAME
    return msg


def command_topic(joint: str) -> str:
    """The position-controller command topic of ``joint`` (OceanWATERS names)."""
    short = joint.removeprefix("j_")
    if short == "grinder":
        short = "grinder_yaw"
    return f"/{short}_position_controller/command"


def detector_signal_msg(signal: DetectorSignal) -> GroundDetectorSignal:
    """The ``ow_msgs/GroundDetectorSignal`` of one detector sample."""
    msg = GroundDetectorSignal()
    msg.header.stamp = genpy.Time.from_sec(signal.stamp)
    msg.header.frame_id = BASE_FRAME
    msg.detector = signal.detector
    msg.signal = signal.signal
    msg.moving_average = signal.moving_average
    msg.threshold = signal.threshold
    msg.contact = signal.contact
    return msg


def goal_to_dict(goal: Any, prefix: str = "") -> dict[str, Any]:
    """An action goal's fields, flat: nested messages joined with dots (``pose.position.x``),
    arrays as lists of floats, numbers as Python numbers."""
    out: dict[str, Any] = {}
    for name in goal.__slots__:
        value = getattr(goal, name)
        if hasattr(value, "__slots__"):
            out.update(goal_to_dict(value, f"{prefix}{name}."))
        elif isinstance(value, list | tuple):
            out[prefix + name] = [float(v) for v in value]
        else:
            out[prefix + name] = float(value) if isinstance(value, float) else value
    return out


def fill_fields(msg: Any, values: Mapping[str, Any]) -> Any:
    """Set the fields of ``msg`` (an action goal, result or feedback) that ``values`` has:
    numbers, lists, Points and Vector3s ((3,)) and Poses (((3,) m, (4,) x y z w))."""
    for name, kind in zip(msg.__slots__, msg._slot_types, strict=True):
        if name not in values:
            continue
        value = values[name]
        if kind == "geometry_msgs/Pose":
            value = Pose(Point(*value[0]), Quaternion(*value[1]))
        elif kind == "geometry_msgs/Point":
            value = Point(*value)
        elif kind == "geometry_msgs/Vector3":
            value = Vector3(*value)
        setattr(msg, name, value)
    return msg
