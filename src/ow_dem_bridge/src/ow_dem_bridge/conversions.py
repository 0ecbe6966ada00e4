"""Messages <-> library types: ``ow_msgs/ToolState`` -> :class:`ToolState`, :class:`Wrench` ->
``geometry_msgs/WrenchStamped``. No rospy here (generated message classes only)."""

from __future__ import annotations

from typing import Any

import numpy as np
import pinocchio as pin

from ow_dem_bridge.api import FloatArray, ToolState, Wrench


def tool_state_from_msg(msg: Any, tip_offset: FloatArray) -> ToolState:
    """The library's tool state from an ``ow_msgs/ToolState``.

    The message carries the link pose and the link-origin twist in ``base_link``; the library wants
    the tip velocity and the angular velocity in the link frame.

    Args:
        msg: ``ow_msgs/ToolState``.
        tip_offset: (3,) m, the tool tip in the link frame (e.g. (0.1, 0, 0.08) for l_scoop).
    """
    o = msg.pose.orientation
    # Normalised first; an all-zero (unset) orientation reads as the identity.
    R_base_link = np.asarray(pin.Quaternion(o.w, o.x, o.y, o.z).normalized().matrix())
    v = msg.twist.linear
    w = msg.twist.angular
    omega_base = np.array([w.x, w.y, w.z])
    v_tip_base = np.array([v.x, v.y, v.z]) + np.cross(omega_base, R_base_link @ tip_offset)
    return ToolState(
        tool=msg.tool,
        material=int(msg.material),
        depth=float(msg.depth),
        progress=float(msg.progress),
        velocity=R_base_link.T @ v_tip_base,
        angular_velocity=R_base_link.T @ omega_base,
    )


def wrench_to_msg(wrench: Wrench, stamp: Any, frame_id: str) -> Any:
    """A ``geometry_msgs/WrenchStamped`` in the tool link frame (about the link COM)."""
    from geometry_msgs.msg import WrenchStamped

    msg = WrenchStamped()
    msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    f, t = wrench.force, wrench.torque
    msg.wrench.force.x, msg.wrench.force.y, msg.wrench.force.z = (float(v) for v in f)
    msg.wrench.torque.x, msg.wrench.torque.y, msg.wrench.torque.z = (float(v) for v in t)
    return msg


def wrench_from_msg(msg: Any) -> Wrench:
    """The library's wrench from a ``geometry_msgs/WrenchStamped`` (frame not checked)."""
    f, t = msg.wrench.force, msg.wrench.torque
    return Wrench(np.array([f.x, f.y, f.z]), np.array([t.x, t.y, t.z]))
