"""The antenna mast's actions on the real simulation, through actionlib's SimpleActionClient:
moves checked against the simulation's joint states, the look-at against forward kinematics, a
cancel that holds the mast, and bad goals refused with the reason."""

from __future__ import annotations

import math
import threading
import time

import numpy as np
import pytest
import rospy
from actionlib_msgs.msg import GoalStatus
from geometry_msgs.msg import Point
from sensor_msgs.msg import JointState

from ow_bringup.testing import FLAT, action_client, subscribe
from ow_lander.mast.pan_tilt import AntennaPointing
from owl_msgs.msg import (
    PanTiltMoveCartesianAction,
    PanTiltMoveCartesianGoal,
    PanTiltMoveJointsAction,
    PanTiltMoveJointsActionFeedback,
    PanTiltMoveJointsGoal,
)

TOLERANCE = 0.05
RESULT_WAIT = 120.0  # s of wall time


class Feedback:
    """Stamps (s of sim time) of every PanTiltMoveJoints feedback message."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.stamps: list[float] = []
        subscribe(
            "/PanTiltMoveJoints/feedback",
            PanTiltMoveJointsActionFeedback,
            self._on,
        )

    def _on(self, msg) -> None:
        with self.lock:
            self.stamps.append(msg.header.stamp.to_sec())

    def take(self) -> list[float]:
        with self.lock:
            stamps, self.stamps = self.stamps, []
        return stamps


@pytest.fixture(scope="module")
def mast(ros_stack):
    ros_stack.start_node(
        "ow_sim_bullet",
        "sim",
        params={"real_time_factor": 1.0, "terrain": FLAT},
        wait_for_topics=["/joint_states"],
    )
    node = ros_stack.start_node(
        "ow_lander", "pan_tilt", wait_for_topics=["/PanTiltMoveJoints/status"]
    )
    joints = action_client("PanTiltMoveJoints", PanTiltMoveJointsAction)
    cartesian = action_client("PanTiltMoveCartesian", PanTiltMoveCartesianAction)
    return node, joints, cartesian, Feedback()


def joint_state() -> dict[str, float]:
    msg = rospy.wait_for_message("/joint_states", JointState, timeout=10)
    return {n: float(p) for n, p in zip(msg.name, msg.position, strict=True)}


def test_move_joints_reaches_the_goal_in_the_simulation(mast):
    _, joints, _, feedback = mast
    feedback.take()
    joints.send_goal(PanTiltMoveJointsGoal(pan=0.6, tilt=0.4))
    assert joints.wait_for_end(RESULT_WAIT)
    assert joints.get_state() == GoalStatus.SUCCEEDED, joints.get_goal_status_text()
    result = joints.get_result()
    assert result.pan_position == pytest.approx(0.6, abs=TOLERANCE)
    assert result.tilt_position == pytest.approx(0.4, abs=TOLERANCE)
    time.sleep(1.0)
    state = joint_state()
    assert state["j_ant_pan"] == pytest.approx(0.6, abs=TOLERANCE)
    assert state["j_ant_tilt"] == pytest.approx(0.4, abs=TOLERANCE)
    stamps = feedback.take()
    assert len(stamps) >= 3
    gaps = np.diff(stamps)
    assert np.max(gaps) <= 0.1 + 1e-6  # at least 10 Hz of sim time


def test_move_cartesian_points_the_camera_axis_at_the_point(mast):
    _, _, cartesian, _ = mast
    target = (1.5, -0.3, -0.155)
    cartesian.send_goal(PanTiltMoveCartesianGoal(frame=0, point=Point(*target)))
    assert cartesian.wait_for_end(RESULT_WAIT)
    assert cartesian.get_state() == GoalStatus.SUCCEEDED, cartesian.get_goal_status_text()
    time.sleep(1.0)
    pointing = AntennaPointing()
    q = pointing.model.q_from(joint_state())
    miss, ahead = pointing.pointing(q).miss(np.array(target))
    assert ahead > 0.0
    assert miss / ahead < math.tan(math.hypot(TOLERANCE, TOLERANCE))


def test_a_cancel_stops_and_holds_the_mast(mast):
    _, joints, _, _ = mast
    start = joint_state()["j_ant_pan"]
    joints.send_goal(PanTiltMoveJointsGoal(pan=-3.0, tilt=0.0))
    deadline = time.monotonic() + 30.0
    while abs(joint_state()["j_ant_pan"] - start) < 0.1:
        assert time.monotonic() < deadline, "the mast did not start moving"
        time.sleep(0.05)
    joints.cancel_goal()
    assert joints.wait_for_end(RESULT_WAIT)
    assert joints.get_state() == GoalStatus.PREEMPTED, joints.get_goal_status_text()
    stopped = joints.get_result().pan_position  # where the mast was told to stay
    time.sleep(6.0)  # the panel swings back onto the set-point
    held = joint_state()["j_ant_pan"]
    assert held == pytest.approx(stopped, abs=0.03)
    assert held > -3.0 + 0.5  # far from the cancelled goal


@pytest.mark.parametrize(
    ("action", "goal", "message"),
    [
        ("joints", PanTiltMoveJointsGoal(pan=math.nan, tilt=0.0), "pan = nan is not a finite"),
        ("joints", PanTiltMoveJointsGoal(pan=0.0, tilt=2.0), "tilt = 2 rad is outside the limits"),
        ("joints", PanTiltMoveJointsGoal(pan=4.0, tilt=0.0), "[-3.2, 3.2] rad"),
        ("cartesian", PanTiltMoveCartesianGoal(frame=5, point=Point(1, 0, 0)), "frame = 5"),
        (
            "cartesian",
            PanTiltMoveCartesianGoal(frame=0, point=Point(math.inf, 0, 0)),
            "point.x = inf is not a finite number",
        ),
    ],
)
def test_bad_goals_are_refused_with_the_reason_and_the_node_lives(mast, action, goal, message):
    node, joints, cartesian, _ = mast
    client = joints if action == "joints" else cartesian
    before = joint_state()
    client.send_goal(goal)
    assert client.wait_for_end(RESULT_WAIT)
    assert client.get_state() == GoalStatus.ABORTED
    assert message in client.get_goal_status_text()
    assert node.alive()
    after = joint_state()
    for joint in ("j_ant_pan", "j_ant_tilt"):
        assert after[joint] == pytest.approx(before[joint], abs=0.01)
