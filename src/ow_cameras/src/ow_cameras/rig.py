"""Where OceanWATERS' stereo cameras and mast lights sit and how they project, free of ROS.

Every figure is OceanWATERS' (``ow_lander/urdf/lander.xacro``, ``stereo_camera_triggered.xacro``,
``lander_lights.xacro``; spec section 13): the camera head is fixed to ``l_ant_panel`` at
(0.53811, 0.07, 0) m, rpy (pi/2, pi, pi/2); the left and right cameras sit 0.1 m either side of
it along the head's y (baseline 0.2 m), each with an optical frame of rpy (-pi/2, 0, -pi/2)
(REP 103: z forward, x right, y down). The lights' bracket is fixed to ``l_ant_panel`` at
(0.85, 0.08, 0) m, rpy (-pi/2, 0, 0), the "left" light 0.33 m along the bracket's +y, the
"right" one 0.33 m along -y, both shining along the bracket's -z. So everything moves with pan and
tilt; at pan = tilt = 0 the head is at (0, 0.65, 1.461) m in base_link, looking along -y, and
the lights are at (+-0.33, 0.66, 1.773) m.

Transforms are named ``X_<from>_<to>``: 4x4 homogeneous matrices mapping coordinates in frame
``<to>`` to frame ``<from>`` (``X_base_optical @ p_optical = p_base``), as in
:mod:`ow_description.model`.

:class:`Mast` is the mast's own two joints, read from the lander URDF: where the panel is for a
pan and tilt, and the pan and tilt that look at a point, for clients that must not load a
dynamics library for two joints (the mission aims the cameras with it).
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt

from ow_cameras.errors import RigError
from ow_description.description import ANTENNA_JOINTS, BASE_FRAME, URDF_PATH, wrap_angle

FloatArray = npt.NDArray[np.float64]

#: The link the camera head and the lights' bracket are fixed to.
PANEL_LINK = "l_ant_panel"
#: OceanWATERS' frame names (TF children of :data:`PANEL_LINK`).
HEAD_FRAME = "StereoCamera_head_link"
LEFT_LINK = "StereoCameraLeft_link"
LEFT_OPTICAL_FRAME = "StereoCameraLeft_optical_frame"
RIGHT_LINK = "StereoCameraRight_link"
RIGHT_OPTICAL_FRAME = "StereoCameraRight_optical_frame"
CENTER_LINK = "StereoCameraCenter_link"
LIGHTS_LINK = "lander_lights_link"
#: The lights by their LightSetIntensity names ("left" is lander_light0, at +x of base_link when
#: pan = 0: on the cameras' left).
LIGHT_LINKS = {"left": "lander_light0", "right": "lander_light1"}

#: m, distance between the two cameras' centres (OceanWATERS' ``camera_baseline``).
BASELINE_M = 0.2
#: deg, horizontal field of view of each camera (OceanWATERS: 21).
OCEANWATERS_HFOV_DEG = 21.0


def rpy_matrix(roll: float, pitch: float, yaw: float) -> FloatArray:
    """(3, 3) rotation of URDF's rpy (fixed axes: roll about x, then pitch about y, then yaw
    about z)."""
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    Rx = np.array([[1.0, 0.0, 0.0], [0.0, cr, -sr], [0.0, sr, cr]])
    Ry = np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])
    Rz = np.array([[cy, -sy, 0.0], [sy, cy, 0.0], [0.0, 0.0, 1.0]])
    return Rz @ Ry @ Rx


def transform(xyz: tuple[float, float, float], rpy: tuple[float, float, float]) -> FloatArray:
    """(4, 4) transform of a URDF ``<origin xyz rpy>`` (m, rad)."""
    X = np.eye(4)
    X[:3, :3] = rpy_matrix(*rpy)
    X[:3, 3] = xyz
    return X


_HALF_PI = math.pi / 2
_OPTICAL = ((0.0, 0.0, 0.0), (-_HALF_PI, 0.0, -_HALF_PI))

#: (parent, child, X_parent_child) of every fixed frame of the rig, parents first.
FIXED_FRAMES: tuple[tuple[str, str, FloatArray], ...] = (
    (PANEL_LINK, HEAD_FRAME, transform((0.53811, 0.07, 0.0), (_HALF_PI, math.pi, _HALF_PI))),
    (HEAD_FRAME, LEFT_LINK, transform((0.0, BASELINE_M / 2, 0.0), (0.0, 0.0, 0.0))),
    (LEFT_LINK, LEFT_OPTICAL_FRAME, transform(*_OPTICAL)),
    (HEAD_FRAME, RIGHT_LINK, transform((0.0, -BASELINE_M / 2, 0.0), (0.0, 0.0, 0.0))),
    (RIGHT_LINK, RIGHT_OPTICAL_FRAME, transform(*_OPTICAL)),
    (HEAD_FRAME, CENTER_LINK, transform((0.0, 0.0, 0.0), (0.0, 0.0, 0.0))),
    (PANEL_LINK, LIGHTS_LINK, transform((0.85, 0.08, 0.0), (-_HALF_PI, 0.0, 0.0))),
    (LIGHTS_LINK, LIGHT_LINKS["left"], transform((0.0, 0.33, 0.0), (0.0, 0.0, 0.0))),
    (LIGHTS_LINK, LIGHT_LINKS["right"], transform((0.0, -0.33, 0.0), (0.0, 0.0, 0.0))),
)
#: Unit vector, the direction a light shines in its own frame (OceanWATERS' ``<direction>``).
LIGHT_AXIS = np.array([0.0, 0.0, -1.0])


def X_panel(frame: str) -> FloatArray:
    """(4, 4) transform from ``frame`` (one of :data:`FIXED_FRAMES`' children) to
    :data:`PANEL_LINK`.

    Raises:
        KeyError: ``frame`` is not a frame of the rig.
    """
    parents = {child: (parent, X) for parent, child, X in FIXED_FRAMES}
    if frame not in parents:
        msg = f"{frame!r} is not a frame of the camera rig; known: {', '.join(parents)}"
        raise KeyError(msg)
    X = np.eye(4)
    while frame != PANEL_LINK:
        frame, X_parent = parents[frame]
        X = X_parent @ X
    return X


@dataclass(frozen=True)
class Pinhole:
    """An ideal, distortion-free pinhole camera with square pixels and its principal point at
    the image centre (pixel centres at integer coordinates, so ``cx = (width - 1) / 2``).

    Attributes:
        width: px.
        height: px.
        hfov_rad: rad, horizontal field of view (edge to edge).
    """

    width: int
    height: int
    hfov_rad: float

    @property
    def focal_px(self) -> float:
        """px, fx = fy."""
        return self.width / 2 / math.tan(self.hfov_rad / 2)

    @property
    def vfov_rad(self) -> float:
        """rad, vertical field of view (edge to edge)."""
        return 2 * math.atan(self.height / 2 / self.focal_px)

    @property
    def cx(self) -> float:
        """px, principal point x."""
        return (self.width - 1) / 2

    @property
    def cy(self) -> float:
        """px, principal point y."""
        return (self.height - 1) / 2

    @property
    def K(self) -> FloatArray:
        """(3, 3) intrinsic matrix."""
        f = self.focal_px
        return np.array([[f, 0.0, self.cx], [0.0, f, self.cy], [0.0, 0.0, 1.0]])

    def P(self, tx_px_m: float = 0.0) -> FloatArray:
        """(3, 4) projection matrix of ROS's CameraInfo, ``P[0, 3] = tx_px_m`` (px m; the right
        camera of a rectified pair has ``-fx * baseline``)."""
        P = np.zeros((3, 4))
        P[:, :3] = self.K
        P[0, 3] = tx_px_m
        return P

    def rays(self) -> tuple[FloatArray, FloatArray]:
        """((height, width), (height, width)): x/z and y/z of each pixel's ray in the optical
        frame."""
        u = (np.arange(self.width, dtype=np.float64) - self.cx) / self.focal_px
        v = (np.arange(self.height, dtype=np.float64) - self.cy) / self.focal_px
        return np.broadcast_to(u, (self.height, self.width)), np.broadcast_to(
            v[:, None], (self.height, self.width)
        )


@dataclass(frozen=True)
class Spotlight:
    """One mast light as it shines now.

    Attributes:
        name: "left" or "right".
        position: (3,) m, in base_link.
        axis: (3,) unit vector, the direction it shines, in base_link.
    """

    name: str
    position: FloatArray
    axis: FloatArray


@dataclass(frozen=True)
class RigPose:
    """The cameras and lights for one pose of the panel.

    Attributes:
        X_base_left: (4, 4) the left camera's optical frame in base_link.
        X_base_right: (4, 4) the right camera's optical frame in base_link.
        lights: the two lights, left first.
    """

    X_base_left: FloatArray
    X_base_right: FloatArray
    lights: tuple[Spotlight, Spotlight]

    @classmethod
    def from_panel(cls, X_base_panel: FloatArray) -> RigPose:
        """The rig on ``l_ant_panel`` at ``X_base_panel`` ((4, 4), base_link)."""
        lights = []
        for name in ("left", "right"):
            X = X_base_panel @ X_panel(LIGHT_LINKS[name])
            lights.append(Spotlight(name, X[:3, 3].copy(), X[:3, :3] @ LIGHT_AXIS))
        return cls(
            X_base_panel @ X_panel(LEFT_OPTICAL_FRAME),
            X_base_panel @ X_panel(RIGHT_OPTICAL_FRAME),
            (lights[0], lights[1]),
        )


def _axis_rotation(axis: FloatArray, angle: float) -> FloatArray:
    """(3, 3) rotation by ``angle`` rad about the unit vector ``axis`` (Rodrigues)."""
    K = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    return np.eye(3) + math.sin(angle) * K + (1.0 - math.cos(angle)) * (K @ K)


def _floats(element: ET.Element | None, attribute: str, default: str) -> tuple[float, ...]:
    text = default if element is None else element.get(attribute, default)
    return tuple(float(v) for v in text.split())


@dataclass(frozen=True)
class MastJoint:
    """One revolute joint of the mast as the URDF has it.

    Attributes:
        name: the joint's name.
        parent: its parent link.
        child: its child link.
        X_parent_joint: (4, 4) the joint frame at angle 0 in the parent link (``<origin>``).
        axis: (3,) unit vector, the rotation axis in the joint frame (``<axis>``).
    """

    name: str
    parent: str
    child: str
    X_parent_joint: FloatArray
    axis: FloatArray

    def X_parent_child(self, angle: float) -> FloatArray:
        """(4, 4) the child link in the parent link at ``angle`` rad."""
        X = self.X_parent_joint.copy()
        X[:3, :3] = X[:3, :3] @ _axis_rotation(self.axis, angle)
        return X


@dataclass(frozen=True)
class Mast:
    """The antenna mast: ``base_link`` -> ``j_ant_pan`` -> ``j_ant_tilt`` -> ``l_ant_panel``,
    with the camera head on the panel (:data:`FIXED_FRAMES`).

    Attributes:
        pan: the pan joint (parent ``base_link``).
        tilt: the tilt joint (parent: the pan joint's child).
    """

    pan: MastJoint
    tilt: MastJoint

    @classmethod
    def from_urdf(cls, urdf: Path | str = URDF_PATH) -> Mast:
        """The mast of the URDF at ``urdf`` (default: the lander's).

        Raises:
            RigError: the file cannot be read, lacks a mast joint, or the joints do not chain
                from ``base_link`` to :data:`PANEL_LINK`.
        """
        try:
            root = ET.parse(urdf).getroot()
        except (OSError, ET.ParseError) as error:
            msg = f"cannot read the mast's joints from {urdf}: {error}"
            raise RigError(msg) from error
        joints = []
        for name in ANTENNA_JOINTS:
            element = root.find(f"joint[@name='{name}']")
            parent = None if element is None else element.find("parent")
            child = None if element is None else element.find("child")
            if element is None or parent is None or child is None:
                msg = f"{urdf} has no joint {name!r} with a parent and a child link"
                raise RigError(msg)
            origin = element.find("origin")
            xyz = _floats(origin, "xyz", "0 0 0")
            rpy = _floats(origin, "rpy", "0 0 0")
            axis = np.array(_floats(element.find("axis"), "xyz", "1 0 0"))
            joints.append(
                MastJoint(
                    name,
                    parent.get("link", ""),
                    child.get("link", ""),
                    transform((xyz[0], xyz[1], xyz[2]), (rpy[0], rpy[1], rpy[2])),
                    axis / np.linalg.norm(axis),
                )
            )
        pan, tilt = joints
        if pan.parent != BASE_FRAME or tilt.parent != pan.child or tilt.child != PANEL_LINK:
            msg = (
                f"{urdf}: the mast's joints link {pan.parent} -> {pan.child} and {tilt.parent} -> "
                f"{tilt.child}, not {BASE_FRAME} -> ... -> {PANEL_LINK}"
            )
            raise RigError(msg)
        return cls(pan, tilt)

    def X_base_panel(self, pan: float, tilt: float) -> FloatArray:
        """(4, 4) :data:`PANEL_LINK` in base_link at ``pan`` and ``tilt`` rad."""
        return self.pan.X_parent_child(pan) @ self.tilt.X_parent_child(tilt)

    def look_at(self, point: FloatArray) -> tuple[float, float]:
        """Pan and tilt (rad) that put ``point`` ((3,) m, base_link) on the camera head's axis.

        OceanWATERS' PanTiltMoveCartesian solution: pan = atan2(dy, dx) + pi/2 about the tilt
        joint, and the tilt that puts the line of sight, perpendicular to the head's lever of
        0.538 m across the tilt axis, through the point. Exact for this mast, whose pan axis is
        vertical through the tilt axis and whose head lies in the plane of both, up to the URDF's
        rounding of pi (the axis passes within 1e-4 m per m of the point).

        Returns:
            (pan, tilt) rad, pan in [-pi, pi).

        Raises:
            RigError: the point is within the lever of the tilt axis (no tilt looks at it).
        """
        p = np.asarray(point, dtype=np.float64)
        d = p - self.X_base_panel(0.0, 0.0)[:3, 3]
        horizontal, vertical = math.hypot(d[0], d[1]), float(d[2])
        distance = math.hypot(horizontal, vertical)
        lever = float(X_panel(CENTER_LINK)[0, 3])
        if distance <= lever:
            msg = (
                f"point ({p[0]:.3f}, {p[1]:.3f}, {p[2]:.3f}) m is {distance:.3f} m from the tilt "
                f"axis, within the camera head's lever of {lever:.3f} m: no tilt looks at it"
            )
            raise RigError(msg)
        pan = float(wrap_angle(math.atan2(d[1], d[0]) + math.pi / 2))
        tilt = math.asin(lever / distance) - math.atan2(vertical, horizontal)
        return pan, tilt
