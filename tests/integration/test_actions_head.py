"""OceanWATERS' (HEAD's) semantics of the arm and task actions, through actionlib's stock
``SimpleActionClient`` as OceanWATERS' own clients use it, on HEAD's flat ground (-0.172 m):
ArmFindSurface's surface normal and its SUCCEEDED ends, HEAD's texts for bad goals, ArmStop
on nothing and on a running goal, a guard that trips at once, the tool frame with ``relative``,
and where TaskGrind and TaskScoopLinear put their trenches (the tool tips from the recorded
joint states, by forward kinematics)."""

# ruff: noqa: E501  (the goal table reads best one case a line)

from __future__ import annotations

import functools
import math
import time

import actionlib
import numpy as np
import pytest
from actionlib_msgs.msg import GoalStatus
from geometry_msgs.msg import Point, Pose, Quaternion, Vector3
from sensor_msgs.msg import JointState

import owl_msgs.msg as owl
from ow_bringup.testing import subscribe, wait_for_server
from ow_description.description import GRINDER_TIP_FRAME, SCOOP_TIP_FRAME, UNSTOWED
from ow_description.model import LanderModel
from ow_lander.actions.owl import quaternion_from_rotation, rotation_from_quaternion

GROUND = -0.172  # m, OceanWATERS' DEFAULT_GROUND_HEIGHT
#: s of wall time a goal may take (the simulation runs at 20x real time).
END_WAIT_S = 180.0


@pytest.fixture(scope="module")
def stack(start_lander):
    return start_lander(terrain=f"flat:{GROUND}")


@pytest.fixture(scope="module")
def model():
    return LanderModel()


class Recorder:
    """The arm joints of every /joint_states sample while recording: (stamp s, {joint: rad})."""

    def __init__(self) -> None:
        self.samples: list[tuple[float, dict[str, float]]] = []
        self.recording = False
        self.sub = subscribe("/joint_states", JointState, self._on)

    def _on(self, msg: JointState) -> None:
        if self.recording:
            self.samples.append(
                (msg.header.stamp.to_sec(), dict(zip(msg.name, msg.position, strict=True)))
            )

    def tips(self, model: LanderModel, frame: str) -> np.ndarray:
        """(n, 3) m, ``frame`` in base_link at each recorded sample."""
        return np.array(
            [model.fk(model.q_from(joints), frame)[:3, 3] for _, joints in self.samples]
        )


@pytest.fixture(scope="module")
def recorder(stack):
    rec = Recorder()
    yield rec
    rec.sub.unregister()


@functools.cache
def client(name: str) -> actionlib.SimpleActionClient:
    """actionlib's own client of ``name``, connected (its result topic too)."""
    c = actionlib.SimpleActionClient(name, getattr(owl, f"{name}Action"))
    wait_for_server(c, 60)
    deadline = time.monotonic() + 30
    while c.action_client.result_sub.get_num_connections() == 0:
        assert time.monotonic() < deadline, f"{name}: result topic not connected"
        time.sleep(0.01)
    return c


def wait_done(c: actionlib.SimpleActionClient, what: str, timeout_s: float = END_WAIT_S) -> None:
    """Wait in wall time (``wait_for_result`` counts the simulation's) until the goal is done."""
    deadline = time.monotonic() + timeout_s
    while c.simple_state != actionlib.SimpleGoalState.DONE:
        assert time.monotonic() < deadline, f"{what} did not end for the stock client"
        time.sleep(0.01)


def run(name: str, goal, feedback=None):
    """Send ``goal`` with the stock client and wait: (state, result, status text)."""
    c = client(name)
    c.send_goal(goal, feedback_cb=feedback)
    wait_done(c, name)
    return c.get_state(), c.get_result(), c.get_goal_status_text()


def unstow() -> None:
    state, _, text = run("ArmUnstow", owl.ArmUnstowGoal())
    assert (state, text) == (GoalStatus.SUCCEEDED, "ArmUnstow trajectory succeeded")


def _find_surface(**kw):
    fields = dict(frame=0, relative=False, position=Point(1.7, 0.5, GROUND),
                  normal=Vector3(0, 0, 1), distance=0.2, overdrive=0.05,
                  force_threshold=200.0, torque_threshold=100.0)  # fmt: skip
    fields.update(kw)
    return owl.ArmFindSurfaceGoal(**fields)


def test_find_surface_normal_is_the_surface_normal(stack):
    unstow()
    feedback = []
    state, result, text = run("ArmFindSurface", _find_surface(), feedback.append)
    assert state == GoalStatus.SUCCEEDED, text
    assert text.startswith("ArmFindSurface trajectory stopped by a force of ")
    p = result.final_pose.position
    assert f". Surface found at ({p.x:.3f}, {p.y:.3f}, {p.z:.3f})" in text
    assert p.z == pytest.approx(GROUND, abs=0.01)
    # The arm gives a little under 200 N: the scoop is held a few cm from where it touched.
    assert (p.x, p.y) == pytest.approx((1.7, 0.5), abs=0.05)
    gap = np.linalg.norm(np.subtract([p.x, p.y, p.z], [1.7, 0.5, GROUND]))
    assert result.final_distance == pytest.approx(gap, abs=1e-6)  # from the surface point
    assert result.final_force >= 200.0 or result.final_torque >= 100.0
    # Feedback: distance, force and torque 0 until the approach begins, then the distance.
    assert feedback and feedback[0].distance == 0.0 and feedback[0].force == 0.0
    approach = [f for f in feedback if f.distance > 0.0]
    assert approach[0].distance == pytest.approx(0.2, abs=0.01)
    # On the approach, the scoop's bottom against the normal and its x along base_link's x
    # (OceanWATERS' pose; under 200 N at the end the arm gives a little).
    o = approach[0].pose.orientation
    R = rotation_from_quaternion([o.x, o.y, o.z, o.w])
    assert R[:, 2] @ [0.0, 0.0, -1.0] > math.cos(0.05)
    assert R[:, 0] @ [1.0, 0.0, 0.0] > math.cos(0.05)


def test_find_surface_without_a_surface_succeeds(stack):
    # Above the ground (OceanWATERS' test_11): the approach ends 0.1 m below the "surface" it
    # was given, still 0.4 m above the ground.
    goal = _find_surface(position=Point(1.86, -0.63, GROUND + 0.5), distance=0.1, overdrive=0.1)
    state, result, text = run("ArmFindSurface", goal)
    assert (state, text) == (GoalStatus.SUCCEEDED, "No surface was found")
    assert result.final_pose.position.z == pytest.approx(GROUND + 0.4, abs=0.01)
    assert result.final_distance == pytest.approx(0.1, abs=0.01)


BAD = [
    ("ArmFindSurface", _find_surface(normal=Vector3(0, 0, 0)),
     "Normal is the zero-vector and cannot represent a direction"),
    ("ArmMoveCartesian", owl.ArmMoveCartesianGoal(0, False, Pose(Point(1.7, 0, 0.3), Quaternion())),
     "Orientation is the zero-quaternion and cannot represent a rotation"),
    ("ArmMoveCartesian", owl.ArmMoveCartesianGoal(2, False, Pose(Point(1.7, 0, 0.3), Quaternion(0, 0, 0, 1))),
     "Unrecognized frame index 2. Options are {0: 'base_link', 1: 'l_scoop_tip'}"),
    ("ArmMoveJoint", owl.ArmMoveJointGoal(False, 6, 0.1),
     "Provided joint index is not within range: joint=6, not in 0..5"),
    ("TaskScoopLinear", owl.TaskScoopLinearGoal(0, False, Point(1.6, float("nan"), GROUND), 0.01, 0.1),
     "point.y=nan is not finite"),
]  # fmt: skip


@pytest.mark.parametrize(("name", "goal", "text"), BAD, ids=[b[0] for b in BAD])
def test_bad_goal_aborted_with_oceanwaters_text(stack, name, goal, text):
    state, _, status = run(name, goal)
    assert (state, status) == (GoalStatus.ABORTED, text)


def test_arm_stop_with_nothing_to_stop(stack):
    state, _, text = run("ArmStop", owl.ArmStopGoal())
    assert (state, text) == (GoalStatus.ABORTED, "No arm trajectory to stop")


def test_arm_stop_ends_the_running_goal_aborted(stack, recorder):
    unstow()
    move = client("ArmMoveJoint")
    recorder.samples.clear()
    recorder.recording = True
    try:
        move.send_goal(owl.ArmMoveJointGoal(True, 0, 0.8))  # several s of shoulder yaw
        deadline = time.monotonic() + 60
        while (
            not recorder.samples
            or abs(recorder.samples[-1][1]["j_shou_yaw"] - UNSTOWED["j_shou_yaw"]) < 0.1
        ):
            assert time.monotonic() < deadline, "the shoulder yaw did not start moving"
            time.sleep(0.005)
        state, _, text = run("ArmStop", owl.ArmStopGoal())
        wait_done(move, "ArmMoveJoint")
    finally:
        recorder.recording = False
    assert (state, text) == (GoalStatus.SUCCEEDED, "Arm trajectory stopped")
    assert move.get_state() == GoalStatus.ABORTED
    assert move.get_goal_status_text() == "Stop was called; trajectory execution ceased"
    assert move.get_result().final_angles[0] < UNSTOWED["j_shou_yaw"] + 0.75


def test_a_zero_threshold_trips_at_once(stack, recorder):
    unstow()
    recorder.samples.clear()
    recorder.recording = True
    try:
        goal = owl.ArmMoveJointsGuardedGoal(True, [0.3, 0, 0, 0, 0, 0], 0.0, 0.0)
        state, result, text = run("ArmMoveJointsGuarded", goal)
    finally:
        recorder.recording = False
    assert state == GoalStatus.SUCCEEDED, text
    assert text.startswith("ArmMoveJointsGuarded trajectory stopped by a force of ")
    assert " N and a torque of " in text
    assert result.final_angles[0] == pytest.approx(UNSTOWED["j_shou_yaw"], abs=0.01)


def test_tool_frame_relative_is_the_tool_frame(stack, model):
    unstow()
    X0 = model.fk(model.q_from(dict(UNSTOWED)), SCOOP_TIP_FRAME)
    offset = np.array([0.0, 0.05, 0.05])
    pose = Pose(Point(*offset), Quaternion(0, 0, 0, 1))
    state, result, text = run("ArmMoveCartesian", owl.ArmMoveCartesianGoal(1, True, pose))
    assert (state, text) == (GoalStatus.SUCCEEDED, "ArmMoveCartesian trajectory succeeded")
    p = result.final_pose.position
    assert np.allclose([p.x, p.y, p.z], X0[:3, :3] @ offset + X0[:3, 3], atol=0.01)


def test_relative_rotation_turns_the_tool_about_its_own_axes(stack, model):
    unstow()
    X0 = model.fk(model.q_from(dict(UNSTOWED)), SCOOP_TIP_FRAME)
    turn = Quaternion(0, 0, math.sin(0.2), math.cos(0.2))  # 0.4 rad about z
    goal = owl.ArmMoveCartesianGoal(0, True, Pose(Point(0, 0, 0), turn))
    state, result, text = run("ArmMoveCartesian", goal)
    assert (state, text) == (GoalStatus.SUCCEEDED, "ArmMoveCartesian trajectory succeeded")
    o = result.final_pose.orientation
    expected = X0[:3, :3] @ rotation_from_quaternion([0, 0, math.sin(0.2), math.cos(0.2)])
    q_expected = quaternion_from_rotation(expected)
    assert abs(float(np.dot([o.x, o.y, o.z, o.w], q_expected))) > math.cos(0.05 / 2)


def test_grind_is_centred_between_its_passes_at_oceanwaters_depth(stack, model, recorder):
    unstow()
    recorder.samples.clear()
    recorder.recording = True
    try:
        state, result, text = run("TaskGrind", owl.TaskGrindGoal(1.8, 0.0, 0.15, 0.4, 1.0, GROUND))
    finally:
        recorder.recording = False
    assert (state, text) == (GoalStatus.SUCCEEDED, "TaskGrind trajectory succeeded")
    tips = recorder.tips(model, GRINDER_TIP_FRAME)
    deep = tips[tips[:, 2] < GROUND - 0.14]
    assert deep[:, 2].min() == pytest.approx(GROUND - 0.15, abs=0.015)
    # Radial passes, 0.4 m long and 0.08 m apart, centred on (1.8, 0).
    assert (deep[:, 0].min(), deep[:, 0].max()) == pytest.approx((1.6, 2.0), abs=0.02)
    assert (deep[:, :2].max(axis=0) + deep[:, :2].min(axis=0)) / 2 == pytest.approx(
        [1.8, 0.0], abs=0.02
    )
    assert result.final.z > GROUND  # the scoop tip where the arm ended, not (0, 0, 0)


def test_scoop_linear_point_is_the_middle_of_the_cut(stack, model, recorder):
    unstow()
    recorder.samples.clear()
    recorder.recording = True
    try:
        goal = owl.TaskScoopLinearGoal(0, False, Point(1.6, 0.3, GROUND), 0.03, 0.2)
        state, _, text = run("TaskScoopLinear", goal)
    finally:
        recorder.recording = False
    assert (state, text) == (GoalStatus.SUCCEEDED, "TaskScoopLinear trajectory succeeded")
    tips = recorder.tips(model, SCOOP_TIP_FRAME)
    cut = tips[tips[:, 2] < GROUND - 0.025]
    ends = cut[[np.argmin(cut[:, 0]), np.argmax(cut[:, 0])]]
    assert ends.mean(axis=0)[:2] == pytest.approx([1.6, 0.3], abs=0.02)
    assert np.linalg.norm(ends[1] - ends[0]) == pytest.approx(0.2, abs=0.03)
