"""Configuration of the camera node: frozen dataclasses built by a pure ``from_dict()``.

The node reads its private namespace once (``rospy.get_param("~")``) and passes the dict here;
``config/camera.yaml`` holds the defaults below (:data:`CONFIG_FILE`). A missing key takes its
default; unknown keys, wrong types and values out of range are reported together in one
:class:`~ow_cameras.errors.ConfigError` naming each key (``camera/stereo/block_size``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ow_cameras.errors import ConfigError
from ow_cameras.rig import OCEANWATERS_HFOV_DEG, Pinhole
from ow_description.description import DEFAULT_GROUND_Z
from ow_runtime.params import Params

#: The camera node's parameter file (``src/ow_cameras/config/camera.yaml``), loaded whole as ``~``.
CONFIG_FILE = Path(__file__).resolve().parents[2] / "config" / "camera.yaml"

#: rad, OceanWATERS' spot lights' cone (inner = outer angle, edge to edge).
OCEANWATERS_CONE_RAD = 1.222


@dataclass(frozen=True)
class SunConfig:
    """The sun and the sky. The simulation has no sun of its own: this is the world's.

    Attributes:
        azimuth_deg: deg, direction of the sun in base_link's x-y plane, from +x towards +y.
        elevation_deg: deg, height of the sun above base_link's x-y plane (<= 0: night).
        irradiance_w_m2: W/m^2, the sun's irradiance on a surface facing it (Europa: 1361 / 5.2^2).
        ambient_w_m2: W/m^2, irradiance from every direction (sky, Jupiter shine), shadows too.
    """

    azimuth_deg: float = 150.0
    elevation_deg: float = 30.0
    irradiance_w_m2: float = 50.0
    ambient_w_m2: float = 1.0

    @property
    def direction(self) -> npt.NDArray[np.float64]:
        """(3,) unit vector towards the sun, in base_link."""
        az, el = math.radians(self.azimuth_deg), math.radians(self.elevation_deg)
        return np.array([math.cos(az) * math.cos(el), math.sin(az) * math.cos(el), math.sin(el)])


@dataclass(frozen=True)
class LightsConfig:
    """The two mast lights (OceanWATERS' spot lights ``lander_light0/1``).

    Attributes:
        left: initial intensity of the left light, 0 (off) to 1 (OceanWATERS: 1).
        right: initial intensity of the right light, 0 to 1 (OceanWATERS: 1).
        irradiance_at_1m_w_m2: W/m^2 at 1 m on a surface facing a light at intensity 1, falling
            with the square of the distance (OceanWATERS: quadratic attenuation 0.04 -> 25).
        cone_angle_rad: rad, the lit cone, edge to edge, hard-edged (OceanWATERS: 1.222).
        power_w: W drawn by one light at intensity 1, in proportion below (OceanWATERS: 4.8).
    """

    left: float = 1.0
    right: float = 1.0
    irradiance_at_1m_w_m2: float = 25.0
    cone_angle_rad: float = OCEANWATERS_CONE_RAD
    power_w: float = 4.8


@dataclass(frozen=True)
class StereoConfig:
    """OpenCV's semi-global block matcher (``cv2.StereoSGBM``, 3-way mode).

    Attributes:
        min_disparity: px, smallest disparity searched.
        num_disparities: px, disparities searched (a multiple of 16). With ``min_disparity`` 0
            the nearest range is ``fx * 0.2 / num_disparities`` m; the leftmost
            ``min_disparity + num_disparities`` columns of the left image have no match.
        block_size: px, odd side of the matched block.
        uniqueness_ratio: %, margin by which the best match must beat the second best.
        speckle_window: px, largest region of disparities differing from its surroundings that
            is removed as noise (0: off).
        speckle_range: px, disparity variation allowed within a connected region.
    """

    min_disparity: int = 0
    num_disparities: int = 336
    block_size: int = 5
    uniqueness_ratio: int = 10
    speckle_window: int = 100
    speckle_range: int = 2


@dataclass(frozen=True)
class CameraConfig:
    """Parameters of the camera node (private namespace ``~``).

    Attributes:
        width: px, image width (OceanWATERS: 1600; the default, 800, halves each side: see
            docs/cameras.md for the cost of each).
        height: px, image height (OceanWATERS: 1200).
        horizontal_fov_deg: deg, edge to edge (OceanWATERS: 21).
        exposure_s: s, initial exposure time (OceanWATERS: 0.001).
        saturation_j_m2: J/m^2, the albedo-weighted radiant exposure (irradiance times albedo
            times exposure time) at which a pixel reaches 255; pixels are linear below it.
        fallback_ground_z: m, flat ground (base_link z) drawn until ``/sim/terrain`` arrives.
        power_w: W drawn by the cameras while a capture runs (OceanWATERS: 0.1).
        actionlib_status_frequency: Hz of sim time, the action servers' periodic status (read
            by actionlib itself, actionlib's own key; every goal transition is also published
            when it happens).
        sun: the sun and the sky.
        lights: the mast lights.
        stereo: the matcher.
    """

    width: int = 800
    height: int = 600
    horizontal_fov_deg: float = OCEANWATERS_HFOV_DEG
    exposure_s: float = 0.001
    saturation_j_m2: float = 0.05
    fallback_ground_z: float = DEFAULT_GROUND_Z
    power_w: float = 0.1
    actionlib_status_frequency: float = 5.0
    sun: SunConfig = field(default_factory=SunConfig)
    lights: LightsConfig = field(default_factory=LightsConfig)
    stereo: StereoConfig = field(default_factory=StereoConfig)

    @property
    def pinhole(self) -> Pinhole:
        """The cameras' projection."""
        return Pinhole(self.width, self.height, math.radians(self.horizontal_fov_deg))

    @classmethod
    def from_dict(cls, params: Mapping[str, Any]) -> CameraConfig:
        """Validate a parameter dict (missing keys take their defaults).

        Args:
            params: the node's private namespace (the content of :data:`CONFIG_FILE`).

        Raises:
            ConfigError: unknown keys, wrong types or values out of range; the message names
                each key.
        """
        p = Params(params, "camera", ConfigError)
        d = cls()
        width = p.integer("width", d.width, low=64, high=4096)
        height = p.integer("height", d.height, low=48, high=4096)
        config = cls(
            width=width,
            height=height,
            horizontal_fov_deg=p.number(
                "horizontal_fov_deg",
                d.horizontal_fov_deg,
                low=1.0,
                high=120.0,
                unit="deg",
            ),
            exposure_s=p.positive("exposure_s", d.exposure_s, "s"),
            saturation_j_m2=p.positive("saturation_j_m2", d.saturation_j_m2, "J/m^2"),
            fallback_ground_z=p.number("fallback_ground_z", d.fallback_ground_z, unit="m"),
            power_w=p.non_negative("power_w", d.power_w, "W"),
            actionlib_status_frequency=p.positive(
                "actionlib_status_frequency", d.actionlib_status_frequency, "Hz"
            ),
            sun=_sun(p.section("sun")),
            lights=_lights(p.section("lights")),
            stereo=_stereo(p.section("stereo"), width),
        )
        p.finish()
        return config


def _sun(p: Params) -> SunConfig:
    d = SunConfig()
    return SunConfig(
        azimuth_deg=p.number("azimuth_deg", d.azimuth_deg, low=-360.0, high=360.0, unit="deg"),
        elevation_deg=p.number("elevation_deg", d.elevation_deg, low=-90.0, high=90.0, unit="deg"),
        irradiance_w_m2=p.non_negative("irradiance_w_m2", d.irradiance_w_m2, "W/m^2"),
        ambient_w_m2=p.non_negative("ambient_w_m2", d.ambient_w_m2, "W/m^2"),
    )


def _lights(p: Params) -> LightsConfig:
    d = LightsConfig()
    return LightsConfig(
        left=p.number("left", d.left, low=0.0, high=1.0),
        right=p.number("right", d.right, low=0.0, high=1.0),
        irradiance_at_1m_w_m2=p.non_negative(
            "irradiance_at_1m_w_m2", d.irradiance_at_1m_w_m2, "W/m^2"
        ),
        cone_angle_rad=p.number(
            "cone_angle_rad",
            d.cone_angle_rad,
            low=0.0,
            high=math.pi,
            low_inclusive=False,
            unit="rad",
        ),
        power_w=p.non_negative("power_w", d.power_w, "W"),
    )


def _stereo(p: Params, width: int) -> StereoConfig:
    d = StereoConfig()
    config = StereoConfig(
        min_disparity=p.integer("min_disparity", d.min_disparity, low=0),
        num_disparities=p.integer("num_disparities", d.num_disparities, low=16),
        block_size=p.integer("block_size", d.block_size, low=1, high=31),
        uniqueness_ratio=p.integer("uniqueness_ratio", d.uniqueness_ratio, low=0, high=100),
        speckle_window=p.integer("speckle_window", d.speckle_window, low=0),
        speckle_range=p.integer("speckle_range", d.speckle_range, low=0),
    )
    if config.num_disparities % 16:
        p.problem(
            f"{p.name('num_disparities')} = {config.num_disparities} must be a multiple of 16"
        )
    if config.block_size % 2 == 0:
        p.problem(f"{p.name('block_size')} = {config.block_size} must be odd")
    if config.min_disparity + config.num_disparities >= width:
        p.problem(
            f"{p.name('min_disparity')} + {p.name('num_disparities')} = "
            f"{config.min_disparity + config.num_disparities} px leaves no column of the "
            f"{width} px wide image to match"
        )
    return config
