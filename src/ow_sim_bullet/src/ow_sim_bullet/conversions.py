"""Messages from the simulation's numpy and dataclass outputs, and joint transforms for tf.

The tf of a joint is computed here directly from its URDF origin and axis (pure Python
quaternions), which is cheaper than matrix forward kinematics at tf rates.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass

import genpy
import numpy as np
from geometry_msgs.msg import TransformStamped, WrenchStamped

from ow_lander.terrain import HeightMap
from ow_msgs.msg import HeightMap as HeightMapMsg
from ow_msgs.msg import ToolState as ToolStateMsg
from ow_sim_bullet.tool_tracking import FloatArray, ToolSnapshot

Quaternion = tuple[float, float, float, float]  # x, y, z, w


def stamp_parts(time_s: float) -> tuple[int, int]:
    """(secs, nsecs) of a sim time in seconds, rounded to the nanosecond."""
    nanoseconds = round(time_s * 1e9)
    return nanoseconds // 1_000_000_000, nanoseconds % 1_000_000_000


def stamp(time_s: float) -> genpy.Time:
    """ROS time for a sim time in seconds (rounded to the nanosecond)."""
    return genpy.Time(*stamp_parts(time_s))


def quaternion_from_rpy(roll: float, pitch: float, yaw: float) -> Quaternion:
    """URDF fixed-axis roll, pitch, yaw (rad) -> quaternion (x, y, z, w)."""
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    return (
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
        cr * cp * cy + sr * sp * sy,
    )


def quaternion_multiply(a: Quaternion, b: Quaternion) -> Quaternion:
    """Hamilton product a * b of (x, y, z, w) quaternions."""
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
        aw * bw - ax * bx - ay * by - az * bz,
    )


def quaternion_from_matrix(rotation: FloatArray) -> Quaternion:
    """(3, 3) rotation matrix -> quaternion (x, y, z, w)."""
    m = rotation
    trace = m[0, 0] + m[1, 1] + m[2, 2]
    if trace > 0:
        s = 0.5 / math.sqrt(trace + 1.0)
        return ((m[2, 1] - m[1, 2]) * s, (m[0, 2] - m[2, 0]) * s, (m[1, 0] - m[0, 1]) * s, 0.25 / s)
    i = int(np.argmax([m[0, 0], m[1, 1], m[2, 2]]))
    j, k = (i + 1) % 3, (i + 2) % 3
    s = 2.0 * math.sqrt(1.0 + m[i, i] - m[j, j] - m[k, k])
    q = [0.0, 0.0, 0.0, 0.0]
    q[i] = 0.25 * s
    q[j] = (m[j, i] + m[i, j]) / s
    q[k] = (m[k, i] + m[i, k]) / s
    q[3] = (m[k, j] - m[j, k]) / s
    return (q[0], q[1], q[2], q[3])


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
    """

    joint: str
    parent: str
    child: str
    translation: tuple[float, float, float]
    rotation: Quaternion
    axis: tuple[float, float, float] | None

    def rotation_at(self, angle: float) -> Quaternion:
        """Rotation of the child in the parent frame at joint angle ``angle`` (rad)."""
        if self.axis is None:
            return self.rotation
        s = math.sin(angle / 2)
        turn = (self.axis[0] * s, self.axis[1] * s, self.axis[2] * s, math.cos(angle / 2))
        return quaternion_multiply(self.rotation, turn)


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
        axis = None
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
        parent, child = element.find("parent"), element.find("child")
        frames.append(
            JointFrame(
                element.get("name", ""),
                parent.get("link", "") if parent is not None else "",
                child.get("link", "") if child is not None else "",
                (float(xyz[0]), float(xyz[1]), float(xyz[2])),
                quaternion_from_rpy(*(float(v) for v in rpy)),
                axis,
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


def tool_state_msg(snapshot: ToolSnapshot) -> ToolStateMsg:
    """ow_msgs/ToolState of a tool (pose and twist of its link in base_link)."""
    msg = ToolStateMsg()
    msg.header.stamp = stamp(snapshot.time)
    msg.header.frame_id = "base_link"
    msg.tool = snapshot.tool
    msg.link = snapshot.link
    position = snapshot.X_base_link[:3, 3]
    msg.pose.position.x, msg.pose.position.y, msg.pose.position.z = (float(v) for v in position)
    o = msg.pose.orientation
    o.x, o.y, o.z, o.w = quaternion_from_matrix(snapshot.X_base_link[:3, :3])
    lin, ang = msg.twist.linear, msg.twist.angular
    lin.x, lin.y, lin.z = (float(v) for v in snapshot.linear_velocity)
    ang.x, ang.y, ang.z = (float(v) for v in snapshot.angular_velocity)
    msg.depth = snapshot.depth
    msg.progress = snapshot.progress
    msg.material = snapshot.material
    return msg


def model_state_msg(snapshot: ToolSnapshot) -> ToolStateMsg:
    """ow_msgs/ToolState of the state the terrain-force model was given in a tool snapshot's step
    (its depth, not the depth measured after the step; depth 0 when no model ran)."""
    msg = tool_state_msg(snapshot)
    msg.depth = snapshot.model_depth
    return msg


def model_wrench_msg(snapshot: ToolSnapshot) -> WrenchStamped:
    """geometry_msgs/WrenchStamped of the terrain-force model's wrench in a tool snapshot (tool
    link frame, about the link COM; zero when no model ran)."""
    msg = WrenchStamped()
    msg.header.stamp = stamp(snapshot.time)
    msg.header.frame_id = snapshot.link
    if snapshot.model_wrench is not None:
        f, t = msg.wrench.force, msg.wrench.torque
        f.x, f.y, f.z = (float(v) for v in snapshot.model_wrench.force)
        t.x, t.y, t.z = (float(v) for v in snapshot.model_wrench.torque)
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
