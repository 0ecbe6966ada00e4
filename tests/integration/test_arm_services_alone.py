"""The arm services without a simulation: every goal still ends for a stock client.

A goal that arrives before the first ``/joint_states`` cannot be planned (there is no arm to
start from); it is aborted with the reason and an empty result, and the node stays up."""

from __future__ import annotations

import time

import actionlib
import pytest
from actionlib_msgs.msg import GoalStatus
from geometry_msgs.msg import Point, Pose, Quaternion, Vector3

import owl_msgs.msg as owl
from ow_bringup.testing import wait_for_server

pytestmark = pytest.mark.filterwarnings("ignore:notifyAll:DeprecationWarning")  # actionlib's

#: s of wall time a goal gets to end.
END_WAIT_S = 60.0

POSE = Pose(Point(1.6, 0, 0.2), Quaternion(0, 0, 0, 1))
SURFACE = (Point(1.7, 0, -0.155), Vector3(0, 0, 1), 0.2, 0.05, 10, 10)
GOALS = [
    ("ArmUnstow", owl.ArmUnstowGoal()),
    ("ArmMoveJoint", owl.ArmMoveJointGoal(False, 9, 0.1)),  # a bad goal: aborted as well
    ("ArmMoveCartesian", owl.ArmMoveCartesianGoal(0, False, POSE)),
    ("ArmFindSurface", owl.ArmFindSurfaceGoal(0, False, *SURFACE)),
]  # fmt: skip


@pytest.fixture(scope="module")
def arm_services(ros_stack):
    # Half a second of waiting for a joint state, not the default 5: none comes here.
    return ros_stack.start_node(
        "ow_lander",
        "arm_services",
        params={"execution": {"joint_state_timeout_s": 0.5}},
        wait_for_topics=["/ArmUnstow/status"],
    )


@pytest.mark.parametrize(("name", "goal"), GOALS, ids=[g[0] for g in GOALS])
def test_a_goal_before_any_joint_state_ends_aborted(arm_services, name, goal):
    client = actionlib.SimpleActionClient(name, getattr(owl, f"{name}Action"))
    wait_for_server(client, 60.0)
    client.send_goal(goal)
    deadline = time.monotonic() + END_WAIT_S
    while client.simple_state != actionlib.SimpleGoalState.DONE:
        assert time.monotonic() < deadline, f"{name}: the goal never ended"
        time.sleep(0.05)
    assert client.get_state() == GoalStatus.ABORTED, client.get_goal_status_text()
    assert client.get_goal_status_text()
    assert arm_services.alive()
