"""Messages from the scene's arrays and arrays from messages (generated messages, no rospy)."""

from __future__ import annotations

from typing import Any

import numpy as np
from geometry_msgs.msg import Point, TransformStamped
from std_msgs.msg import ColorRGBA
from visualization_msgs.msg import Marker

from ow_viz.errors import SceneError
from ow_viz.scene import FloatArray, TerrainMesh

#: RGBA of the planned tool path (orange) and of the ground point (magenta): apart from the URDF's
#: materials and the terrain palette.
PATH_RGBA = (1.0, 0.55, 0.0, 1.0)
GROUND_RGBA = (0.9, 0.1, 0.8, 1.0)


def _marker(kind: int, ns: str, frame: str, stamp: Any) -> Marker:
    marker = Marker()
    marker.header.frame_id = frame
    marker.header.stamp = stamp
    marker.ns = ns
    marker.id = 0
    marker.type = kind
    marker.action = Marker.ADD
    marker.pose.orientation.w = 1.0
    return marker


def terrain_marker(mesh: TerrainMesh, frame: str, stamp: Any) -> Marker:
    """A TRIANGLE_LIST marker (namespace ``terrain``) of ``mesh`` with per-vertex colours.

    Each distinct vertex becomes one ``Point`` and one ``ColorRGBA`` object, referenced by every
    triangle that uses it: a 101 x 101 map makes 10 201 of each instead of 60 000.
    """
    marker = _marker(Marker.TRIANGLE_LIST, "terrain", frame, stamp)
    marker.scale.x = marker.scale.y = marker.scale.z = 1.0
    marker.color.r = marker.color.g = marker.color.b = marker.color.a = 1.0
    points = [Point(x, y, z) for x, y, z in mesh.vertices.tolist()]
    colours = [ColorRGBA(r, g, b, a) for r, g, b, a in mesh.colours.tolist()]
    order = mesh.triangles.ravel().tolist()
    marker.points = [points[i] for i in order]
    marker.colors = [colours[i] for i in order]
    return marker


def path_marker(path: FloatArray, frame: str, stamp: Any, width_m: float) -> Marker:
    """A LINE_STRIP marker (namespace ``tool_path``) through ``path`` (K, 3) m."""
    marker = _marker(Marker.LINE_STRIP, "tool_path", frame, stamp)
    marker.scale.x = width_m
    marker.color.r, marker.color.g, marker.color.b, marker.color.a = PATH_RGBA
    marker.points = [Point(x, y, z) for x, y, z in np.asarray(path, dtype=float).tolist()]
    return marker


def ground_marker(position: Any, frame: str, stamp: Any, diameter_m: float) -> Marker:
    """A SPHERE marker (namespace ``ground``) at ``position`` (a geometry_msgs/Point, m)."""
    marker = _marker(Marker.SPHERE, "ground", frame, stamp)
    marker.pose.position.x = position.x
    marker.pose.position.y = position.y
    marker.pose.position.z = position.z
    marker.scale.x = marker.scale.y = marker.scale.z = diameter_m
    marker.color.r, marker.color.g, marker.color.b, marker.color.a = GROUND_RGBA
    return marker


def static_transform(
    parent: str, child: str, xyz: tuple[float, float, float], stamp: Any
) -> TransformStamped:
    """``child`` at ``xyz`` (m) in ``parent``, unrotated."""
    transform = TransformStamped()
    transform.header.frame_id = parent
    transform.header.stamp = stamp
    transform.child_frame_id = child
    transform.transform.translation.x, transform.transform.translation.y = xyz[0], xyz[1]
    transform.transform.translation.z = xyz[2]
    transform.transform.rotation.w = 1.0
    return transform


def trajectory_arrays(
    msg: Any,
) -> tuple[tuple[str, ...], FloatArray, FloatArray, FloatArray | None]:
    """Joint names, times (n,) s, positions (n, k) rad and velocities (n, k) rad/s or None of a
    ``trajectory_msgs/JointTrajectory``.

    Raises:
        SceneError: no points, or some points give velocities and others do not.
    """
    points = msg.points
    if not points:
        msg_text = "the trajectory has no points"
        raise SceneError(msg_text)
    times = np.array([p.time_from_start.to_sec() for p in points])
    positions = np.array([list(p.positions) for p in points], dtype=np.float64)
    given = [len(p.velocities) > 0 for p in points]
    if any(given) and not all(given):
        msg_text = "give velocities on every point of the trajectory or on none"
        raise SceneError(msg_text)
    velocities = np.array([list(p.velocities) for p in points]) if all(given) else None
    return tuple(msg.joint_names), times, positions, velocities
