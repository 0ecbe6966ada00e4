"""Watching the execution of a timed trajectory: the arm services' decisions, free of ROS.

The node hands the trajectory to the simulation (or streams its set-points), then feeds an
:class:`ExecutionMonitor` what it observes, each with its simulation-time stamp (s):

* every joint state (``{joint: rad}``) with :meth:`ExecutionMonitor.record_joint_state`, and the
  newest one, whenever it wakes up, with :meth:`ExecutionMonitor.decide`;
* during a guarded descent, the scoop tip (base_link, m) from tf with
  :meth:`ExecutionMonitor.tip_sample` (``ground_detector: velocity``) or the wrist force (N) with
  :meth:`ExecutionMonitor.wrist_force` (``ground_detector: force``);
* with ``wrench_limits`` (the guarded actions), the wrist force and torque with
  :meth:`ExecutionMonitor.wrist_force`: a force/torque guard replaces the ground detector;
* a stop request (a cancelled action, ``ArmStop``) with :meth:`ExecutionMonitor.request_stop`.

Each :class:`Decision` says what to command and whether the execution is over: the final
set-point reached, a tracking error, a timeout, ground found or a force/torque threshold
exceeded (the arm held where it was at the contact stamp), no ground within the searched
distance, or stopped on request (the arm held where it was at the stop stamp). Every detector
sample is kept in :attr:`ExecutionMonitor.signals` for the node to publish.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from ow_description.description import ALL_JOINTS, ARM_JOINTS, SCOOP_TIP_FRAME
from ow_description.model import LanderModel
from ow_description.trajectory import Trajectory
from ow_lander.config import ExecutionConfig
from ow_lander.execution.ground_detection import ForceDetector, GroundDetector, WrenchDetector
from ow_runtime.names import STAMP_SLACK_S

FloatArray = npt.NDArray[np.float64]

#: s (sim) of joint states kept before the one decided on, to look up the one at a stop's
#: stamp (those after it are kept however many: they are still to be decided on).
HISTORY_S = 5.0
#: rad/s, a stopping arm is at rest when no joint moves faster than this.
REST_SPEED = 0.005
#: rad/s, a joint slower than this at a stop request needs no braking.
MOVING_SPEED = 0.02
#: s (sim), longest braking after a stop request before the arm is held wherever it is.
MAX_BRAKING_S = 1.0
#: Label of the trajectory segment the ground detector watches.
GUARDED = "guarded"


@dataclass
class ExecutionResult:
    """Outcome of executing a trajectory.

    Attributes:
        success: the final set-point was reached, or a guarded descent found the ground.
        message: what happened, or why it failed.
        duration: s (simulation time) from the trajectory's start to the end of the execution.
        ground_found: a guarded descent detected contact.
        ground_position: (3,) m, scoop tip in base_link at contact; zeros when not found.
        reports_ground: a guarded descent ended (found or not): the node publishes
            ``/guarded_move_result`` once.
        contact_time: s (simulation time) of the contact, or None.
        stopped: ended by a stop request (a cancelled action, ArmStop).
        hold: rad by joint name, where the arm was told to hold at the end, or None.
        wrench: (N, N m), force and torque change magnitudes at which a force/torque guard
            stopped the move, or None.
        fault: the fault that stopped the move (:meth:`ExecutionMonitor.request_stop`), or None.
    """

    success: bool
    message: str
    duration: float = 0.0
    ground_found: bool = False
    ground_position: FloatArray = field(default_factory=lambda: np.zeros(3))
    reports_ground: bool = False
    contact_time: float | None = None
    stopped: bool = False
    hold: dict[str, float] | None = None
    wrench: tuple[float, float] | None = None
    fault: str | None = None


@dataclass(frozen=True)
class DetectorSignal:
    """One sample of a detector (published as ``ow_msgs/GroundDetectorSignal``).

    Attributes:
        stamp: s (sim) of the sample.
        detector: "velocity" (m/s), "force" (N) or "torque" (N m).
        signal: the sample, in the detector's unit.
        moving_average: the detector's moving average (= signal when it has none).
        threshold: the value at which contact is declared (nan while not yet known).
        contact: contact was declared at this sample.
    """

    stamp: float
    detector: str
    signal: float
    moving_average: float
    threshold: float
    contact: bool


@dataclass(frozen=True)
class Decision:
    """What to do after an observation.

    Attributes:
        setpoints: rad by joint name, to command now (the streaming interface), or None.
        hold: rad by joint name, to command so that the arm stops there, or None.
        result: the outcome once the execution is over; None while it goes on.
        in_place: the hold means "where the arm is" (``hold`` is where it was at the joint
            state decided on): a command that takes effect later (the lockstep's latency) holds
            each joint where it is then, rather than pulling the arm back.
    """

    setpoints: dict[str, float] | None = None
    hold: dict[str, float] | None = None
    result: ExecutionResult | None = None
    in_place: bool = False


@dataclass
class Braking:
    """The arm braking after a stop request (joint arrays in trajectory order).

    Attributes:
        direction: (n,) the sign of each joint's velocity at the stop (0: it was not moving).
        last_stamp: s (sim) of the latest joint state.
        last: (n,) rad, the latest joint state.
        done: (n,) each joint has stopped or turned back since (or was not moving).
    """

    direction: FloatArray
    last_stamp: float
    last: FloatArray
    done: npt.NDArray[np.bool_]


class GuardWatch:
    """The ground detector armed for one guarded descent, fed on simulation time.

    Args:
        start: s (sim), first time of the steady descent (after the settle pause).
        end: s (sim), last time of the steady descent.
        config: the detector choice and its thresholds.
        wrench_limits: (N, N m) force and torque thresholds of a guarded action: the
            force/torque guard replaces the configured detector.

    Attributes:
        kind: "velocity" (the paper's detector), "force" (the wrist force/torque sensor) or
            "wrench" (a guarded action's force and torque thresholds).
        detector: the paper's detector.
        force_detector: the force detector.
        wrench_detector: the force/torque guard (kind "wrench"), or None.
        tip_at_contact: m, scoop tip (base_link) at the contact stamp (force and wrench).
        contact_time: s (sim) of the sample at which contact was declared, or None.
        joints: recent (stamp s, joint positions by name) of the descent, to hold the arm where
            it was at contact rather than where the running simulation has pushed it since.
    """

    def __init__(
        self,
        start: float,
        end: float,
        config: ExecutionConfig,
        wrench_limits: tuple[float, float] | None = None,
    ) -> None:
        self.start = start
        self.end = end
        self.kind = config.ground_detector if wrench_limits is None else "wrench"
        self.detector = GroundDetector(relative_tolerance=config.ground_relative_tolerance)
        self.force_detector = ForceDetector(config.ground_force_threshold_n)
        self.wrench_detector = None if wrench_limits is None else WrenchDetector(*wrench_limits)
        self.tip_at_contact: FloatArray | None = None
        self.contact_time: float | None = None
        self.joints: deque[tuple[float, dict[str, float]]] = deque()
        #: how many readings it watched, and the stamps (s, sim) of the first and the last
        self.readings = 0
        self.read_span = (math.nan, math.nan)

    @property
    def contact(self) -> FloatArray | None:
        """m, scoop tip (base_link) where the chosen detector declared contact, or None."""
        return self.detector.contact if self.kind == "velocity" else self.tip_at_contact

    def watching(self, kind: str, t: float) -> bool:
        """True when the ``kind`` detector still looks for contact at time ``t`` (s, sim)."""
        return self.kind == kind and self.contact_time is None and self.start <= t <= self.end

    def keep(self, stamp: float, joints: dict[str, float]) -> None:
        """Keep the joint state of ``stamp`` (s, sim) for :meth:`joints_at_contact` while a
        contact can still be at or after it. A contact comes at a reading watched from now on,
        so at or after the start and the last reading watched: the states before that are
        dropped but the last one. Their readings may lag the joint states by seconds (each
        stream on its own connection): a fixed number of the newest states once lost the one
        at the contact, and a breach was reported as no ground found."""
        if self.contact_time is not None and stamp > self.contact_time:
            return
        self.joints.append((stamp, joints))
        floor = self.start if self.readings == 0 else max(self.start, self.read_span[1])
        while len(self.joints) >= 2 and self.joints[1][0] <= floor:
            self.joints.popleft()

    def watched(self, t: float) -> None:
        """Count a reading of time ``t`` (s, sim) it watched."""
        self.read_span = (t if self.readings == 0 else self.read_span[0], t)
        self.readings += 1

    def searched(self) -> str:
        """What it read of the descent and the largest change seen (a search without contact)."""
        if self.readings == 0:
            return f"no {self.kind} reading between t={self.start:.2f} and t={self.end:.2f} s"
        first, last = self.read_span
        span = f"{self.readings} {self.kind} readings from t={first:.2f} to t={last:.2f} s"
        if self.wrench_detector is not None:
            return f"{span}: {self.wrench_detector.describe()}"
        if self.kind == "force":
            peak = self.force_detector.peak_rise
            return f"{span}: largest force rise {peak:.1f} N of {self.force_detector.threshold} N"
        return span

    def joints_at_contact(self) -> dict[str, float] | None:
        """Joint positions of the last joint state at or before the contact, or None."""
        if self.contact_time is None:
            return None
        before = [values for stamp, values in self.joints if stamp <= self.contact_time]
        return before[-1] if before else None


def with_settle_pause(trajectory: Trajectory, config: ExecutionConfig) -> Trajectory:
    """The trajectory to execute: a guarded segment is preceded by ``guarded_settle_s`` at rest
    (OceanWATERS waits 2 s before the descent)."""
    guarded = trajectory.segment_span(GUARDED)
    if guarded is None or config.guarded_settle_s <= 0:
        return trajectory
    return trajectory.with_pause(guarded[0], config.guarded_settle_s)


def unknown_joints(trajectory: Trajectory) -> ExecutionResult | None:
    """A refusal when ``trajectory`` names joints that are not arm joints (no controller)."""
    unknown = [j for j in trajectory.joints if j not in ARM_JOINTS]
    if unknown:
        return ExecutionResult(False, f"trajectory names joints without a controller: {unknown}")
    return None


def start_error(
    trajectory: Trajectory, joints: Mapping[str, float], config: ExecutionConfig
) -> ExecutionResult | None:
    """A refusal when the arm (``joints``: rad by name) is too far from the first row."""
    here = np.array([joints[j] for j in trajectory.joints])
    error = float(np.max(np.abs(here - trajectory.positions[0])))
    if error > config.max_tracking_error_rad:
        return ExecutionResult(
            False,
            f"the arm is {error:.3f} rad from the trajectory's first row "
            f"(limit {config.max_tracking_error_rad} rad); plan again from the current state",
        )
    return None


class ExecutionMonitor:
    """Follows one execution of ``trajectory`` and decides when and how it ends.

    Args:
        trajectory: what is executed (with its settle pause, see :func:`with_settle_pause`).
        t_start: s (sim), when its first row is due.
        config: tolerances, timeouts, the set-point rate and the ground detector.
        model: the lander, for the scoop tip's position by forward kinematics.
        joints: rad by joint name, the joint state when the execution started.
        wrench_limits: (N, N m), the force and torque thresholds of a guarded action: watched
            along the guarded segment if the trajectory has one, else along all of it.

    Attributes:
        signals: detector samples not yet published (the node takes and clears them).
        stop_time: s (sim) of a stop request, or None.
    """

    def __init__(
        self,
        trajectory: Trajectory,
        t_start: float,
        config: ExecutionConfig,
        model: LanderModel,
        joints: Mapping[str, float],
        wrench_limits: tuple[float, float] | None = None,
    ) -> None:
        self.trajectory = trajectory
        self.t_start = t_start
        self.config = config
        self.model = model
        self.limit = trajectory.duration * config.timeout_factor + config.settle_timeout_s
        self._latest = dict(joints)
        self._history: deque[tuple[float, dict[str, float]]] = deque()
        self._next_command = t_start
        self.signals: list[DetectorSignal] = []
        self.stop_time: float | None = None
        self.fault: str | None = None
        self.braking: Braking | None = None
        self.guarded = trajectory.segment_span(GUARDED)
        # The detector watches the *steady* descent (the paper): samples of the acceleration
        # ramp would set its threshold so close to zero velocity that ground which gives a
        # little is never detected, and the braking ramp at the end would look like contact.
        steady = trajectory.steady_span(GUARDED)
        self.guard = (
            GuardWatch(t_start + steady[0], t_start + steady[1], config, wrench_limits)
            if self.guarded is not None and steady is not None
            else None
        )
        if self.guard is None and wrench_limits is not None:
            self.guard = GuardWatch(t_start, t_start + self.limit, config, wrench_limits)

    @property
    def contact_time(self) -> float | None:
        """s (sim) at which the ground detector declared contact, or None."""
        return None if self.guard is None else self.guard.contact_time

    # --------------------------------------------------------------------------- observations
    def record_joint_state(self, stamp: float, joints: Mapping[str, float]) -> None:
        """Keep a joint state (every one received, rad by name) for the contact and stop
        lookups."""
        self._latest.update(joints)
        self._history.append((stamp, dict(self._latest)))
        if self.guard is not None:
            self.guard.keep(stamp, dict(self._latest))

    def wants_tip(self, t: float) -> bool:
        """True when a scoop-tip sample at time ``t`` (s, sim) is wanted (velocity detector)."""
        return self.guard is not None and self.guard.watching("velocity", t)

    def tip_sample(self, t: float, position: FloatArray) -> bool:
        """Feed the scoop tip (3,) m in base_link at time ``t`` (s, sim); True on contact."""
        guard = self.guard
        if guard is None or not guard.watching("velocity", t):
            return False
        guard.watched(t)
        detector = guard.detector
        fired = detector.update(t, position)
        if detector.velocity is not None and detector.average is not None:
            threshold = math.nan if detector.threshold is None else detector.threshold
            self.signals.append(
                DetectorSignal(t, "velocity", detector.velocity, detector.average, threshold, fired)
            )
        if fired:
            guard.contact_time = t
        return fired

    def wrist_force(self, t: float, force: FloatArray, torque: FloatArray | None = None) -> bool:
        """Feed the wrist force (3,) N and torque (3,) N m at time ``t`` (s, sim); True on
        contact (force detector) or a threshold exceeded (force/torque guard).

        The tip position at contact comes from the joint states of that stamp (see
        :meth:`decide`): tf at 30 Hz may lag the 50 Hz wrench by more than the tolerance.
        """
        guard = self.guard
        if guard is None:
            return False
        wrench = guard.wrench_detector
        if wrench is not None and guard.watching("wrench", t):
            guard.watched(t)
            fired = wrench.update(force, np.zeros(3) if torque is None else torque)
            for kind, value, limit in (
                ("force", wrench.force, wrench.force_threshold),
                ("torque", wrench.torque, wrench.torque_threshold),
            ):
                self.signals.append(
                    DetectorSignal(t, kind, value, value, limit, fired and wrench.breach == kind)
                )
        elif guard.watching("force", t):
            guard.watched(t)
            detector = guard.force_detector
            fired = detector.update(force)
            self.signals.append(
                DetectorSignal(t, "force", detector.rise, detector.rise, detector.threshold, fired)
            )
        else:
            return False
        if fired:
            guard.contact_time = t
        return fired

    def guard_stream(self, t: float) -> str | None:
        """The guard's input stream ("force": the wrist F/T sensor, "tip": the scoop tip from
        tf) that must have reached time ``t`` (s, sim) before a decision on the joint state of
        ``t``: a descent ends as "no ground" only once the readings up to its end are in. None
        when no guard is looking for contact then."""
        guard = self.guard
        if guard is None or guard.contact_time is not None or t < guard.start:
            return None
        return "tip" if guard.kind == "velocity" else "force"

    @property
    def watches_force(self) -> bool:
        """Whether contact is detected from the wrist F/T sensor (force detector or a guarded
        action's thresholds)."""
        return self.guard is not None and self.guard.kind in ("force", "wrench")

    def request_stop(self, stamp: float, fault: str | None = None) -> None:
        """Stop at ``stamp`` (s, sim; a cancelled action, ``ArmStop``, or a ``fault``): the
        decision on the joint state of that stamp (or the first after it; none on those before)
        holds the arm at the joint state of that stamp (it brakes); once it is at rest,
        the arm is held where it came to rest and the execution ends as stopped, or, for a
        fault, as failed with the fault in its message."""
        if self.stop_time is None:
            self.stop_time = stamp
            self.fault = fault

    # ------------------------------------------------------------------------------ decisions
    def decide(self, stamp: float, joints: Mapping[str, float]) -> Decision:
        """The decision on the joint state of ``stamp`` (s sim, rad by name); call it on every
        joint state in order, once the guard's stream has reached ``stamp``
        (:meth:`guard_stream`).

        A contact (or threshold) is acted on at the first joint state at or after the reading
        that showed it, whenever that reading arrived: the arm is held at the joint state of
        the contact stamp.
        """
        cfg = self.config
        names = self.trajectory.joints
        here = np.array([joints[j] for j in names])
        t = stamp - self.t_start
        history = self._history
        while len(history) >= 2 and history[1][0] <= stamp - HISTORY_S:
            history.popleft()
        contact = self.contact_time
        if contact is not None and contact <= stamp + STAMP_SLACK_S:
            return self._contact(here, t)
        if self.stop_time is not None:
            if stamp < self.stop_time - STAMP_SLACK_S:  # a state from before the stop request
                return Decision()
            return self._stop(stamp, here, t)
        setpoints = None
        if cfg.interface == "position_controllers" and stamp >= self._next_command:
            ahead = self.trajectory.sample(max(t + 1.0 / cfg.command_rate_hz, 0.0))
            setpoints = _by_name(names, ahead)
            self._next_command = stamp + 1.0 / cfg.command_rate_hz
        if t < 0.0:
            return Decision(setpoints)
        error = np.abs(here - self.trajectory.sample(t))
        worst = int(np.argmax(error))
        if error[worst] > cfg.max_tracking_error_rad:
            message = (
                f"tracking error: {names[worst]} is {error[worst]:.3f} rad from its set-point "
                f"at t={t:.1f} s (limit {cfg.max_tracking_error_rad} rad); the arm holds where "
                "it is"
            )
            failed = ExecutionResult(False, message, t)
            return Decision(setpoints, _by_name(names, here), failed, in_place=True)
        if t >= self.trajectory.duration and error[worst] <= cfg.goal_tolerance_rad:
            reached = ExecutionResult(True, "reached the final set-point", t)
            return Decision(setpoints, None, self._finished(reached))
        if t > self.limit:
            message = (
                f"timeout: final set-point not reached within {self.limit:.1f} s "
                f"(worst joint {names[worst]} {error[worst]:.3f} rad away)"
            )
            failed = ExecutionResult(False, message, t)
            return Decision(setpoints, _by_name(names, here), failed, in_place=True)
        return Decision(setpoints)

    def stalled(self) -> Decision:
        """The decision when joint states stopped arriving: hold the last one, fail."""
        message = (
            f"no /joint_states for {self.config.joint_state_timeout_s} s of wall time: "
            "is the simulation running?"
        )
        hold = {j: self._latest[j] for j in self.trajectory.joints}
        return Decision(None, hold, ExecutionResult(False, message))

    def _stop(self, stamp: float, here: FloatArray, t: float) -> Decision:
        """Stopping on request. First hold the joint state of the stop stamp: the joint
        controllers brake the arm, which overshoots that hold a little. Once every joint that
        was moving has stopped or turned back (or after ``MAX_BRAKING_S``), hold it right
        there: a hold behind the arm would pull it back for seconds (the controllers' slow
        return), one where it stands keeps it still."""
        assert self.stop_time is not None
        names = self.trajectory.joints
        if self.braking is None:
            before = [(s, v) for s, v in self._history if s <= self.stop_time]
            hold = np.array([before[-1][1][j] for j in names]) if before else here
            direction = np.zeros(len(names))
            if len(before) >= 2 and before[-1][0] > before[-2][0]:
                previous = np.array([before[-2][1][j] for j in names])
                velocity = (hold - previous) / (before[-1][0] - before[-2][0])
                direction = np.where(np.abs(velocity) > MOVING_SPEED, np.sign(velocity), 0.0)
            self.braking = Braking(direction, stamp, here, direction == 0)
            return Decision(None, _by_name(names, hold))
        brake = self.braking
        if stamp <= brake.last_stamp:
            return Decision()
        step = here - brake.last
        speed = np.abs(step) / (stamp - brake.last_stamp)
        brake.last_stamp, brake.last = stamp, here
        brake.done |= (np.sign(step) != brake.direction) | (speed < REST_SPEED)
        if not np.all(brake.done) and stamp - self.stop_time < MAX_BRAKING_S:
            return Decision()
        at = (
            f"at t={self.stop_time - self.t_start:.2f} s, at rest {stamp - self.stop_time:.2f} s "
            "later"
        )
        message = (
            f"stopped on request {at}"
            if self.fault is None
            else f"{self.fault}: the arm stopped {at} and holds there"
        )
        rest = _by_name(names, here)
        stopped = self.fault is None
        result = ExecutionResult(False, message, t, stopped=stopped, hold=rest, fault=self.fault)
        return Decision(None, rest, result, in_place=True)

    def _contact(self, here: FloatArray, t: float) -> Decision:
        """Ground found: hold where the arm was at the contact stamp. The simulation may have
        run on for a while (it runs many times faster than real time): go back there, not
        further into the ground it yields."""
        guard = self.guard
        assert guard is not None  # a contact time comes from the guard
        hold = here
        at_contact = guard.joints_at_contact()
        if at_contact is not None:
            q_contact = self._q(at_contact)
            if guard.kind != "velocity":
                # Where the tip was at the force reading's stamp (tf may lag it).
                guard.tip_at_contact = self.model.position(q_contact, SCOOP_TIP_FRAME)
            hold = np.array([q_contact[self.model.index(j)] for j in self.trajectory.joints])
        wrench = guard.wrench_detector
        found = ExecutionResult(True, "ground found" if wrench is None else wrench.describe(), t)
        result = self._finished(found)
        result.hold = _by_name(self.trajectory.joints, hold)
        if wrench is not None:
            result.wrench = (wrench.force, wrench.torque)
        return Decision(None, result.hold, result)

    def _finished(self, result: ExecutionResult) -> ExecutionResult:
        """A successful end; for a guarded descent, ground found or not found."""
        if self.guarded is None:
            return result
        guard = self.guard
        if guard is not None and guard.contact_time is not None and guard.contact is not None:
            position = guard.contact
            found = "ground found" if guard.wrench_detector is None else result.message
            return ExecutionResult(
                True,
                f"{found} at z={position[2]:.4f} m (t={guard.contact_time:.2f} s sim)",
                result.duration,
                ground_found=True,
                ground_position=position,
                reports_ground=True,
                contact_time=guard.contact_time,
            )
        base = self._q(self._latest)
        ends = [
            self.model.position(
                self.model.q_from(_by_name(self.trajectory.joints, row), base), SCOOP_TIP_FRAME
            )
            for row in (
                self.trajectory.sample(self.guarded[0]),
                self.trajectory.sample(self.guarded[1]),
            )
        ]
        searched = float(np.linalg.norm(ends[1] - ends[0]))
        read = "" if guard is None else f" ({guard.searched()})"
        return ExecutionResult(
            False,
            f"no ground within {searched:.2f} m of the start of the descent{read}",
            result.duration,
            reports_ground=True,
        )

    def _q(self, joints: Mapping[str, float]) -> FloatArray:
        """(9,) rad, the model configuration of a joint state (joints of the lander only)."""
        return self.model.q_from({j: v for j, v in joints.items() if j in ALL_JOINTS})


def _by_name(joints: tuple[str, ...], values: FloatArray) -> dict[str, float]:
    return {joint: float(value) for joint, value in zip(joints, values, strict=True)}
