"""The observing side of ``arm_services`` (rospy wiring only): joint states, tf and the wrist
force/torque sensor fed to the running :class:`~ow_lander.execution.monitor.ExecutionMonitor`, its
detector samples published."""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable

import numpy as np
import rospy
from sensor_msgs.msg import JointState

from ow_description.description import ALL_JOINTS, ARM_JOINTS
from ow_lander import conversions as conv
from ow_lander.arm_services.lockstep_join import LockstepJoin
from ow_lander.arm_services.tip_sampler import TipSampler
from ow_lander.errors import PlanningError
from ow_lander.execution.guard_streams import GuardStreams
from ow_lander.execution.monitor import ExecutionMonitor
from ow_msgs.msg import GroundDetectorSignal
from ow_runtime.lockstep_client import LockstepClient, LockstepError
from ow_runtime.names import (
    ARM_END_EFFECTOR_FORCE_TORQUE,
    ARM_GROUND_DETECTOR,
    EVERY_MESSAGE,
    JOINT_STATES,
    STAMP_SLACK_S,
)
from ow_runtime.sim_time import wait_for_clock
from owl_msgs.msg import ArmEndEffectorForceTorque

#: Called with (stamp s sim, joints rad by name, wrist force (3,) N, torque (3,) N m) on every
#: joint state during an execution (the actions' feedback).
SampleCallback = Callable[[float, dict[str, float], np.ndarray, np.ndarray], None]


class ArmObserver:
    """What the arm services observe, on simulation time.

    Subscribes: ``/joint_states`` (sensor_msgs/JointState, by joint name); ``/tf``,
        ``/tf_static``: the scoop tip for the velocity ground detector (:class:`TipSampler`);
        ``/arm_end_effector_force_torque`` (owl_msgs/ArmEndEffectorForceTorque, N, N m): the
        wrist force and torque for the force detector and the guarded actions.
    Publishes: ``/arm/ground_detector`` (ow_msgs/GroundDetectorSignal) every detector sample.

    Args:
        joint_state_timeout_s: s (wall), how long :meth:`current_joints` waits.
    """

    def __init__(self, joint_state_timeout_s: float) -> None:
        self.joint_state_timeout_s = joint_state_timeout_s
        self._state_changed = threading.Condition(threading.Lock())
        self._joints: dict[str, float] = {}
        self._joint_stamp = 0.0
        self._monitor: ExecutionMonitor | None = None
        #: every joint state (s sim, rad by name) since the monitor was set, for its decisions
        self._pending: deque[tuple[float, dict[str, float]]] = deque()
        self._streams = GuardStreams(self._state_changed)
        self._on_sample: SampleCallback | None = None
        #: the simulation's lockstep, once joined: with no execution running, every joint state
        #: is acknowledged as it arrives (an execution acknowledges its decisions)
        self._lockstep: LockstepClient | None = None
        self._joining: LockstepJoin | None = None  # None: not joining a lockstep
        self._wrench = (np.zeros(3), np.zeros(3))
        self.signal_pub = rospy.Publisher(ARM_GROUND_DETECTOR, GroundDetectorSignal, queue_size=100)
        # TCP_NODELAY: the simulation writes a few messages at a time, and Nagle's algorithm
        # with delayed acknowledgements held each write back 40 ms (a lockstep round trip).
        rospy.Subscriber(
            JOINT_STATES,
            JointState,
            self._on_joint_states,
            queue_size=EVERY_MESSAGE,
            tcp_nodelay=True,
        )
        self._tip = TipSampler(
            self._state_changed, self._streams, lambda: self._monitor, self._publish_signals
        )
        rospy.Subscriber(
            ARM_END_EFFECTOR_FORCE_TORQUE,
            ArmEndEffectorForceTorque,
            self._on_wrist,
            queue_size=EVERY_MESSAGE,
            tcp_nodelay=True,
        )

    def start_joining_lockstep(self, hold: bool) -> None:
        """Register with the simulation's lockstep, on a thread of its own, once it offers one
        (it may start later, or never: then commands go out on the controllers' topics);
        ``hold``: holding it. A request meanwhile waits for it (:meth:`LockstepJoin.wait`)."""
        self._joining = LockstepJoin(rospy.get_name(), hold, self._joined, "arm services")

    def _joined(self, client: LockstepClient) -> None:
        with self._state_changed:  # and the joint states since registration
            self._lockstep = client
            if self._monitor is None:
                client.ack(self._joint_stamp, force=True)

    def _on_joint_states(self, msg: JointState) -> None:
        values = conv.joint_positions(list(msg.name), msg.position)
        with self._state_changed:
            self._joints.update(values)
            self._joint_stamp = msg.header.stamp.to_sec()
            if self._monitor is not None:
                self._monitor.record_joint_state(self._joint_stamp, self._joints)
                self._pending.append((self._joint_stamp, dict(self._joints)))
            elif self._lockstep is not None:
                self._lockstep.ack(self._joint_stamp)
            self._state_changed.notify_all()
            on_sample, joints, (force, torque) = self._on_sample, dict(self._joints), self._wrench
        if on_sample is not None:
            on_sample(msg.header.stamp.to_sec(), joints, force, torque)

    def _on_wrist(self, msg: ArmEndEffectorForceTorque) -> None:
        f, m, t = msg.value.force, msg.value.torque, msg.header.stamp.to_sec()
        force, torque = np.array([f.x, f.y, f.z]), np.array([m.x, m.y, m.z])
        with self._state_changed:
            self._wrench = (force, torque)
            monitor = self._monitor
            if monitor is not None:
                monitor.wrist_force(t, force, torque)
            self._streams.arrived("force", t)
        if monitor is not None:
            self._publish_signals(monitor)

    def _wait_stream(self, monitor: ExecutionMonitor, stamp: float) -> None:
        """Wait (holding ``_state_changed``; ``joint_state_timeout_s`` of wall time at most: the
        simulation has stopped then) until the input stream of ``monitor``'s guard ("force",
        "tip"; none: no wait) has a message of ``stamp`` (s, sim) or later, so a decision on the
        joint state of ``stamp`` has every reading up to it: the streams arrive on connections of
        their own, and under load one may lag another by seconds. A stop request ends the wait
        (the clock is paused for it)."""
        stream = monitor.guard_stream(stamp)
        if stream is not None and not self._streams.wait(
            stream, stamp, self.joint_state_timeout_s, lambda: monitor.stop_time is not None
        ):
            late = f"t={self._streams.newest[stream]:.3f} s, not t={stamp:.3f} s"
            rospy.logwarn(f"arm services: deciding on {stream} readings up to {late} only")

    def wait_quiet(self, quiet_s: float, limit_s: float = 1.0) -> None:
        """Wait until no new /joint_states has arrived for ``quiet_s`` (wall; ``limit_s`` at
        most): the newest one then carries the paused simulation's time."""
        deadline = time.monotonic() + limit_s
        with self._state_changed:
            stamp = None
            while time.monotonic() < deadline and stamp != self._joint_stamp:
                stamp = self._joint_stamp
                self._state_changed.wait(timeout=quiet_s)

    def wait_standing(self, clock: float, stamp: float) -> None:
        """Wait (``joint_state_timeout_s`` of wall time at most; logged when it runs out) until
        this node has what a paused simulation published up to where it stands: its clock reads
        ``clock`` and its newest joint state is the one of ``stamp`` (s, sim; see
        :meth:`~ow_runtime.clock_client.SimClock.standing`), however long they took to come."""
        arrived = self._wait_joint_state(stamp)
        if not (wait_for_clock(clock, self.joint_state_timeout_s) and arrived):
            rospy.logwarn(
                f"arm services: the paused simulation's t={clock:.3f} s (joint state of "
                f"t={stamp:.3f} s) did not arrive within {self.joint_state_timeout_s} s"
            )

    def _wait_joint_state(self, stamp: float) -> bool:
        """Wait (``joint_state_timeout_s`` of wall time at most) until the joint state of
        ``stamp`` (s, sim) or a newer one has arrived; whether it has."""
        with self._state_changed:
            return self._state_changed.wait_for(
                lambda: self._joint_stamp >= stamp - STAMP_SLACK_S, self.joint_state_timeout_s
            )

    def newest_stamp(self) -> float:
        """s (sim), the stamp of the newest joint state received (0 before one)."""
        with self._state_changed:
            return self._joint_stamp

    def _publish_signals(self, monitor: ExecutionMonitor) -> None:
        with self._state_changed:
            signals, monitor.signals = monitor.signals, []
        for signal in signals:
            self.signal_pub.publish(conv.detector_signal_msg(signal))

    def _catch_up(self) -> None:
        """While this node holds the simulation in the lockstep, wait (``joint_state_timeout_s``
        of wall time at most, each) until it stands held with its outputs (its terrain too)
        written and the newest joint state it published has arrived: a plan started from an
        older state or terrain (a subscriber lagging under load) differs from run to run."""
        if self._joining is not None:
            self._joining.wait(self.joint_state_timeout_s)
        lockstep = self._lockstep
        if lockstep is None or not lockstep.holding:
            return
        try:
            stamp = lockstep.held_stamp(self.joint_state_timeout_s)
        except LockstepError as error:
            rospy.logwarn(f"arm services: {error}")
            return
        if not self._wait_joint_state(stamp):
            rospy.logwarn(
                f"arm services: the joint state of t={stamp:.3f} s did not arrive within "
                f"{self.joint_state_timeout_s} s; planning from t={self.newest_stamp():.3f} s"
            )

    def current_joints(self) -> dict[str, float]:
        """rad by name, the latest joint state of the lander's joints; waits for the first one
        (and in the lockstep, holding the simulation, for the one it stands at).

        Raises:
            PlanningError: none with every arm joint within ``joint_state_timeout_s``, or the
                node is shutting down.
        """
        self._catch_up()
        deadline = time.monotonic() + self.joint_state_timeout_s
        while not rospy.is_shutdown():
            with self._state_changed:
                missing = [j for j in ARM_JOINTS if j not in self._joints]
                if not missing:
                    return {j: v for j, v in self._joints.items() if j in ALL_JOINTS}
            if time.monotonic() > deadline:
                msg = f"no /joint_states with the arm joints ({', '.join(missing)}) received"
                raise PlanningError(msg)
            time.sleep(0.01)
        msg = "shutting down"
        raise PlanningError(msg)

    def wrench(self) -> tuple[np.ndarray, np.ndarray]:
        """The latest wrist reading: force (3,) N and torque (3,) N m (zeros before one)."""
        with self._state_changed:
            return self._wrench
