"""ROS wiring of the antenna mast's actions (see :mod:`ow_lander.mast.pan_tilt`)."""

from __future__ import annotations

import math
import threading
from collections import deque
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from functools import partial
from typing import Any

import actionlib
import numpy as np
import rospy
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64, Header

from ow_description.description import ANTENNA_JOINTS
from ow_lander.errors import GoalError
from ow_lander.fault_watch_node import FaultWatch
from ow_lander.mast.comms_node import CommsServer
from ow_lander.mast.dock_ingest_node import DockIngestServer
from ow_lander.mast.pan_tilt import (
    PAN,
    TILT,
    AntennaPointing,
    MoveEnd,
    MoveWatch,
    SettleWatch,
    SingleJoint,
    check_joints_goal,
)
from ow_lander.msg import PanAction, PanFeedback, PanResult, TiltAction, TiltFeedback, TiltResult
from ow_runtime.action_server import SimpleActionServer
from ow_runtime.feedback import StampedFeedback
from ow_runtime.names import EVERY_MESSAGE, JOINT_STATES, REFUSED, SIM_NAMESPACE
from ow_runtime.node import init_node, spin
from ow_runtime.status_timer import share_status_timer
from owl_msgs.msg import (
    PanTiltMoveCartesianAction,
    PanTiltMoveCartesianResult,
    PanTiltMoveJointsAction,
    PanTiltMoveJointsFeedback,
    PanTiltMoveJointsResult,
)

#: Hz of sim time, feedback (by the joint states' stamps).
FEEDBACK_HZ = 20.0
#: s of sim time a move may take before it is aborted (OceanWATERS: 30 s).
MOVE_TIMEOUT_S = 30.0
#: s of wall time to wait for a first /joint_states, and for each next one during a move.
JOINT_STATE_WAIT_S = 5.0

PAN_COMMAND = "/ant_pan_position_controller/command"
TILT_COMMAND = "/ant_tilt_position_controller/command"
#: The simulation's receipts of set-points (std_msgs/Header: stamp = the sim time a set-point
#: holds from, frame_id = its joint; ``ow_sim_bullet.commands_node``).
SETPOINT_RECEIPTS = f"{SIM_NAMESPACE}/setpoint_received"
#: The refusal of a goal while another one moves the mast.
MAST_BUSY = "another pan/tilt goal is running"
#: The end of a move that the joint states stopped coming to.
NO_STATES = f"no /joint_states for {JOINT_STATE_WAIT_S:.0f} s (wall): stopped"
#: ow_lander's single-joint actions: the action, its result and feedback messages.
SINGLE_JOINT_ACTIONS = {
    PAN.action: (PAN, PanAction, PanResult, PanFeedback),
    TILT.action: (TILT, TiltAction, TiltResult, TiltFeedback),
}


class PanTiltNode:
    """The ``pan_tilt`` node: OceanWATERS' antenna mast actions on the simulation's position
    controllers. One goal at a time: a new goal to the same action preempts the running one, a
    goal to the other action while one runs is aborted.

    Action servers (owl_msgs):
        PanTiltMoveJoints: goal pan, tilt rad (|pan| <= 3.2, |tilt| <= 1.56); succeeds when both
            joints are within 0.05 rad of it; feedback and result pan_position, tilt_position rad,
            feedback at 20 Hz of sim time (every 0.05 s of joint-state stamps, whatever the
            machine's load).
        PanTiltMoveCartesian: goal frame (0 base_link, 1 tool = l_scoop_tip) and point m; points
            the stereo camera's axis through the point (pan/tilt from the URDF's kinematics).
        A move is watched on every joint state, in order: arrival, cancel, faults, the timeout.
        A cancel stops the mast where it is and holds it (preempted); a move not done within 30 s
        of sim time (joint-state stamps) is stopped and aborted. Bad goals (NaN/inf, beyond a
        limit, unknown frame) are aborted at once with a status text naming the field, its value
        and the limit.
        Faults (:class:`~ow_lander.fault_watch_node.FaultWatch`): a goal is aborted at once
        while PAN_TILT_GOAL_ERROR stands with ``auto_clear_goal_errors`` false, or while an
        antenna joint is locked (PAN_TILT_EXECUTION_ERROR); a lock during a move stops the
        mast where it is and aborts the goal naming the joint.

    Action servers (ow_lander, OceanWATERS' semantics and texts;
    :class:`~ow_lander.mast.pan_tilt.SettleWatch`):
        Pan, Tilt: goal pan (|pan| <= 3.2) or tilt (|tilt| <= 1.56) rad, only that joint is
            commanded; outside the limits (or NaN): aborted "Requested pan 4.0 is not within
            allowed limits."; checked every 0.2 s of sim time until both joints turn slower than
            1e-4 rad/s (at most 30 s), then SUCCEEDED "Reached commanded pan value" when the
            joint is within 0.05 rad of the goal (modulo 2 pi), else ABORTED "Pan joint failed
            to reach its goal position." holding the joint where it is; a cancel holds it too,
            PREEMPTED "Action was preempted"; feedback and result pan_position (tilt_position)
            rad, feedback at each check. Busy and fault refusals as above.
        ActivateComms: :class:`~ow_lander.mast.comms_node.CommsServer`.
        DockIngestSample: :class:`~ow_lander.mast.dock_ingest_node.DockIngestServer` (calls the
            simulation's /sim/ingest_sample).

    Subscriptions:
        /joint_states (sensor_msgs/JointState): the mast's joints (and the arm's for frame 1), by
            name.
        /sim/setpoint_received (std_msgs/Header): when the simulation took a Pan or Tilt
            set-point (sim time), from which the move's checks are timed.

    Publications:
        /ant_pan_position_controller/command, /ant_tilt_position_controller/command
            (std_msgs/Float64): rad, the joints' set-points.
        /electrical_power (std_msgs/Float64, W, latched): the communication load, when no
            lockstep simulation or power node is there to take it exactly
            (:class:`~ow_lander.mast.comms_node.CommsServer`).

    Calls:
        /power/set_load (ow_msgs/SetLoad), /sim/lockstep_register: the communication load,
            exact in sim time (:class:`~ow_lander.mast.comms_node.CommsServer`).
    """

    def __init__(self) -> None:
        self.pointing = AntennaPointing()
        self.model = self.pointing.model
        self._lock = threading.Lock()
        self._state: JointState | None = None
        self._arrived = threading.Condition(self._lock)
        self._during_move: deque[JointState] | None = None  # every state while a move runs
        self._busy = threading.Lock()
        self.faults = FaultWatch()
        self._pan = rospy.Publisher(PAN_COMMAND, Float64, queue_size=10)
        self._tilt = rospy.Publisher(TILT_COMMAND, Float64, queue_size=10)
        rospy.Subscriber(JOINT_STATES, JointState, self._on_joint_state, queue_size=EVERY_MESSAGE)
        self.joints_server = SimpleActionServer(
            "PanTiltMoveJoints", PanTiltMoveJointsAction, self._on_joints
        )
        self.cartesian_server = SimpleActionServer(
            "PanTiltMoveCartesian", PanTiltMoveCartesianAction, self._on_cartesian
        )
        self.joints_server.start()
        self._joints_feedback = StampedFeedback(self.joints_server.action_server, 0.0)
        self.cartesian_server.start()
        self._receipts: dict[str, float | None] = {}  # joint -> sim s its set-point holds from
        rospy.Subscriber(SETPOINT_RECEIPTS, Header, self._on_receipt, queue_size=EVERY_MESSAGE)
        self.single_servers: dict[str, tuple[SimpleActionServer, StampedFeedback]] = {}
        for name, (joint, action, _, _) in SINGLE_JOINT_ACTIONS.items():
            server = SimpleActionServer(name, action, partial(self._on_single, joint))
            server.start()
            self.single_servers[name] = (server, StampedFeedback(server.action_server, 0.0))
        self.comms = CommsServer()
        self.dock_ingest = DockIngestServer()
        # One status timer that outlives a clock set back (actionlib's own ends its thread).
        self._status_timer = share_status_timer(
            [self.joints_server.action_server, self.cartesian_server.action_server]
            + [s.action_server for s, _ in self.single_servers.values()]
            + [self.comms.server.action_server, self.dock_ingest.server.action_server]
        )

    def _on_joint_state(self, msg: JointState) -> None:
        with self._lock:
            self._state = msg
            if self._during_move is not None:
                self._during_move.append(msg)
                self._arrived.notify_all()

    def _on_receipt(self, msg: Header) -> None:
        with self._lock:
            refused = msg.frame_id.startswith(REFUSED)
            self._receipts[msg.frame_id.removeprefix(REFUSED)] = (
                None if refused else msg.stamp.to_sec()
            )
            self._arrived.notify_all()

    def _next_state(self) -> JointState | None:
        """The oldest joint state of the move not yet watched, waited for up to
        ``JOINT_STATE_WAIT_S`` of wall time; None if none came."""
        with self._lock:
            queue = self._during_move
            if queue is None or not self._arrived.wait_for(
                lambda: bool(queue) or rospy.is_shutdown(), JOINT_STATE_WAIT_S
            ):
                return None
            return queue.popleft() if queue else None

    def _q(self, state: JointState) -> np.ndarray:
        known = set(self.model.joint_names)
        values = {n: p for n, p in zip(state.name, state.position, strict=False) if n in known}
        return self.model.q_from(values)

    def _configuration(self) -> np.ndarray | None:
        """(9,) rad, the latest joint state by name (waits a little for a first one)."""
        deadline = rospy.get_rostime().to_sec() + JOINT_STATE_WAIT_S
        rate = rospy.Rate(FEEDBACK_HZ)
        while True:
            with self._lock:
                state = self._state
            if state is not None:
                return self._q(state)
            if rospy.get_rostime().to_sec() > deadline or rospy.is_shutdown():
                return None
            rate.sleep()

    def _antenna(self, q: np.ndarray) -> tuple[float, float]:
        return float(q[self.model.index(ANTENNA_JOINTS[0])]), float(
            q[self.model.index(ANTENNA_JOINTS[1])]
        )

    # ------------------------------------------------------------------ goals
    def _on_joints(self, goal: Any) -> None:
        server = self.joints_server

        def result(pan: float, tilt: float) -> PanTiltMoveJointsResult:
            return PanTiltMoveJointsResult(pan_position=pan, tilt_position=tilt)

        def feedback(pan: float, tilt: float, stamp: float) -> None:
            msg = PanTiltMoveJointsFeedback(pan_position=pan, tilt_position=tilt)
            self._joints_feedback.publish(server.current_goal, msg, stamp)

        self._run(server, lambda _: check_joints_goal(goal.pan, goal.tilt), result, feedback)

    def _on_cartesian(self, goal: Any) -> None:
        def target(q: np.ndarray) -> tuple[float, float]:
            point = (goal.point.x, goal.point.y, goal.point.z)
            return self.pointing.look_at(self.pointing.to_base(goal.frame, point, q), q)

        self._run(
            self.cartesian_server, target, lambda *_: PanTiltMoveCartesianResult(), lambda *_: None
        )

    def _run(
        self,
        server: actionlib.SimpleActionServer,
        target: Callable[[np.ndarray], tuple[float, float]],
        result: Callable[[float, float], Any],
        feedback: Callable[[float, float, float], None],
    ) -> None:
        """Check the goal, command it and watch the joints until they arrive, a cancel, the
        timeout or a shutdown."""
        with self._hold_mast() as free:
            if not free:
                server.set_aborted(result(0.0, 0.0), MAST_BUSY)
                return
            self._move(server, target, result, feedback)

    @contextmanager
    def _hold_mast(self) -> Iterator[bool]:
        """Take the mast for one goal: yields whether it was free; while taken, every joint
        state is queued for the move (:meth:`_next_state`)."""
        if not self._busy.acquire(blocking=False):
            yield False
            return
        try:
            with self._lock:
                self._during_move = deque()
            yield True
        finally:
            with self._lock:
                self._during_move = None
            self._busy.release()

    def _move(
        self,
        server: actionlib.SimpleActionServer,
        target: Callable[[np.ndarray], tuple[float, float]],
        result: Callable[[float, float], Any],
        feedback: Callable[[float, float, float], None],
    ) -> None:
        q = self._configuration()
        if q is None:
            server.set_aborted(result(0.0, 0.0), "no /joint_states: the mast's state is unknown")
            return
        try:
            goal = target(q)
        except GoalError as error:
            rospy.logwarn(f"pan_tilt: goal refused: {error}")
            server.set_aborted(result(*self._antenna(q)), f"goal refused: {error}")
            return
        refused = self.faults.now().refusal("pan_tilt")
        if refused is not None:
            server.set_aborted(result(*self._antenna(q)), f"goal refused: {refused}")
            return
        self._command(*goal)
        watch = MoveWatch(goal, MOVE_TIMEOUT_S, 1.0 / FEEDBACK_HZ)
        while not rospy.is_shutdown():
            state = self._next_state()
            if state is None:
                if rospy.is_shutdown():
                    break
                self._command(*self._antenna(q))
                server.set_aborted(result(*self._antenna(q)), NO_STATES)
                return
            stamp = state.header.stamp.to_sec()
            q = self._q(state)
            pan, tilt = self._antenna(q)
            fault = self.faults.now().pan_tilt_error()
            end = watch.end(stamp, pan, tilt, fault, server.is_preempt_requested())
            if end is None:
                if watch.feedback_due(stamp):
                    feedback(pan, tilt, stamp)
                continue
            if end.hold:
                self._command(pan, tilt)
            else:
                feedback(pan, tilt, stamp)
            _finish(server, end, result(pan, tilt))
            return
        server.set_aborted(result(np.nan, np.nan), "shutting down")

    # ------------------------------------------------------- ow_lander's Pan and Tilt
    def _on_single(self, joint: SingleJoint, goal: Any) -> None:
        """A Pan or Tilt goal: checked, refused or moved as OceanWATERS does."""
        server, stamped = self.single_servers[joint.action]
        _, _, result_type, feedback_type = SINGLE_JOINT_ACTIONS[joint.action]
        field = f"{joint.field}_position"

        def result(angle: float) -> Any:
            return result_type(**{field: angle})

        def feedback(angle: float, stamp: float) -> None:
            stamped.publish(server.current_goal, feedback_type(**{field: angle}), stamp)

        q = self._configuration()
        if q is None:
            server.set_aborted(result(math.nan), "no /joint_states: the mast's state is unknown")
            return
        angle = self._antenna(q)[joint.index]
        try:
            target = joint.check_goal(getattr(goal, joint.field))
        except GoalError as error:
            server.set_aborted(result(angle), str(error))
            return
        refused = self.faults.now().refusal("pan_tilt")
        if refused is not None:
            server.set_aborted(result(angle), f"goal refused: {refused}")
            return
        with self._hold_mast() as free:
            if not free:
                server.set_aborted(result(angle), MAST_BUSY)
                return
            self._settle(joint, (angle, target), server, result, feedback)

    def _settle(
        self,
        joint: SingleJoint,
        move: tuple[float, float],
        server: SimpleActionServer,
        result: Callable[[float], Any],
        feedback: Callable[[float, float], None],
    ) -> None:
        """Command ``joint`` from ``move[0]`` to ``move[1]`` (rad) and judge the move at each
        check."""
        angle, target = move
        name = ANTENNA_JOINTS[joint.index]
        with self._lock:
            self._receipts.pop(name, None)
        self._command_joint(joint, target)
        with self._lock:
            self._arrived.wait_for(
                lambda: name in self._receipts or rospy.is_shutdown(), JOINT_STATE_WAIT_S
            )
            start = self._receipts.pop(name, None)
        if start is None:
            rospy.logwarn(f"pan_tilt: no receipt of the {name} set-point: timed from now on")
        watch = SettleWatch(joint, target, start)
        while not rospy.is_shutdown():
            state = self._next_state()
            if state is None:
                if rospy.is_shutdown():
                    break
                self._command_joint(joint, angle)
                server.set_aborted(result(angle), NO_STATES)
                return
            stamp = state.header.stamp.to_sec()
            angles = self._antenna(self._q(state))
            angle = angles[joint.index]
            if not watch.due(stamp):
                continue
            end = watch.judge(angles, _speeds(state), server.is_preempt_requested())
            if end is None or end.outcome != "preempted":
                feedback(angle, stamp)
            if end is None:
                continue
            if end.hold:
                self._command_joint(joint, angle)
            _finish(server, end, result(angle))
            return
        server.set_aborted(result(math.nan), "shutting down")

    def _command(self, pan: float, tilt: float) -> None:
        self._pan.publish(Float64(pan))
        self._tilt.publish(Float64(tilt))

    def _command_joint(self, joint: SingleJoint, angle: float) -> None:
        (self._pan, self._tilt)[joint.index].publish(Float64(angle))


def _finish(server: Any, end: MoveEnd, result: Any) -> None:
    """End the goal of ``server`` as ``end`` says, with ``result``."""
    finish = {
        "succeeded": server.set_succeeded,
        "preempted": server.set_preempted,
        "aborted": server.set_aborted,
    }[end.outcome]
    finish(result, end.text)


def _speeds(state: JointState) -> tuple[float, float]:
    """rad/s, (pan, tilt) velocities of ``state`` (NaN where it has none)."""
    velocity = dict(zip(state.name, state.velocity, strict=False))
    pan, tilt = (float(velocity.get(name, math.nan)) for name in ANTENNA_JOINTS)
    return pan, tilt


def main() -> None:
    """Entry point of ``rosrun ow_lander pan_tilt``."""
    init_node("pan_tilt")
    PanTiltNode()
    rospy.loginfo(
        "pan_tilt: PanTiltMoveJoints, PanTiltMoveCartesian, Pan, Tilt, ActivateComms, "
        "DockIngestSample"
    )
    spin()
