"""The antenna mast's pan and tilt, as OceanWATERS' PanTiltMoveJoints and PanTiltMoveCartesian
actions use them: goal checks, the look-at solution and the arrival test; and as its single-joint
Pan and Tilt actions (ow_lander) use them: their goal check and settle rule. No ROS.

The mast's pointing axis is OceanWATERS' stereo camera's: our URDF has no camera links, so the
camera mount of OceanWATERS' URDF (spec section 1.5: on ``l_ant_panel`` at (0.53811, 0.07, 0) m,
rpy (pi/2, pi, pi/2), looking along its +x) is written here as :data:`CAMERA_ORIGIN_PANEL` and
:data:`CAMERA_AXIS_PANEL`. At pan = tilt = 0 the camera sits 0.538 m above the tilt axis and looks
along -y of base_link; pan turns it about +z, a positive tilt turns it down.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ow_description.description import ANTENNA_JOINTS, SCOOP_TIP_FRAME
from ow_description.model import LanderModel
from ow_lander.errors import GoalError

FloatArray = npt.NDArray[np.float64]

#: rad, |pan| and |tilt| a goal may ask for (OceanWATERS' PanTiltMoveJoints limits).
PAN_LIMIT_RAD = 3.2
TILT_LIMIT_RAD = 1.56
#: rad, how close to its goal each joint must come for the action to succeed.
TOLERANCE_RAD = 0.05
#: The ``frame`` values of a PanTiltMoveCartesian goal: base_link, and the tool (l_scoop_tip).
FRAME_BASE = 0
FRAME_TOOL = 1
FRAMES = {FRAME_BASE: "base_link", FRAME_TOOL: SCOOP_TIP_FRAME}
#: m, the camera's origin (between the two cameras) in l_ant_panel.
CAMERA_ORIGIN_PANEL = np.array([0.53811, 0.07, 0.0])
#: Unit vector, the camera's viewing direction in l_ant_panel (its link's +x).
CAMERA_AXIS_PANEL = np.array([0.0, -1.0, 0.0])
#: m, the look-at solution's largest distance between the point and the pointing axis.
LOOK_AT_TOLERANCE_M = 1e-9

_PANEL = "l_ant_panel"


def _finite(field: str, value: float) -> float:
    value = float(value)
    if not math.isfinite(value):
        msg = f"{field} = {value} is not a finite number"
        raise GoalError(msg)
    return value


def _within(field: str, value: float, limit: float) -> float:
    value = _finite(field, value)
    if abs(value) > limit:
        msg = f"{field} = {value:.4g} rad is outside the limits [-{limit}, {limit}] rad"
        raise GoalError(msg)
    return value


def check_joints_goal(pan: float, tilt: float) -> tuple[float, float]:
    """A PanTiltMoveJoints goal, checked.

    Args:
        pan: rad, target of j_ant_pan.
        tilt: rad, target of j_ant_tilt.

    Returns:
        (pan, tilt) rad.

    Raises:
        GoalError: a value is not finite or beyond :data:`PAN_LIMIT_RAD` /
            :data:`TILT_LIMIT_RAD` (the message names the field, its value and the limit).
    """
    return _within("pan", pan, PAN_LIMIT_RAD), _within("tilt", tilt, TILT_LIMIT_RAD)


def reached(pan: float, tilt: float, goal: tuple[float, float]) -> bool:
    """True when both joints (rad) are within :data:`TOLERANCE_RAD` of ``goal`` (pan, tilt)."""
    return abs(pan - goal[0]) <= TOLERANCE_RAD and abs(tilt - goal[1]) <= TOLERANCE_RAD


@dataclass(frozen=True)
class MoveEnd:
    """How a pan/tilt move ends.

    Attributes:
        outcome: "succeeded", "aborted" or "preempted".
        text: the goal's status text.
        hold: command the mast to hold where it is (not at the goal).
    """

    outcome: str
    text: str
    hold: bool


class MoveWatch:
    """Watches one pan/tilt move on every joint state, in order, by the states' stamps (s, sim):
    a fault, a cancel, arrival within :data:`TOLERANCE_RAD`, then the timeout; feedback every
    ``feedback_period_s`` of stamps. The same joint states give the same decisions whatever the
    machine's load.

    Args:
        goal: rad, (pan, tilt).
        timeout_s: s of stamps from the first joint state after which the move is aborted.
        feedback_period_s: s of stamps between feedback messages.
    """

    def __init__(
        self, goal: tuple[float, float], timeout_s: float, feedback_period_s: float
    ) -> None:
        self.goal = goal
        self.timeout_s = timeout_s
        self.feedback_period_s = feedback_period_s
        self._deadline: float | None = None
        self._next_feedback = -math.inf

    def feedback_due(self, stamp: float) -> bool:
        """Whether feedback is due at this joint state (then the next is one period later)."""
        if stamp < self._next_feedback:
            return False
        self._next_feedback = stamp + self.feedback_period_s - 1e-9
        return True

    def end(
        self, stamp: float, pan: float, tilt: float, fault: str | None, preempted: bool
    ) -> MoveEnd | None:
        """The move's end at the joint state ``stamp`` (pan, tilt rad), or None while it goes
        on. ``fault``: a pan/tilt execution error standing; ``preempted``: a cancel came."""
        if self._deadline is None:
            self._deadline = stamp + self.timeout_s
        where = f"stopped at pan {pan:.3f}, tilt {tilt:.3f} rad"
        if fault is not None:
            return MoveEnd("aborted", f"{fault}: {where}", hold=True)
        if preempted:
            return MoveEnd("preempted", where, hold=True)
        if reached(pan, tilt, self.goal):
            text = f"reached pan {pan:.3f}, tilt {tilt:.3f} rad"
            return MoveEnd(
                "succeeded", f"{text} (goal {self.goal[0]:.3f}, {self.goal[1]:.3f})", hold=False
            )
        if stamp > self._deadline:
            text = (
                f"pan/tilt did not reach ({self.goal[0]:.3f}, {self.goal[1]:.3f}) rad within "
                f"{self.timeout_s:.0f} s: {where}"
            )
            return MoveEnd("aborted", text, hold=True)
        return None


@dataclass(frozen=True)
class SingleJoint:
    """One of OceanWATERS' single-joint mast actions (ow_lander's Pan and Tilt).

    Attributes:
        action: the action's name ("Pan").
        field: its goal's field ("pan"); the result and feedback field is ``<field>_position``.
        index: the joint's index in ``ANTENNA_JOINTS`` and in (pan, tilt) pairs.
        limit_rad: rad, the goal's limit: it must lie in [-limit, limit].
    """

    action: str
    field: str
    index: int
    limit_rad: float

    def check_goal(self, value: float) -> float:
        """The goal's angle (rad), checked as OceanWATERS checks it (NaN fails too).

        Raises:
            GoalError: outside [-limit, limit], with OceanWATERS' text ("Requested pan 4.0 is
                not within allowed limits.").
        """
        value = float(value)
        if not -self.limit_rad <= value <= self.limit_rad:
            msg = f"Requested {self.field} {value} is not within allowed limits."
            raise GoalError(msg)
        return value


PAN = SingleJoint("Pan", "pan", 0, PAN_LIMIT_RAD)
TILT = SingleJoint("Tilt", "tilt", 1, TILT_LIMIT_RAD)
#: s of sim time from the command to a Pan/Tilt move's first check, and between its checks
#: (OceanWATERS polls at 5 Hz and sleeps one period first).
SETTLE_PERIOD_S = 0.2
#: Checks of a Pan/Tilt move before it is judged without having settled (30 s at 5 Hz).
SETTLE_CHECKS = 150
#: rad/s, a Pan/Tilt move has settled when both mast joints turn slower than this.
SETTLE_SPEED = 1e-4
#: The status text of a cancelled Pan or Tilt goal.
PREEMPTED_TEXT = "Action was preempted"
#: s, a stamp this close to a check's time is at it (stamps are float sums of steps).
_STAMP_SLACK_S = 1e-9


class SettleWatch:
    """OceanWATERS' rule for a Pan or Tilt move, on the joint states' stamps (s, sim): checks
    every :data:`SETTLE_PERIOD_S` from one period after the set-point took effect; at each check a
    cancel ends the move, else it goes on until both joints turn slower than
    :data:`SETTLE_SPEED` (or :data:`SETTLE_CHECKS` periods passed); the joint's angle then
    decides, modulo 2 pi, within :data:`TOLERANCE_RAD` of the goal. The same joint states give
    the same decisions whatever the machine's load.

    OceanWATERS waits one period after publishing the set-point, for the joint to start moving.
    Here the set-point reaches the simulation some time after it is published (tenths of a
    second of sim time when the simulation runs many times faster than real time): the first
    check is one period after ``start_s``, the sim time the simulation took the set-point from
    (its receipt), or, without one, one period after the first joint state.

    Args:
        joint: the action.
        goal: rad, the joint's target (checked).
        start_s: s (sim), when the set-point took effect, or None.
    """

    def __init__(self, joint: SingleJoint, goal: float, start_s: float | None = None) -> None:
        self.joint = joint
        self.goal = goal
        #: periods passed since the first check's time (each check counts those it ends)
        self.checks = 0
        self._next = None if start_s is None else start_s + SETTLE_PERIOD_S

    def due(self, stamp: float) -> bool:
        """Whether the joint state at ``stamp`` (s) is a check (then the next is one period
        after this one's time)."""
        if self._next is None:
            self._next = stamp + SETTLE_PERIOD_S
            return False
        if stamp < self._next - _STAMP_SLACK_S:
            return False
        passed = 1 + max(math.floor((stamp - self._next + _STAMP_SLACK_S) / SETTLE_PERIOD_S), 0)
        self._next += SETTLE_PERIOD_S * passed
        self.checks += passed  # a gap in the states counts every period it spans
        return True

    def judge(
        self, angles: tuple[float, float], speeds: tuple[float, float], preempted: bool
    ) -> MoveEnd | None:
        """The move's end at a check, or None while it goes on.

        Args:
            angles: rad, (pan, tilt) now.
            speeds: rad/s, (pan, tilt) velocities now (NaN: not measured, never settled).
            preempted: a cancel came.
        """
        if preempted:
            return MoveEnd("preempted", PREEMPTED_TEXT, hold=True)
        settled = all(abs(v) < SETTLE_SPEED for v in speeds)
        if not settled and self.checks < SETTLE_CHECKS:
            return None
        if abs(_wrap(angles[self.joint.index] - self.goal)) <= TOLERANCE_RAD:
            return MoveEnd("succeeded", f"Reached commanded {self.joint.field} value", hold=False)
        text = f"{self.joint.field.capitalize()} joint failed to reach its goal position."
        return MoveEnd("aborted", text, hold=True)


def _wrap(angle: float) -> float:
    """``angle`` (rad) in [-pi, pi)."""
    return (angle + math.pi) % (2 * math.pi) - math.pi


@dataclass(frozen=True)
class Pointing:
    """Where the mast points at one configuration.

    Attributes:
        origin: (3,) m, the camera's origin in base_link.
        axis: (3,) unit vector, its viewing direction in base_link.
    """

    origin: FloatArray
    axis: FloatArray

    def miss(self, point: FloatArray) -> tuple[float, float]:
        """(distance m from ``point`` to the pointing axis, m along the axis to its foot)."""
        r = np.asarray(point, dtype=np.float64) - self.origin
        along = float(r @ self.axis)
        return float(np.linalg.norm(r - along * self.axis)), along


class AntennaPointing:
    """The mast's kinematics: pointing at a configuration, and the pan and tilt that look at a
    point (not thread-safe, like the model).

    Args:
        model: the lander model (default: a new one).
    """

    def __init__(self, model: LanderModel | None = None) -> None:
        self.model = model or LanderModel()
        self._pan = self.model.index(ANTENNA_JOINTS[0])
        self._tilt = self.model.index(ANTENNA_JOINTS[1])
        X = self.model.fk(np.zeros(self.model.nq), _PANEL)
        #: m, the tilt joint's origin in base_link; the pan axis (vertical) passes through it.
        self.tilt_origin = X[:3, 3].copy()
        #: m, the lever from the tilt axis to the camera's origin, across the tilt axis.
        self.lever = float(CAMERA_ORIGIN_PANEL[0])

    def pointing(self, q: FloatArray) -> Pointing:
        """Where the mast points at configuration ``q`` (9,) rad (its antenna joints)."""
        X = self.model.fk(q, _PANEL)
        return Pointing(X[:3, :3] @ CAMERA_ORIGIN_PANEL + X[:3, 3], X[:3, :3] @ CAMERA_AXIS_PANEL)

    def to_base(self, frame: int, point: Sequence[float] | FloatArray, q: FloatArray) -> FloatArray:
        """(3,) m, ``point`` given in ``frame`` (:data:`FRAMES`) expressed in base_link, the tool
        frame taken at configuration ``q`` (9,) rad.

        Raises:
            GoalError: unknown frame or a non-finite coordinate.
        """
        if frame not in FRAMES:
            msg = f"frame = {frame} is neither 0 (base_link) nor 1 (tool, {SCOOP_TIP_FRAME})"
            raise GoalError(msg)
        p = np.array([_finite(f"point.{k}", v) for k, v in zip("xyz", point, strict=True)])
        if frame == FRAME_BASE:
            return p
        X = self.model.fk(q, FRAMES[frame])
        return X[:3, :3] @ p + X[:3, 3]

    def look_at(self, point: FloatArray, q: FloatArray | None = None) -> tuple[float, float]:
        """Pan and tilt (rad) that put ``point`` (3,) m in base_link on the pointing axis, in
        front of the camera.

        OceanWATERS' approximation gives the start: pan = atan2(dy, dx) + pi/2 about the tilt
        joint, and the tilt of a lever perpendicular to the line of sight; Newton steps on the
        forward kinematics then make the miss distance below :data:`LOOK_AT_TOLERANCE_M`.

        Args:
            point: (3,) m, base_link.
            q: (9,) rad, configuration giving the other joints (default 0).

        Returns:
            (pan, tilt) rad, pan in [-pi, pi).

        Raises:
            GoalError: the point is within the lever of the tilt axis (no tilt looks at it), or
                the tilt needed is beyond :data:`TILT_LIMIT_RAD` (the message names both).
        """
        p = np.asarray(point, dtype=np.float64)
        d = p - self.tilt_origin
        horizontal, vertical = math.hypot(d[0], d[1]), float(d[2])
        distance = math.hypot(horizontal, vertical)
        if distance <= self.lever * (1 + 1e-6):
            msg = (
                f"point ({p[0]:.3f}, {p[1]:.3f}, {p[2]:.3f}) m is {distance:.3f} m from the tilt "
                f"axis, within the camera's lever of {self.lever:.3f} m: no tilt looks at it"
            )
            raise GoalError(msg)
        pan = _wrap(math.atan2(d[1], d[0]) + math.pi / 2)
        tilt = math.asin(self.lever / distance) - math.atan2(vertical, horizontal)
        config = np.zeros(self.model.nq) if q is None else np.array(q, dtype=np.float64)
        angles = np.array([pan, tilt])
        for _ in range(6):
            residual = self._residual(config, angles, p)
            if float(np.max(np.abs(residual))) < LOOK_AT_TOLERANCE_M:
                break
            step = 1e-7
            jacobian = np.column_stack(
                [
                    (self._residual(config, angles + e, p) - residual) / step
                    for e in np.eye(2) * step
                ]
            )
            angles = angles - np.linalg.solve(jacobian, residual)
        pan, tilt = _wrap(float(angles[0])), float(angles[1])
        if abs(tilt) > TILT_LIMIT_RAD:
            msg = (
                f"looking at ({p[0]:.3f}, {p[1]:.3f}, {p[2]:.3f}) m needs tilt = {tilt:.3f} rad, "
                f"outside the limits [-{TILT_LIMIT_RAD}, {TILT_LIMIT_RAD}] rad"
            )
            raise GoalError(msg)
        return pan, tilt

    def _residual(self, q: FloatArray, angles: FloatArray, point: FloatArray) -> FloatArray:
        """(2,) m, ``point`` off the pointing axis, across it in the panel's x and z."""
        q[self._pan], q[self._tilt] = angles
        X = self.model.fk(q, _PANEL)
        local = X[:3, :3].T @ (point - X[:3, 3]) - CAMERA_ORIGIN_PANEL
        return np.array([local[0], local[2]])
