"""ROS wiring of the antenna mast's actions (see :mod:`ow_lander.mast.pan_tilt`)."""

from __future__ import annotations

import threading
from collections import deque
from collections.abc import Callable
from typing import Any

import actionlib
import numpy as np
import rospy
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64

from ow_description.description import ANTENNA_JOINTS
from ow_lander.errors import GoalError
from ow_lander.fault_watch_node import FaultWatch
from ow_lander.mast.pan_tilt import AntennaPointing, MoveWatch, check_joints_goal
from ow_runtime.feedback import StampedFeedback
from ow_runtime.names import EVERY_MESSAGE, JOINT_STATES
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

    Subscriptions:
        /joint_states (sensor_msgs/JointState): the mast's joints (and the arm's for frame 1), by
            name.

    Publications:
        /ant_pan_position_controller/command, /ant_tilt_position_controller/command
            (std_msgs/Float64): rad, the joints' set-points.
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
        self.joints_server = actionlib.SimpleActionServer(
            "PanTiltMoveJoints", PanTiltMoveJointsAction, self._on_joints, auto_start=False
        )
        self.cartesian_server = actionlib.SimpleActionServer(
            "PanTiltMoveCartesian", PanTiltMoveCartesianAction, self._on_cartesian, auto_start=False
        )
        self.joints_server.start()
        self._joints_feedback = StampedFeedback(self.joints_server.action_server, 0.0)
        self.cartesian_server.start()
        # One status timer that outlives a clock set back (actionlib's own ends its thread).
        self._status_timer = share_status_timer(
            [self.joints_server.action_server, self.cartesian_server.action_server]
        )

    def _on_joint_state(self, msg: JointState) -> None:
        with self._lock:
            self._state = msg
            if self._during_move is not None:
                self._during_move.append(msg)
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
        if not self._busy.acquire(blocking=False):
            server.set_aborted(result(0.0, 0.0), "another pan/tilt goal is running")
            return
        try:
            with self._lock:
                self._during_move = deque()
            self._move(server, target, result, feedback)
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
                text = f"no /joint_states for {JOINT_STATE_WAIT_S:.0f} s (wall): stopped"
                server.set_aborted(result(*self._antenna(q)), text)
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
            finish = {
                "succeeded": server.set_succeeded,
                "preempted": server.set_preempted,
                "aborted": server.set_aborted,
            }[end.outcome]
            finish(result(pan, tilt), end.text)
            return
        server.set_aborted(result(np.nan, np.nan), "shutting down")

    def _command(self, pan: float, tilt: float) -> None:
        self._pan.publish(Float64(pan))
        self._tilt.publish(Float64(tilt))


def main() -> None:
    """Entry point of ``rosrun ow_lander pan_tilt``."""
    init_node("pan_tilt")
    PanTiltNode()
    rospy.loginfo("pan_tilt: PanTiltMoveJoints and PanTiltMoveCartesian ready")
    spin()
