"""Messages from the scene's arrays and arrays from messages (generated messages, no rospy)."""

from __future__ import annotations

import io
import struct
from typing import Any

import numpy as np
from geometry_msgs.msg import Point, TransformStamped
from visualization_msgs.msg import Marker

from ow_viz.errors import SceneError
from ow_viz.scene import FloatArray, TerrainMesh

#: RGBA of the planned tool path (orange) and of the ground point (magenta): apart from the URDF's
#: materials and the terrain palette.
PATH_RGBA = (1.0, 0.55, 0.0, 1.0)
GROUND_RGBA = (0.9, 0.1, 0.8, 1.0)
_U32 = struct.Struct("<I")


def _marker(kind: int, ns: str, frame: str, stamp: Any, marker: Marker | None = None) -> Marker:
    """``marker`` (default: a new Marker) with its header, namespace, type and pose set."""
    marker = Marker() if marker is None else marker
    marker.header.frame_id = frame
    marker.header.stamp = stamp
    marker.ns = ns
    marker.id = 0
    marker.type = kind
    marker.action = Marker.ADD
    marker.pose.orientation.w = 1.0
    return marker


class ArrayMarker(Marker):
    """A ``visualization_msgs/Marker`` whose points and colours are arrays, written to the wire
    as they are: :attr:`point_array` (N, 3) m as the ``points``, :attr:`color_array` (N, 4) as
    the ``colors``, while the message's own ``points`` and ``colors`` stay empty.

    Building 60 000 genpy ``Point`` and ``ColorRGBA`` objects and packing them one by one took
    about 65 ms per terrain (a tenth of the monitors' CPU in a mission); this writes the same
    bytes from the arrays (tested against genpy). A subscriber receives an ordinary Marker.
    """

    # No __slots__ of its own: genpy reads a message's fields from ``__slots__``.

    def __init__(self, *args: Any, **kwds: Any) -> None:
        super().__init__(*args, **kwds)
        self.point_array: FloatArray = np.zeros((0, 3))
        self.color_array: FloatArray = np.zeros((0, 4))

    def serialize(self, buff: Any) -> None:
        """Write the message as genpy would with the arrays as ``points`` and ``colors``."""
        if self.points or self.colors:
            msg = "an ArrayMarker carries its points and colours as arrays only"
            raise ValueError(msg)
        rest = io.BytesIO()
        super().serialize(rest)  # with both lists empty: two zero counts before the tail
        data = rest.getvalue()
        # The tail: text and mesh_resource (uint32 length + bytes each), then a uint8.
        tail = 4 + len(self.text.encode()) + 4 + len(self.mesh_resource.encode()) + 1
        head = data[: len(data) - tail - 8]
        points = np.ascontiguousarray(self.point_array, dtype="<f8")
        colors = np.ascontiguousarray(self.color_array, dtype="<f4")
        buff.write(head)
        buff.write(_U32.pack(len(points)))
        buff.write(points.tobytes())
        buff.write(_U32.pack(len(colors)))
        buff.write(colors.tobytes())
        buff.write(data[len(data) - tail :])


def terrain_marker(mesh: TerrainMesh, frame: str, stamp: Any) -> ArrayMarker:
    """A TRIANGLE_LIST marker (namespace ``terrain``) of ``mesh`` with per-vertex colours: every
    triangle's three corners in turn (an :class:`ArrayMarker`)."""
    marker = ArrayMarker()
    _marker(Marker.TRIANGLE_LIST, "terrain", frame, stamp, marker)
    marker.scale.x = marker.scale.y = marker.scale.z = 1.0
    marker.color.r = marker.color.g = marker.color.b = marker.color.a = 1.0
    order = mesh.triangles.ravel()
    marker.point_array = mesh.vertices[order]
    marker.color_array = mesh.colours[order]
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
