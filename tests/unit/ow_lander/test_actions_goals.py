"""OceanWATERS' action goals: what HEAD checks (with its texts), the NaNs it lets through, and
the mapping onto the paper's operations with HEAD's semantics (no ROS master)."""
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
    angles_reached,
    arm_state,
    pose_error,
    quaternion_from_rotation,
    rotation_between,
    rotation_from_quaternion,
    target_pose,
    to_request,
    validate_goal,
)
from ow_lander.errors import GoalError

NAN, INF = float("nan"), float("inf")
GROUND = -0.172
POSE = Pose(Point(1.6, 0.0, 0.2), Quaternion(0, 0, 0, 1))
ARM = np.array([UNSTOWED[j] for j in ARM_JOINTS])
#: The tool 1 m out along x, turned 90 degrees about z.
X_TIP = np.array([[0.0, -1.0, 0.0, 1.0], [1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.5], [0, 0, 0, 1]])
FRAMES_TEXT = "Options are {0: 'base_link', 1: 'l_scoop_tip'}"


def surface(**kw):
    fields = dict(frame=0, relative=False, position=Point(1.7, 0.5, GROUND),
                  normal=Vector3(0, 0, 1), distance=0.2, overdrive=0.05,
                  force_threshold=200.0, torque_threshold=100.0)  # fmt: skip
    fields.update(kw)
    return owl.ArmFindSurfaceGoal(**fields)


BAD = [
    ("ArmMoveJoint", owl.ArmMoveJointGoal(False, 6, 0.1), "Provided joint index is not within range: joint=6"),
    ("ArmMoveJoint", owl.ArmMoveJointGoal(False, -1, 0.1), "Provided joint index is not within range: joint=-1"),
    ("ArmMoveJoint", owl.ArmMoveJointGoal(False, 0, NAN), "angle=nan is not finite"),
    ("ArmMoveJoints", owl.ArmMoveJointsGoal(False, [0.0] * 5), "Number of angle positions provided does not much the number of joints in the arm move group: angles=[0.0, 0.0, 0.0, 0.0, 0.0] has 5 values, 6 needed"),
    ("ArmMoveJoints", owl.ArmMoveJointsGoal(False, [0, 0, INF, 0, 0, 0]), "angles[2]=inf is not finite"),
    ("ArmMoveJointsGuarded", owl.ArmMoveJointsGuardedGoal(False, [0.0] * 6, NAN, 1.0), "force_threshold=nan is not finite"),
    ("ArmMoveCartesian", owl.ArmMoveCartesianGoal(2, False, POSE), f"Unrecognized frame index 2. {FRAMES_TEXT}"),
    ("ArmMoveCartesian", owl.ArmMoveCartesianGoal(0, False, Pose(Point(NAN, 0, 0), Quaternion(0, 0, 0, 1))), "pose.position.x=nan is not finite"),
    ("ArmMoveCartesian", owl.ArmMoveCartesianGoal(0, False, Pose(Point(1, 0, 0), Quaternion(0, 0, 0, 0))), "Orientation is the zero-quaternion and cannot represent a rotation"),
    ("ArmMoveCartesianGuarded", owl.ArmMoveCartesianGuardedGoal(0, False, POSE, 1.0, NAN), "torque_threshold=nan is not finite"),
    ("ArmFindSurface", surface(normal=Vector3(0, 0, 0)), "Normal is the zero-vector and cannot represent a direction"),
    ("ArmFindSurface", surface(frame=-1), f"Unrecognized frame index -1. {FRAMES_TEXT}"),
    ("ArmFindSurface", surface(distance=INF), "distance=inf is not finite"),
    ("TaskGrind", owl.TaskGrindGoal(1.65, 0.0, NAN, 0.6, 1.0, GROUND), "depth=nan is not finite"),
    ("TaskScoopLinear", owl.TaskScoopLinearGoal(3, False, Point(1.46, 0, GROUND), 0.01, 0.1), "Unrecognized frame index 3"),
    ("TaskScoopCircular", owl.TaskScoopCircularGoal(0, False, Point(1.6, NAN, GROUND), 0.01, True), "point.y=nan is not finite"),
    ("TaskDiscardSample", owl.TaskDiscardSampleGoal(0, False, Point(1.5, 0.8, 0), NAN), "height=nan is not finite"),
    ("PanTiltMoveJoints", owl.PanTiltMoveJointsGoal(0.0, 0.0), "unknown action 'PanTiltMoveJoints'"),
]  # fmt: skip


@pytest.mark.parametrize(("action", "goal", "message"), BAD, ids=[b[2][:40] for b in BAD])
def test_bad_goal_has_oceanwaters_text_or_names_the_value(action, goal, message):
    with pytest.raises(GoalError) as error:
        validate_goal(action, conv.goal_to_dict(goal))
    assert message in str(error.value)


#: What OceanWATERS accepts, so do we: it never checks depths, lengths, heights, distances or
#: overdrives, and a threshold <= 0 (the message default) is a guard that trips at once.
GOOD = [
    ("ArmUnstow", owl.ArmUnstowGoal()),
    ("ArmMoveJoint", owl.ArmMoveJointGoal(True, 5, -0.3)),
    ("ArmMoveJointsGuarded", owl.ArmMoveJointsGuardedGoal(False, [0.1] * 6, 0.0, 0.0)),
    ("ArmMoveJointsGuarded", owl.ArmMoveJointsGuardedGoal(False, [0.1] * 6, INF, -1.0)),
    ("ArmMoveJoints", owl.ArmMoveJointsGoal(False, [0.84, 1.48, 7.87, -0.31, 3.47, 2.29])),
    ("ArmMoveCartesian", owl.ArmMoveCartesianGoal(1, True, POSE)),
    ("ArmMoveCartesian", owl.ArmMoveCartesianGoal(0, False, Pose(Point(1, 0, 0), Quaternion(0, 0, 0, 2)))),
    ("ArmFindSurface", surface()),
    ("ArmFindSurface", surface(distance=-0.1, overdrive=-0.2, force_threshold=0.0)),
    ("ArmFindSurface", surface(normal=Vector3(0, 0, 5))),
    ("TaskGrind", owl.TaskGrindGoal(1.6, 0.0, 0.15, 0.8, 1.0, GROUND)),
    ("TaskGrind", owl.TaskGrindGoal(1.6, 0.0, -0.1, 3.0, 0.0, GROUND)),
    ("TaskScoopLinear", owl.TaskScoopLinearGoal(0, False, Point(1.4, 0, GROUND), 0.3, 0.0)),
    ("TaskDiscardSample", owl.TaskDiscardSampleGoal(0, False, Point(1.5, 0.8, 0), -0.3)),
]  # fmt: skip


@pytest.mark.parametrize(("action", "goal"), GOOD, ids=[f"{g[0]}-{i}" for i, g in enumerate(GOOD)])
def test_what_oceanwaters_accepts_passes(action, goal):
    validate_goal(action, conv.goal_to_dict(goal))


def _request(action, goal):
    return to_request(action, conv.goal_to_dict(goal), ARM, X_TIP)


def test_joint_goals_in_shoulder_to_scoop_order():
    absolute = _request("ArmMoveJoint", owl.ArmMoveJointGoal(False, 2, -1.0))
    assert absolute.operation == "move_joints"
    assert absolute.request["angles"] == [*ARM[:2], -1.0, *ARM[3:]]
    assert np.allclose(absolute.target_angles, absolute.request["angles"])
    relative = _request("ArmMoveJoint", owl.ArmMoveJointGoal(True, 5, 0.25))
    assert np.allclose(relative.request["angles"], [*ARM[:5], ARM[5] + 0.25])
    guarded = _request("ArmMoveJointsGuarded", owl.ArmMoveJointsGuardedGoal(True, [0.1] * 6, 9, 3))
    assert np.allclose(guarded.request["angles"], ARM + 0.1)
    assert guarded.request["guarded"] and not absolute.request.get("guarded")
    assert guarded.wrench_limits == (9.0, 3.0)
    assert not guarded.breaches_at_once


@pytest.mark.parametrize(
    ("force", "torque", "at_once"),
    [(0.0, 0.0, True), (0.0, 5.0, True), (5.0, -1.0, True), (5.0, 5.0, False), (INF, INF, False)],
)
def test_a_threshold_at_or_below_zero_trips_at_once(force, torque, at_once):
    goal = owl.ArmMoveJointsGuardedGoal(False, [0.1] * 6, force, torque)
    assert _request("ArmMoveJointsGuarded", goal).breaches_at_once is at_once


def test_angles_reached_modulo_a_turn():
    target = np.array([0.84, 1.48, 7.87, -0.31, 3.47, 2.29])
    assert angles_reached(target, target - [0, 0, 2 * math.pi, 0, 2 * math.pi, 0])
    assert angles_reached(target, target + 0.049)
    assert not angles_reached(target, target + np.array([0, 0, 0, 0.051, 0, 0]))


def test_find_surface_starts_distance_along_the_normal_and_ends_overdrive_past_the_surface():
    request = _request("ArmFindSurface", surface())
    assert request.operation == "guarded_move"
    assert request.wrench_limits == (200.0, 100.0)
    assert np.allclose(request.surface_point, [1.7, 0.5, GROUND])
    r = request.request
    assert (r["x"], r["y"], r["z"]) == pytest.approx((1.7, 0.5, GROUND + 0.2))
    assert (r["direction_x"], r["direction_y"], r["direction_z"]) == (0.0, 0.0, 1.0)
    assert r["search_distance"] == pytest.approx(0.25)  # distance + overdrive
    assert np.allclose(request.approach_end, [1.7, 0.5, GROUND - 0.05])
    # Scoop bottom (+z) against the normal: half a turn about x, its x along base_link's x.
    assert np.allclose(r["rotation"], np.diag([1.0, -1.0, -1.0]))


def test_find_surface_on_a_tilted_normal():
    normal = np.array([0.1, 0.3, 0.8124]) / np.linalg.norm([0.1, 0.3, 0.8124])
    request = _request(
        "ArmFindSurface",
        surface(
            position=Point(1.86, -0.63, GROUND),
            normal=Vector3(0.1, 0.3, 0.8124),
            distance=0.2,
            overdrive=0.1,
        ),
    )
    R = np.asarray(request.request["rotation"])
    assert np.allclose(R[:, 2], -normal)
    assert np.allclose(R.T @ R, np.eye(3))
    # OceanWATERS' orientation there: quaternion (0.932, -0.311, 0, 0.185).
    assert np.allclose(
        np.abs(quaternion_from_rotation(R) @ [0.932, -0.311, 0.0, 0.185]), 1, atol=1e-3
    )
    assert np.allclose(request.setup_point, [1.86, -0.63, GROUND] + 0.2 * normal)
    assert np.allclose(request.approach_end, [1.86, -0.63, GROUND] - 0.1 * normal)


def test_find_surface_with_a_zero_threshold_only_moves_to_the_setup_pose():
    request = _request("ArmFindSurface", surface(force_threshold=0.0, torque_threshold=0.0))
    assert request.operation == "move_cartesian" and request.breaches_at_once
    assert request.request["position"] == pytest.approx([1.7, 0.5, GROUND + 0.2])


@pytest.mark.parametrize("b", [(0, 0, -1), (0, 0, 1), (1, 0, 0), (0.3, -0.2, 0.9), (0, 0.6, -0.8)])
def test_rotation_between_takes_z_onto_the_direction(b):
    R = rotation_between([0, 0, 1], b)
    assert np.allclose(R[:, 2], np.asarray(b) / np.linalg.norm(b))
    assert np.allclose(R.T @ R, np.eye(3)) and np.linalg.det(R) == pytest.approx(1.0)


def test_points_in_the_tool_frame_and_relative():
    tool = _request("ArmFindSurface", surface(frame=1, position=Point(0.1, 0, 0)))
    assert np.allclose(tool.surface_point, [1.0, 0.1, 0.5])
    # In the tool's own frame the tool is at the origin: relative changes nothing.
    tool_relative = _request(
        "ArmFindSurface", surface(frame=1, relative=True, position=Point(0.1, 0, 0))
    )
    assert np.allclose(tool_relative.surface_point, tool.surface_point)
    relative = _request("ArmFindSurface", surface(relative=True, position=Point(0.1, 0, 0)))
    assert np.allclose(relative.surface_point, [1.1, 0.0, 0.5])
    # The normal stays in base_link whatever the frame.
    assert np.allclose(tool.surface_normal, [0, 0, 1])


def test_cartesian_targets():
    tool = _request("ArmMoveCartesian", owl.ArmMoveCartesianGoal(1, False, POSE))
    offset = np.eye(4)
    offset[:3, 3] = [1.6, 0.0, 0.2]
    assert np.allclose(tool.target_pose, X_TIP @ offset)
    tool_relative = _request("ArmMoveCartesian", owl.ArmMoveCartesianGoal(1, True, POSE))
    assert np.allclose(tool_relative.target_pose, tool.target_pose)
    turn = Quaternion(0, 0, math.sin(math.pi / 4), math.cos(math.pi / 4))
    relative = _request(
        "ArmMoveCartesian", owl.ArmMoveCartesianGoal(0, True, Pose(Point(0, 0, -0.1), turn))
    )
    assert np.allclose(relative.target_pose[:3, 3], [1.0, 0.0, 0.4])
    # The rotation turns the tool about its own axes (OceanWATERS: current * goal).
    assert np.allclose(
        relative.target_pose[:3, :3], X_TIP[:3, :3] @ rotation_from_quaternion([0, 0, 1, 1])
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


def test_tasks_take_the_trench_centre():
    grind = _request("TaskGrind", owl.TaskGrindGoal(1.65, 0.1, 0.15, 0.6, 0.0, GROUND))
    assert grind.operation == "grind"
    assert grind.request["parallel"] is False and grind.request["centred"] is True
    assert (grind.request["x"], grind.request["y"]) == pytest.approx((1.65, 0.1))
    assert grind.request["depth"] == pytest.approx(0.15)
    linear = _request(
        "TaskScoopLinear", owl.TaskScoopLinearGoal(0, False, Point(1.5, 0, GROUND), 0.02, 0.2)
    )
    assert linear.operation == "dig_linear" and linear.request["centred"] is True
    assert (linear.request["x"], linear.request["y"]) == pytest.approx((1.5, 0.0))
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
    tool = _request(
        "TaskScoopCircular", owl.TaskScoopCircularGoal(1, True, Point(0.0, -0.2, 0.1), 0.03, True)
    )
    assert (tool.request["x"], tool.request["y"], tool.request["ground_position"]) == pytest.approx(
        (1.2, 0.0, 0.6)
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
