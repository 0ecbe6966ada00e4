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
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

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
