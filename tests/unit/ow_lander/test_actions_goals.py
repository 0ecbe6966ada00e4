"""OceanWATERS' action goals: validation (every bad field named with its value and limit) and
the mapping onto the paper's operations (no ROS master)."""
# ruff: noqa: E501  (the goal tables read best one case a line)

import math

import numpy as np
import pytest
from geometry_msgs.msg import Point, Pose, Quaternion, Vector3

import owl_msgs.msg as owl
from ow_description.description import ARM_JOINTS, SCOOP_TIP_FRAME, UNSTOWED
from ow_description.model import LanderModel
from ow_lander import conversions as conv
from ow_lander.actions.owl import (
    ArmState,
    action_values,
    arm_state,
    pose_error,
    quaternion_from_rotation,
    rotation_from_quaternion,
    target_pose,
    to_request,
    validate_goal,
)
from ow_lander.errors import GoalError

NAN, INF = float("nan"), float("inf")
GROUND = -0.155
POSE = Pose(Point(1.6, 0.0, 0.2), Quaternion(0, 0, 0, 1))
ARM = np.array([UNSTOWED[j] for j in ARM_JOINTS])
#: The tool 1 m out along x, turned 90 degrees about z.
X_TIP = np.array([[0.0, -1.0, 0.0, 1.0], [1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.5], [0, 0, 0, 1]])


def surface(**kw):
    fields = dict(frame=0, relative=False, position=Point(1.7, 0, GROUND),
                  normal=Vector3(0, 0, -1), distance=0.2, overdrive=0.05,
                  force_threshold=10.0, torque_threshold=5.0)  # fmt: skip
    fields.update(kw)
    return owl.ArmFindSurfaceGoal(**fields)


BAD = [
    ("ArmMoveJoint", owl.ArmMoveJointGoal(False, 6, 0.1), "joint=6 is outside the joint indices 0..5"),
    ("ArmMoveJoint", owl.ArmMoveJointGoal(False, -1, 0.1), "joint=-1 is outside"),
    ("ArmMoveJoint", owl.ArmMoveJointGoal(False, 0, NAN), "angle=nan is not finite"),
    ("ArmMoveJoints", owl.ArmMoveJointsGoal(False, [0.0] * 5), "must have 6 values"),
    ("ArmMoveJoints", owl.ArmMoveJointsGoal(False, [0, 0, INF, 0, 0, 0]), "angles[2]=inf is not finite"),
    ("ArmMoveJointsGuarded", owl.ArmMoveJointsGuardedGoal(False, [0.0] * 6, 0.0, 1.0), "force_threshold=0.0 must be > 0"),
    ("ArmMoveJointsGuarded", owl.ArmMoveJointsGuardedGoal(False, [0.0] * 6, 1.0, -2.0), "torque_threshold=-2.0 must be > 0"),
    ("ArmMoveCartesian", owl.ArmMoveCartesianGoal(2, False, POSE), "frame=2 is neither 0 (base_link) nor 1 (tool)"),
    ("ArmMoveCartesian", owl.ArmMoveCartesianGoal(0, False, Pose(Point(NAN, 0, 0), Quaternion(0, 0, 0, 1))), "pose.position.x=nan is not finite"),
    ("ArmMoveCartesian", owl.ArmMoveCartesianGoal(0, False, Pose(Point(1, 0, 0), Quaternion(0, 0, 0, 0))), "pose.orientation=[0.0, 0.0, 0.0, 0.0] is a zero quaternion"),
    ("ArmMoveCartesianGuarded", owl.ArmMoveCartesianGuardedGoal(0, False, POSE, INF, 1.0), "force_threshold=inf is not finite"),
    ("ArmFindSurface", surface(normal=Vector3(0, 0, 0)), "normal=[0.0, 0.0, 0.0] is a zero vector"),
    ("ArmFindSurface", surface(frame=-1), "frame=-1 is neither"),
    ("ArmFindSurface", surface(distance=0.0), "distance=0.0 must be > 0"),
    ("ArmFindSurface", surface(overdrive=-0.1), "overdrive=-0.1 must be >= 0"),
    ("ArmFindSurface", surface(torque_threshold=0.0), "torque_threshold=0.0 must be > 0"),
    ("TaskGrind", owl.TaskGrindGoal(1.65, 0.0, NAN, 0.6, 1.0, GROUND), "depth=nan is not finite"),
    ("TaskScoopLinear", owl.TaskScoopLinearGoal(3, False, Point(1.46, 0, GROUND), 0.01, 0.1), "frame=3"),
    ("TaskScoopCircular", owl.TaskScoopCircularGoal(0, False, Point(1.6, NAN, GROUND), 0.01, True), "point.y=nan"),
    ("TaskDiscardSample", owl.TaskDiscardSampleGoal(0, False, Point(1.5, 0.8, 0), -0.3), "height=-0.3 must be >= 0"),
    ("PanTiltMoveJoints", owl.PanTiltMoveJointsGoal(0.0, 0.0), "unknown action 'PanTiltMoveJoints'"),
]  # fmt: skip


@pytest.mark.parametrize(("action", "goal", "message"), BAD, ids=[b[2][:30] for b in BAD])
def test_bad_goal_names_field_value_and_limit(action, goal, message):
    with pytest.raises(GoalError) as error:
        validate_goal(action, conv.goal_to_dict(goal))
    assert message in str(error.value)


GOOD = [
    ("ArmUnstow", owl.ArmUnstowGoal()),
    ("ArmMoveJoint", owl.ArmMoveJointGoal(True, 5, -0.3)),
    ("ArmMoveJointsGuarded", owl.ArmMoveJointsGuardedGoal(False, [0.1] * 6, 1.0, 1.0)),
    ("ArmMoveCartesian", owl.ArmMoveCartesianGoal(1, True, POSE)),
    ("ArmFindSurface", surface()),
    ("TaskGrind", owl.TaskGrindGoal(1.65, 0.0, 0.05, 0.6, 1.0, GROUND)),
    ("TaskDiscardSample", owl.TaskDiscardSampleGoal(0, False, Point(1.5, 0.8, 0), 0.3)),
]


@pytest.mark.parametrize(("action", "goal"), GOOD, ids=[g[0] for g in GOOD])
def test_good_goals_pass(action, goal):
    validate_goal(action, conv.goal_to_dict(goal))


def _request(action, goal):
    return to_request(action, conv.goal_to_dict(goal), ARM, X_TIP, lambda x, y: 0.0)


def test_joint_goals_in_shoulder_to_scoop_order():
    absolute = _request("ArmMoveJoint", owl.ArmMoveJointGoal(False, 2, -1.0))
    assert absolute.operation == "move_joints"
    assert absolute.request["angles"] == [*ARM[:2], -1.0, *ARM[3:]]
    relative = _request("ArmMoveJoint", owl.ArmMoveJointGoal(True, 5, 0.25))
    assert np.allclose(relative.request["angles"], [*ARM[:5], ARM[5] + 0.25])
    guarded = _request("ArmMoveJointsGuarded", owl.ArmMoveJointsGuardedGoal(True, [0.1] * 6, 9, 3))
    assert np.allclose(guarded.request["angles"], ARM + 0.1)
    assert guarded.request["guarded"] and not absolute.request.get("guarded")
    assert guarded.wrench_limits == (9.0, 3.0)


def test_find_surface_maps_onto_the_guarded_move():
    request = _request("ArmFindSurface", surface())
    assert request.operation == "guarded_move"
    assert request.wrench_limits == (10.0, 5.0)
    assert np.allclose(request.surface_point, [1.7, 0, GROUND])
    r = request.request
    assert (r["x"], r["y"]) == (1.7, 0.0)
    assert r["z"] == pytest.approx(GROUND + 0.2)  # distance before the point, against normal
    assert (r["direction_x"], r["direction_y"], r["direction_z"]) == (0.0, 0.0, 1.0)
    assert r["search_distance"] == pytest.approx(0.25)  # distance + overdrive


def test_points_in_the_tool_frame_and_relative():
    tool = _request("ArmFindSurface", surface(frame=1, position=Point(0.1, 0, 0)))
    assert np.allclose(tool.surface_point, [1.0, 0.1, 0.5])
    relative = _request("ArmFindSurface", surface(relative=True, position=Point(0.1, 0, 0)))
    assert np.allclose(relative.surface_point, [1.1, 0.0, 0.5])


def test_cartesian_targets():
    tool = _request("ArmMoveCartesian", owl.ArmMoveCartesianGoal(1, False, POSE))
    offset = np.eye(4)
    offset[:3, 3] = [1.6, 0.0, 0.2]
    assert np.allclose(tool.target_pose, X_TIP @ offset)
    turn = Quaternion(0, 0, math.sin(math.pi / 4), math.cos(math.pi / 4))
    relative = _request(
        "ArmMoveCartesian", owl.ArmMoveCartesianGoal(0, True, Pose(Point(0, 0, -0.1), turn))
    )
    assert np.allclose(relative.target_pose[:3, 3], [1.0, 0.0, 0.4])
    assert np.allclose(
        relative.target_pose[:3, :3], rotation_from_quaternion([0, 0, 1, 1]) @ X_TIP[:3, :3]
    )
    assert relative.operation == "move_cartesian" and relative.wrench_limits is None
    guarded = _request(
        "ArmMoveCartesianGuarded", owl.ArmMoveCartesianGuardedGoal(0, False, POSE, 5, 2)
    )
    assert guarded.wrench_limits == (5.0, 2.0)
    assert np.allclose(
        target_pose(conv.goal_to_dict(owl.ArmMoveCartesianGoal(0, False, POSE)), X_TIP)[:3, 3],
        [1.6, 0, 0.2],
    )


def test_tasks_map_onto_the_operations():
    grind = _request("TaskGrind", owl.TaskGrindGoal(1.65, 0.1, 0.05, 0.6, 0.0, GROUND))
    assert grind.operation == "grind"
    assert grind.request["parallel"] is False
    assert grind.request["x"] == pytest.approx(1.65) and grind.request["depth"] == pytest.approx(
        0.05
    )
    linear = _request(
        "TaskScoopLinear", owl.TaskScoopLinearGoal(0, False, Point(1.5, 0, GROUND), 0.02, 0.2)
    )
    assert linear.operation == "dig_linear"
    # OceanWATERS' point is the middle of the cut (heading yaw 0 here): ours starts 0.1 m before.
    assert (linear.request["x"], linear.request["y"]) == pytest.approx((1.4, 0.0))
    assert linear.request["ground_position"] == GROUND and linear.request["length"] == 0.2
    circular = _request(
        "TaskScoopCircular",
        owl.TaskScoopCircularGoal(0, False, Point(1.6, 0.1, GROUND), 0.03, False),
    )
    assert circular.operation == "dig_circular" and circular.request["parallel"] is False
    assert (circular.request["x"], circular.request["y"], circular.request["depth"]) == (
        1.6,
        0.1,
        0.03,
    )
    discard = _request(
        "TaskDiscardSample", owl.TaskDiscardSampleGoal(0, False, Point(1.5, 0.8, 0), 0.3)
    )
    assert discard.operation == "discard"
    assert (discard.request["x"], discard.request["y"], discard.request["z"]) == pytest.approx(
        (1.5, 0.8, 0.3)
    )
    assert _request("TaskDeliverSample", owl.TaskDeliverSampleGoal()).operation == "deliver_sample"
    assert _request("ArmStow", owl.ArmStowGoal()).operation == "stow"


@pytest.mark.parametrize("axis", [(1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 1, 1)])
@pytest.mark.parametrize("angle", [0.0, 0.7, 3.0, -2.0])
def test_quaternion_round_trip(axis, angle):
    a = np.array(axis, dtype=float) / np.linalg.norm(axis)
    q = np.r_[a * math.sin(angle / 2), math.cos(angle / 2)]
    R = rotation_from_quaternion(q)
    assert np.allclose(rotation_from_quaternion(quaternion_from_rotation(R)), R)
    assert pose_error(np.eye(4), np.block([[R, np.zeros((3, 1))], [0, 0, 0, 1]]))[
        1
    ] == pytest.approx(abs(angle))


def test_feedback_and_result_values_from_a_joint_state():
    model = LanderModel()
    joints = dict(UNSTOWED)
    state = arm_state(model, joints, np.array([3.0, 4.0, 0.0]), np.array([0.0, 0.0, 2.0]))
    assert np.allclose(state.angles, ARM)
    assert np.allclose(state.X_base_tip, model.fk(model.q_from(joints), SCOOP_TIP_FRAME))
    assert (state.force, state.torque) == (5.0, 2.0)
    values = action_values(state, np.array([1.736, 0.255, 0.0]))
    assert values["final_angles"] == pytest.approx(list(ARM))
    position, quaternion = values["final_pose"]
    assert np.allclose(position, state.X_base_tip[:3, 3])
    assert np.allclose(rotation_from_quaternion(quaternion), state.X_base_tip[:3, :3])
    assert values["distance"] == pytest.approx(
        np.linalg.norm(np.subtract(position, [1.736, 0.255, 0.0]))
    )
    result = conv.fill_fields(owl.ArmFindSurfaceResult(), values)
    assert result.final_force == 5.0 and result.final_pose.position.x == position[0]
    grind = conv.fill_fields(owl.TaskGrindFeedback(), action_values(ArmState(ARM, np.eye(4), 0, 0)))
    assert (grind.current.x, grind.current.y, grind.current.z) == (0.0, 0.0, 0.0)
