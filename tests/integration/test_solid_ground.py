"""Solid ground outside a dig, and never stranded (issue "Arm compatibility", items 4 and 5), on
the real simulation and arm services through OceanWATERS' actions with actionlib's stock
``SimpleActionClient``.

* A guarded Cartesian move to 0.1 m below flat ground with OceanWATERS' thresholds (200 N,
  100 N m) stops on the ground: the terrain is solid to a tool pressed into it outside a dig.
  Before, the scoop carved its way down and the hand ended 45 mm under the terrain, the guard
  never tripping.
* After a burial (the terrain raised around the arm, the hand 0.12 m under it) and after a dig
  cancelled with the scoop deep in its trench, ArmUnstow takes the arm out and unstows it. Before,
  every later goal was refused with "the arm's current configuration is invalid".
* The simulation publishes the scoop's dig phase as OceanWATERS does: a dig goes through its
  phases, the guarded move has none.
"""

from __future__ import annotations

import time

import actionlib
import numpy as np
import pytest
import rospy
from actionlib_msgs.msg import GoalStatus
from geometry_msgs.msg import Point, Pose, Quaternion
from sensor_msgs.msg import JointState
from std_srvs.srv import Trigger

import owl_msgs.msg as owl
from ow_bringup.testing import set_terrain, subscribe, wait_for_server
from ow_description.conversions import height_map_from_msg
from ow_description.description import (
    ARM_JOINTS,
    DEFAULT_GROUND_Z,
    SCOOP_ABOVE_GROUND,
    SCOOP_TIP_FRAME,
    UNSTOWED,
)
from ow_description.model import LanderModel
from ow_lander.actions.owl import quaternion_from_rotation
from ow_msgs.msg import HeightMap as HeightMapMsg
from ow_msgs.msg import ScoopDigPhase, ToolState
from ow_runtime.connections import wait_sending
from ow_sim_bullet.outputs import DIG_PHASE_TOPIC

GROUND = DEFAULT_GROUND_Z
#: N and N m, OceanWATERS' guarded-move thresholds (ow_lander arm_move_cartesian_guarded.py).
FORCE_THRESHOLD, TORQUE_THRESHOLD = 200.0, 100.0
#: rad, how close to the unstowed pose the arm ends an ArmUnstow.
END_TOLERANCE = 0.03
#: s of wall time a goal may take.
GOAL_TIMEOUT_S = 300.0


@pytest.fixture(scope="module")
def stack(start_lander):
    return start_lander()


@pytest.fixture(scope="module")
def model():
    return LanderModel()


@pytest.fixture(scope="module", autouse=True)
def _clients():
    """The module's clients, one per action (a client ignores the others' goals only with a
    logged error)."""
    CLIENTS.clear()
    yield
    CLIENTS.clear()


CLIENTS: dict[str, actionlib.SimpleActionClient] = {}


def stock_client(name: str) -> actionlib.SimpleActionClient:
    """actionlib's own client of OceanWATERS' action ``name``, its result and feedback
    subscriptions connected on the server's side (a result sent before is lost); one per action
    for the module."""
    if name in CLIENTS:
        return CLIENTS[name]
    client = CLIENTS[name] = actionlib.SimpleActionClient(name, getattr(owl, f"{name}Action"))
    wait_for_server(client, 60.0)
    for sub in (client.action_client.result_sub, client.action_client.feedback_sub):
        assert wait_sending(sub, 30.0), f"{name}: {sub.name} not connected"
    return client


def finish(client: actionlib.SimpleActionClient, goal) -> tuple[int, object, str]:
    """Send ``goal`` and wait (wall time) for its end: (state, result, status text)."""
    client.send_goal(goal)
    deadline = time.monotonic() + GOAL_TIMEOUT_S
    while client.simple_state != actionlib.SimpleGoalState.DONE:
        assert time.monotonic() < deadline, "the goal did not end"
        time.sleep(0.05)
    return client.get_state(), client.get_result(), client.get_goal_status_text()


def arm_joints() -> dict[str, float]:
    msg = rospy.wait_for_message("/joint_states", JointState, timeout=10)
    return {name: float(p) for name, p in zip(msg.name, msg.position, strict=True)}


def latest_terrain():
    return height_map_from_msg(rospy.wait_for_message("/sim/terrain", HeightMapMsg, timeout=10))


class DigPhases:
    """Every /ow_dynamic_terrain/scoop_dig_phase message from now on (the latched one first)."""

    def __init__(self) -> None:
        self.messages: list[ScoopDigPhase] = []
        self.sub = subscribe(DIG_PHASE_TOPIC, ScoopDigPhase, self.messages.append)
        deadline = time.monotonic() + 10.0
        while not self.messages:
            assert time.monotonic() < deadline, "no latched dig phase"
            time.sleep(0.01)

    def phases(self) -> list[int]:
        return [m.phase for m in self.messages]


def move_joints(pose: dict[str, float]) -> None:
    goal = owl.ArmMoveJointsGoal(False, [pose[j] for j in ARM_JOINTS])
    state, _, text = finish(stock_client("ArmMoveJoints"), goal)
    assert state == GoalStatus.SUCCEEDED, text


def unstow_from_here() -> str:
    """ArmUnstow with the stock client; it must succeed and end unstowed. Its status text."""
    state, _, text = finish(stock_client("ArmUnstow"), owl.ArmUnstowGoal())
    assert state == GoalStatus.SUCCEEDED, text
    time.sleep(0.5)  # wall: the arm settles on the unstowed pose
    joints = arm_joints()
    for joint in ARM_JOINTS:
        assert joints[joint] == pytest.approx(UNSTOWED[joint], abs=END_TOLERANCE), joint
    return text


def test_a_guarded_move_into_flat_ground_stops_on_it(stack, model):
    set_terrain(stack, f"flat:{GROUND}", lift_arm=True)
    move_joints(SCOOP_ABOVE_GROUND)  # the scoop level, its tip 5.5 cm above the ground
    X = model.fk(model.q_from(arm_joints()), SCOOP_TIP_FRAME)
    target = Pose(
        Point(*(X[:3, 3] - [0.0, 0.0, X[2, 3] - GROUND + 0.1])),
        Quaternion(*quaternion_from_rotation(X[:3, :3])),
    )
    goal = owl.ArmMoveCartesianGuardedGoal(0, False, target, FORCE_THRESHOLD, TORQUE_THRESHOLD)
    dig = DigPhases()
    try:
        state, result, text = finish(stock_client("ArmMoveCartesianGuarded"), goal)
    finally:
        dig.sub.unregister()
    assert state == GoalStatus.SUCCEEDED, text
    assert dig.phases() == [ScoopDigPhase.NOT_DIGGING]  # pressing is no dig
    assert result.final_force >= FORCE_THRESHOLD or result.final_torque >= TORQUE_THRESHOLD
    # Stopped on the ground, not in it; and the terrain did not give way.
    assert GROUND - 0.01 < result.final_pose.position.z < GROUND + 0.02
    terrain = latest_terrain()
    assert np.ptp(terrain.heights) == 0.0
    assert np.allclose(terrain.heights, GROUND, atol=1e-6)  # float32 on the wire


def test_unstow_recovers_a_buried_arm(stack, model):
    set_terrain(stack, f"flat:{GROUND}", lift_arm=True)
    move_joints(SCOOP_ABOVE_GROUND)
    # The terrain rises around the arm (paused, so that it is the flat map the arm services
    # receive before the simulation clears the tools' pockets in it).
    assert stack.service("/sim/pause", Trigger)().success
    try:
        set_terrain(stack, "flat:0.1")
    finally:
        assert stack.service("/sim/resume", Trigger)().success
    q = model.q_from(arm_joints())
    _, hand_depth = model.collision.terrain_contact(q, latest_terrain(), ("l_hand",))
    assert hand_depth > 0.1
    unstow_from_here()


#: (action, goal, m: the scoop tip's depth at which the dig is cancelled). The linear dig's cut
#: has the hand 6 mm under the carved terrain beside its trench.
AT = Point(1.65, 0.0, GROUND)
DIGS = [
    ("TaskScoopLinear", owl.TaskScoopLinearGoal(0, False, AT, 0.1, 0.3), 0.08),
    ("TaskScoopCircular", owl.TaskScoopCircularGoal(0, False, AT, 0.1, True), 0.06),
]


@pytest.mark.parametrize(("action", "goal", "cancel_at"), DIGS, ids=[d[0] for d in DIGS])
def test_unstow_recovers_from_a_dig_cancelled_deep_in_its_trench(
    stack, model, action, goal, cancel_at
):
    set_terrain(stack, f"flat:{GROUND}", lift_arm=True)
    depths: list[float] = []
    sub = subscribe("/sim/scoop_state", ToolState, lambda m: depths.append(m.depth))
    try:
        client = stock_client(action)
        client.send_goal(goal)
        deadline = time.monotonic() + GOAL_TIMEOUT_S
        while not depths or depths[-1] < cancel_at:
            assert client.simple_state != actionlib.SimpleGoalState.DONE, (
                client.get_goal_status_text()
            )
            assert time.monotonic() < deadline, f"the scoop never got {cancel_at} m deep"
            time.sleep(0.02)
        client.cancel_goal()
        while client.simple_state != actionlib.SimpleGoalState.DONE:
            assert time.monotonic() < deadline, "the cancelled dig did not end"
            time.sleep(0.02)
        assert client.get_state() == GoalStatus.PREEMPTED, client.get_goal_status_text()
    finally:
        sub.unregister()
    time.sleep(0.5)  # wall: the arm holds where it stopped
    tip = model.fk(model.q_from(arm_joints()), SCOOP_TIP_FRAME)[:3, 3]
    assert tip[2] < GROUND - cancel_at + 0.02  # still deep in the trench
    unstow_from_here()


def test_a_dig_goes_through_oceanwaters_dig_phases(stack):
    set_terrain(stack, f"flat:{GROUND}", lift_arm=True)
    dig = DigPhases()
    try:
        goal = owl.TaskScoopLinearGoal(0, False, AT, 0.05, 0.1)
        state, _, text = finish(stock_client("TaskScoopLinear"), goal)
        time.sleep(0.5)  # wall: the last phase's message
    finally:
        dig.sub.unregister()
    assert state == GoalStatus.SUCCEEDED, text
    assert dig.phases() == [
        ScoopDigPhase.NOT_DIGGING,  # latched
        ScoopDigPhase.SINKING,
        ScoopDigPhase.PLOWING,
        ScoopDigPhase.RETRACTING,
        ScoopDigPhase.NOT_DIGGING,
    ]
    assert [m.digging for m in dig.messages] == [False, True, True, True, False]
    stamps = [m.header.stamp.to_sec() for m in dig.messages[1:]]
    assert stamps == sorted(stamps) and stamps[0] > 0.0
    assert {m.header.frame_id for m in dig.messages} == {SCOOP_TIP_FRAME}
