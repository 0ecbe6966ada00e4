"""Messages from the simulation's numpy and dataclass outputs, and joint transforms for tf.

The tf of a joint is computed here directly from its URDF origin and axis, cheaper than matrix
forward kinematics at tf rates. Quaternions are pinocchio's (``pin.Quaternion``), kept as
(x, y, z, w) tuples for the messages.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import genpy
import numpy as np
import pinocchio as pin
from geometry_msgs.msg import TransformStamped

from ow_description.terrain import HeightMap
from ow_msgs.msg import DemDig
from ow_msgs.msg import HeightMap as HeightMapMsg
from ow_sim_bullet.errors import CommandError
from ow_sim_bullet.tool_tracking import FloatArray
from ow_sim_bullet.trajectory import JointTrajectory

Quaternion = tuple[float, float, float, float]  # x, y, z, w


def stamp_parts(time_s: float) -> tuple[int, int]:
    """(secs, nsecs) of a sim time in seconds, rounded to the nanosecond."""
    nanoseconds = round(time_s * 1e9)
    return nanoseconds // 1_000_000_000, nanoseconds % 1_000_000_000


def stamp(time_s: float) -> genpy.Time:
    """ROS time for a sim time in seconds (rounded to the nanosecond)."""
    return genpy.Time(*stamp_parts(time_s))


_AXES = np.eye(3)


def _xyzw(quaternion: pin.Quaternion) -> Quaternion:
    """The (x, y, z, w) tuple of a pinocchio quaternion (the order of ROS messages)."""
    x, y, z, w = quaternion.coeffs().tolist()
    return x, y, z, w


def quaternion_from_rpy(roll: float, pitch: float, yaw: float) -> Quaternion:
    """URDF fixed-axis roll, pitch, yaw (rad) -> quaternion (x, y, z, w): the rotations about
    z, y and x composed by pinocchio (w = cos(yaw/2) cos(pitch/2) cos(roll/2) + ...)."""
    rotation = pin.Quaternion(pin.AngleAxis(yaw, _AXES[2]))
    rotation = rotation * pin.Quaternion(pin.AngleAxis(pitch, _AXES[1]))
    return _xyzw(rotation * pin.Quaternion(pin.AngleAxis(roll, _AXES[0])))


def quaternion_from_matrix(rotation: FloatArray) -> Quaternion:
    """(3, 3) rotation matrix -> quaternion (x, y, z, w), pinocchio's (Eigen's) conversion."""
    return _xyzw(pin.Quaternion(np.ascontiguousarray(rotation, dtype=np.float64)))


@dataclass(frozen=True)
class JointFrame:
    """A URDF joint as a tf transform parent -> child.

    Attributes:
        joint: joint name.
        parent: parent link (tf frame_id).
        child: child link (tf child_frame_id).
        translation: m, joint origin in the parent frame.
        rotation: the joint origin's rotation (x, y, z, w).
        axis: unit rotation axis in the joint frame, or None for a fixed joint.
        axis_rotation: ``rotation`` times the pure quaternion of ``axis`` (x, y, z, w; pinocchio's
            product), None for a fixed joint.
    """

    joint: str
    parent: str
    child: str
    translation: tuple[float, float, float]
    rotation: Quaternion
    axis: tuple[float, float, float] | None
    axis_rotation: Quaternion | None

    def rotation_at(self, angle: float) -> Quaternion:
        """Rotation of the child in the parent frame at joint angle ``angle`` (rad).

        That is ``rotation * (cos(angle/2) + sin(angle/2) axis)``; the Hamilton product being
        bilinear, it is ``cos(angle/2) rotation + sin(angle/2) axis_rotation``, both products
        made once by pinocchio: eight multiplications here instead of a product per call (tf
        runs at 30 Hz of sim time, tens of times real time).
        """
        if self.axis_rotation is None:
            return self.rotation
        c, s = math.cos(angle / 2), math.sin(angle / 2)
        (x0, y0, z0, w0), (x1, y1, z1, w1) = self.rotation, self.axis_rotation
        return (c * x0 + s * x1, c * y0 + s * y1, c * z0 + s * z1, c * w0 + s * w1)


def joint_frames(urdf_text: str) -> list[JointFrame]:
    """The revolute, continuous and fixed joints of a URDF as tf transforms."""
    frames = []
    for element in ET.fromstring(urdf_text).iter("joint"):
        kind = element.get("type", "")
        if kind not in ("revolute", "continuous", "fixed"):
            continue
        origin = element.find("origin")
        xyz = (origin.get("xyz", "0 0 0") if origin is not None else "0 0 0").split()
        rpy = (origin.get("rpy", "0 0 0") if origin is not None else "0 0 0").split()
        axis_element = element.find("axis")
        axis = axis_rotation = None
        rotation = quaternion_from_rpy(*(float(v) for v in rpy))
        if kind != "fixed":
            raw = np.array(
                [
                    float(v)
                    for v in (
                        axis_element.get("xyz", "1 0 0") if axis_element is not None else "1 0 0"
                    ).split()
                ]
            )
            unit = raw / np.linalg.norm(raw)
            axis = (float(unit[0]), float(unit[1]), float(unit[2]))
            x, y, z, w = rotation
            axis_rotation = _xyzw(pin.Quaternion(w, x, y, z) * pin.Quaternion(0.0, *axis))
        parent, child = element.find("parent"), element.find("child")
        frames.append(
            JointFrame(
                element.get("name", ""),
                parent.get("link", "") if parent is not None else "",
                child.get("link", "") if child is not None else "",
                (float(xyz[0]), float(xyz[1]), float(xyz[2])),
                rotation,
                axis,
                axis_rotation,
            )
        )
    return frames


def transform_msg(frame: JointFrame, angle: float, time_s: float) -> TransformStamped:
    """The tf of ``frame`` at joint angle ``angle`` (rad), stamped at sim time ``time_s``."""
    msg = TransformStamped()
    msg.header.stamp = stamp(time_s)
    msg.header.frame_id = frame.parent
    msg.child_frame_id = frame.child
    t = msg.transform.translation
    t.x, t.y, t.z = frame.translation
    r = msg.transform.rotation
    r.x, r.y, r.z, r.w = frame.rotation_at(angle)
    return msg


def heightmap_msg(heightmap: HeightMap, time_s: float) -> HeightMapMsg:
    """ow_msgs/HeightMap of a terrain, stamped at sim time ``time_s``."""
    msg = HeightMapMsg()
    msg.header.stamp = stamp(time_s)
    msg.header.frame_id = "base_link"
    msg.resolution = heightmap.resolution
    msg.origin_x = heightmap.origin_x
    msg.origin_y = heightmap.origin_y
    msg.rows, msg.cols = heightmap.shape
    msg.heights = heightmap.heights.astype(np.float32).ravel().tolist()
    return msg


@dataclass(frozen=True)
class TrajectoryRequest:
    """A ``trajectory_msgs/JointTrajectory`` as received, before the simulation validates it.

    Attributes:
        joints: joint names of the columns.
        start_time: s of sim time of the header stamp; 0 starts the trajectory on arrival.
        times: s from start of each point.
        positions: rad, one row per point.
        velocities: rad/s, one row per point, or None when no point gives velocities.
    """

    joints: tuple[str, ...]
    start_time: float
    times: tuple[float, ...]
    positions: tuple[tuple[float, ...], ...]
    velocities: tuple[tuple[float, ...], ...] | None

    @classmethod
    def from_msg(cls, trajectory: Any) -> TrajectoryRequest:
        """Read a ``trajectory_msgs/JointTrajectory``.

        Raises:
            CommandError: some points give velocities and others do not.
        """
        points = trajectory.points
        velocities = None
        if points and all(len(p.velocities) for p in points):
            velocities = tuple(tuple(p.velocities) for p in points)
        elif any(len(p.velocities) for p in points):
            msg = "give velocities on every point or on none"
            raise CommandError(msg)
        return cls(
            tuple(trajectory.joint_names),
            trajectory.header.stamp.to_sec(),
            tuple(p.time_from_start.to_sec() for p in points),
            tuple(tuple(p.positions) for p in points),
            velocities,
        )

    def build(self, now: float, known_joints: Sequence[str]) -> JointTrajectory:
        """The trajectory, starting at its stamp or, stamped 0, at sim time ``now`` (s).

        Raises:
            CommandError: unknown or repeated joints, bad times or non-finite values.
        """
        return JointTrajectory.build(
            self.joints,
            self.start_time if self.start_time > 0 else now,
            self.times,
            self.positions,
            self.velocities,
            known_joints,
        )


def dem_dig_msg(time_s: float, tool: str, summary: dict[str, Any]) -> DemDig:
    """``ow_msgs/DemDig`` of one live DEM dig (``LiveDig.summary()``), stamped ``time_s`` (s,
    sim): when the simulation learnt it ended."""
    sample = summary.get("sample") or {}
    msg = DemDig(
        tool=tool,
        start_time=float(summary["start_time"]),
        exchanges=int(summary["exchanges"]),
        particles=int(summary["particles"]),
        loose_particles=int(summary["loose_particles"]),
        sample_particles=int(sample.get("sample_particles", 0)),
        sample_volume=float(sample.get("sample_volume_m3", 0.0)),
        sample_mass=float(sample.get("sample_mass_kg", 0.0)),
        error=summary.get("error") or "",
    )
    msg.header.stamp = stamp(time_s)
    msg.header.frame_id = "base_link"
    return msg
