"""Records of the joints: their state at one instant, and a set-point command that was clipped."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class JointSample:
    """The joints at one instant, with the torques applied over the following step.

    Attributes:
        time: s of sim time.
        names: joint names (the controller's order).
        position: (9,) rad.
        velocity: (9,) rad/s.
        effort: (9,) N m, the controller's (motor) torque.
        damping_effort: (9,) N m, the passive joint-damping torque; its power -damping * v is
            dissipated.
        setpoint: (9,) rad, the controllers' set-points.
    """

    time: float
    names: tuple[str, ...]
    position: FloatArray
    velocity: FloatArray
    effort: FloatArray
    damping_effort: FloatArray
    setpoint: FloatArray


@dataclass(frozen=True)
class ClippedSetpoint:
    """A set-point beyond a joint's URDF limits that was moved onto the limit (never one of a
    continuous joint: it has no limits, see :class:`~ow_sim_bullet.joint_control.JointController`).

    Attributes:
        joint: joint name.
        requested: rad, the set-point asked for (the most extreme one of a trajectory).
        applied: rad, the limit it was clipped to.
        lower: rad, the joint's lower limit.
        upper: rad, the joint's upper limit.
    """

    joint: str
    requested: float
    applied: float
    lower: float
    upper: float

    def describe(self) -> str:
        """The clipping in words, for a warning."""
        return (
            f"set-point {self.requested:.6g} rad for {self.joint} is beyond its limits "
            f"[{self.lower:.4g}, {self.upper:.4g}] rad; clipped to {self.applied:.4g} rad"
        )
