"""One stereo capture, from a joint state to images and points: the renderer and the matcher put
together, free of ROS (the node publishes what this returns; the benchmark times it).
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from ow_cameras.config import CameraConfig
from ow_cameras.render import ByteImage, Lighting, SceneRenderer, expose
from ow_cameras.rig import PANEL_LINK, RigPose
from ow_cameras.stereo import StereoCloud, StereoMatcher
from ow_description.terrain import HeightMap

FloatArray = npt.NDArray[np.float64]

#: m, half the side of the flat ground drawn before a terrain is known.
FALLBACK_HALF_EXTENT_M = 6.0


@dataclass(frozen=True)
class Shot:
    """What a capture is of.

    Attributes:
        joint_positions: rad by joint name (the mast's pan and tilt place the cameras).
        stamp_ns: ns of sim time of that joint state: the capture's stamp (whole nanoseconds, as
            ROS stamps: the messages carry it exactly).
        terrain: the ground (None: flat at the configured fallback height).
        exposure_s: s.
        intensities: light name -> intensity, 0 to 1.
        left_fails: the left camera's trigger fails (OceanWATERS'
            ``camera_left_trigger_failure``): no left image, so no point cloud.
    """

    joint_positions: Mapping[str, float]
    stamp_ns: int
    terrain: HeightMap | None
    exposure_s: float
    intensities: Mapping[str, float]
    left_fails: bool = False


@dataclass(frozen=True)
class Capture:
    """A capture's results.

    Attributes:
        stamp_ns: ns of sim time (the shot's).
        left: (height, width, 3) RGB of the left camera, None when its trigger failed.
        right: (height, width, 3) RGB of the right camera.
        cloud: the matched pair, None without a left image.
        X_base_left: (4, 4) the left optical frame in base_link when the images were taken.
        timings_s: s of wall time per stage ("render", "stereo").
    """

    stamp_ns: int
    left: ByteImage | None
    right: ByteImage
    cloud: StereoCloud | None
    X_base_left: FloatArray
    timings_s: Mapping[str, float] = field(default_factory=dict)


class StereoCamera:
    """The mast's stereo pair: renders a shot and matches it.

    Use it from one thread (it owns a pybullet client); :meth:`close` releases it.

    Args:
        config: the camera node's configuration.
        renderer: the scene (default: a new :class:`SceneRenderer` of the lander URDF).
    """

    def __init__(self, config: CameraConfig, renderer: SceneRenderer | None = None) -> None:
        self.config = config
        self.renderer = SceneRenderer() if renderer is None else renderer
        self.matcher = StereoMatcher(config.stereo, config.pinhole)
        self._fallback = HeightMap.flat(config.fallback_ground_z, FALLBACK_HALF_EXTENT_M, 0.1)

    def close(self) -> None:
        """Release the renderer."""
        self.renderer.close()

    def lighting(self, intensities: Mapping[str, float]) -> Lighting:
        """The configured sun and sky with the lights at ``intensities``."""
        sun, lights = self.config.sun, self.config.lights
        return Lighting(
            sun_direction=sun.direction,
            sun_irradiance_w_m2=sun.irradiance_w_m2,
            ambient_w_m2=sun.ambient_w_m2,
            light_irradiance_at_1m_w_m2=lights.irradiance_at_1m_w_m2,
            cone_angle_rad=lights.cone_angle_rad,
            intensities=dict(intensities),
        )

    def capture(self, shot: Shot) -> Capture:
        """Render both cameras (only the right one when the left fails) and match them."""
        start = time.perf_counter()
        self.renderer.set_terrain(self._fallback if shot.terrain is None else shot.terrain)
        self.renderer.set_joints(shot.joint_positions)
        rig = RigPose.from_panel(self.renderer.X_base_link(PANEL_LINK))
        cameras = [rig.X_base_right] if shot.left_fails else [rig.X_base_left, rig.X_base_right]
        views = self.renderer.render(
            self.config.pinhole, cameras, self.lighting(shot.intensities), rig.lights
        )
        images = [expose(v.irradiance, shot.exposure_s, self.config.saturation_j_m2) for v in views]
        rendered = time.perf_counter()
        if shot.left_fails:
            return Capture(
                shot.stamp_ns, None, images[0], None, rig.X_base_left, {"render": rendered - start}
            )
        cloud = self.matcher.match(images[0], images[1])
        timings = {"render": rendered - start, "stereo": time.perf_counter() - rendered}
        return Capture(shot.stamp_ns, images[0], images[1], cloud, rig.X_base_left, timings)
