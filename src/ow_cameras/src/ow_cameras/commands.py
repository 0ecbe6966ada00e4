"""OceanWATERS' camera and light actions as decisions on their goals: what each goal changes and
the status text it ends with (``ow_lander/src/ow_lander/actions.py`` at HEAD; spec section
13.4). No ROS; :mod:`ow_cameras.camera_node` serves them.

HEAD's texts are kept word for word; where HEAD would accept a value it cannot use (a NaN or an
infinite exposure, a NaN intensity), the goal is refused here, and a refusal's text adds, after
HEAD's sentence, what the field accepts.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

from ow_cameras.config import CameraConfig
from ow_cameras.errors import GoalError

#: The lights' names in LightSetIntensity goals (matched lower-cased).
LIGHT_NAMES = ("left", "right")

#: Status texts of CameraCapture (HEAD's).
CAPTURE_SUCCEEDED = "Point cloud received"
CAPTURE_TIMED_OUT = "Timed out waiting for point cloud"
PREEMPTED = "Action was preempted"
#: CameraSetExposure's refusal of ``automatic`` (HEAD's).
NO_AUTOEXPOSURE = "CameraSetExposure action does not support autoexposure."


def exposure_change(automatic: bool, exposure: float) -> float | None:
    """The exposure a CameraSetExposure goal sets.

    Args:
        automatic: the goal's ``automatic``.
        exposure: s, the goal's ``exposure``.

    Returns:
        s, the new exposure; None: unchanged (``exposure`` <= 0, as HEAD).

    Raises:
        GoalError: ``automatic`` is true, or ``exposure`` is not a finite number.
    """
    if automatic:
        raise GoalError(NO_AUTOEXPOSURE)
    if not math.isfinite(exposure):
        msg = f"exposure = {exposure} s is not a finite number (> 0 sets it, <= 0 keeps it)."
        raise GoalError(msg)
    return exposure if exposure > 0.0 else None


def exposure_text(exposure: float | None) -> str:
    """The SUCCEEDED text of a CameraSetExposure goal that set ``exposure`` s (None: kept)."""
    return "Exposure not changed" if exposure is None else f"Exposure set to {exposure}"


def light_change(name: str, intensity: float) -> tuple[str, float]:
    """The light and intensity a LightSetIntensity goal sets (range first, then name, as HEAD).

    Args:
        name: the goal's ``name``, any case.
        intensity: the goal's ``intensity``, 0 to 1.

    Returns:
        (lower-cased name, intensity).

    Raises:
        GoalError: the intensity is outside [0, 1] or NaN, or the name is not a light's.
    """
    if not 0.0 <= intensity <= 1.0:
        msg = f"Intensity = {intensity} is out of range. intensity must be within [0, 1]."
        raise GoalError(msg)
    light = name.lower()
    if light not in LIGHT_NAMES:
        msg = f"'{light}' is not a light identifier. name must be 'left' or 'right'."
        raise GoalError(msg)
    return light, intensity


def light_text(name: str) -> str:
    """The SUCCEEDED text of a LightSetIntensity goal for light ``name`` (lower case)."""
    return f"{name} light intensity set successfully."


def electrical_power_w(
    config: CameraConfig, intensities: Mapping[str, float], capturing: bool
) -> float:
    """W the cameras and lights draw: each light ``power_w`` times its intensity, always (HEAD's
    power node: 4.8 W x (left + right)), and the cameras' ``power_w`` while a capture runs."""
    lights = config.lights.power_w * sum(intensities.get(n, 0.0) for n in LIGHT_NAMES)
    return lights + (config.power_w if capturing else 0.0)
