"""What planning an operation produces, and how it is timed. No ROS."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from ow_description.description import ARM_JOINTS
from ow_description.trajectory import PathSegment, Trajectory, time_parameterize
from ow_lander.config import TimingConfig
from ow_lander.errors import PlanningError

FloatArray = npt.NDArray[np.float64]


@dataclass
class OperationPlan:
    """A planned operation.

    Attributes:
        operation: service name, e.g. ``grind``.
        segments: labelled joint paths of the arm joints (ARM_JOINTS order), in order, each with
            its speed class.
        parameters: the effective request (after defaults), for /arm/operation and the docs.
        notes: remarks for the response message.
    """

    operation: str
    segments: list[PathSegment]
    parameters: dict[str, Any]
    notes: list[str] = field(default_factory=list)

    @property
    def end(self) -> FloatArray:
        """(6,) rad, the arm configuration at the end of the plan."""
        return np.asarray(self.segments[-1].waypoints[-1])

    def timed(self, timing: TimingConfig, velocity_limits: FloatArray) -> Trajectory:
        """The plan as a trajectory of the arm joints, each segment at its speed class's scale.

        Args:
            timing: the velocity scales, acceleration limits and row period.
            velocity_limits: (6,) rad/s, the arm joints' URDF velocity limits.

        Raises:
            TrajectoryError: a segment's waypoints do not have six columns.
        """
        return time_parameterize(
            self.segments,
            ARM_JOINTS,
            velocity_limits,
            np.array([timing.acceleration_limits[j] for j in ARM_JOINTS]),
            timing.sample_period_s,
            self.operation,
            timing.speed_scales,
        )


def check_finite(values: Mapping[str, Any], *names: str) -> None:
    """Raise when one of ``names`` of a request is not a finite number.

    Raises:
        PlanningError: naming the first such value.
    """
    for name in names:
        value = float(values[name])
        if not math.isfinite(value):
            msg = f"{name}={value} is not a finite number"
            raise PlanningError(msg)
