"""How OceanWATERS' actions end: HEAD's states and texts for every way an execution ends
(ow_lander.actions.outcomes, no ROS master)."""
# ruff: noqa: E501  (the tables read best one case a line)

import math

import numpy as np
import pytest
from geometry_msgs.msg import Point, Pose, Quaternion, Vector3

import owl_msgs.msg as owl
from ow_lander import conversions as conv
from ow_lander.actions.outcomes import (
    NO_SURFACE,
    NO_THRESHOLD_BREACH,
    STOP_DURING_EXECUTION,
    SurfaceApproach,
    breach_text,
    execution_outcome,
    success_text,
)
from ow_lander.actions.owl import ArmState, rotation_between, to_request
from ow_lander.execution.monitor import ExecutionResult

GROUND = -0.172
ARM = np.array([0.0, 1.5707, -1.5707, 0.0, 1.5707, 0.0])
X_TIP = np.eye(4)


def _request(action, goal):
    return to_request(action, conv.goal_to_dict(goal), ARM, X_TIP)


def _state(position=(0.0, 0.0, 0.0), rotation=None, angles=ARM, force=3.0, torque=1.0):
    X = np.eye(4)
    X[:3, 3] = position
    if rotation is not None:
        X[:3, :3] = rotation
    return ArmState(np.asarray(angles, dtype=float), X, force, torque)


REACHED = ExecutionResult(True, "reached the final set-point")
FAILED = ExecutionResult(False, "tracking error: j_shou_yaw is 0.4 rad from its set-point")
STOPPED = ExecutionResult(False, "stopped on request at t=1.00 s", stopped=True, hold={})
FAULT = ExecutionResult(False, "ARM_EXECUTION_ERROR: the arm stopped", fault="ARM_EXECUTION_ERROR")


def _breached(force, torque):
    return ExecutionResult(True, "force exceeded", wrench=(force, torque))


@pytest.mark.parametrize(
    ("action", "text"),
    [
        ("ArmUnstow", "ArmUnstow trajectory succeeded"),
        ("ArmStow", "ArmStow trajectory succeeded"),
        ("ArmMoveJoint", "Arm joints moved successfully"),
        ("ArmMoveJoints", "Arm joints moved successfully"),
        ("ArmMoveCartesian", "ArmMoveCartesian trajectory succeeded"),
        ("TaskGrind", "TaskGrind trajectory succeeded"),
        ("TaskScoopLinear", "TaskScoopLinear trajectory succeeded"),
        ("TaskDeliverSample", "TaskDeliverSample trajectory succeeded"),
    ],
)
def test_success_texts(action, text):
    assert success_text(action) == text


@pytest.mark.parametrize(
    ("force", "torque", "text"),
    [
        (250.0, 10.0, "X trajectory stopped by a force of 250.00 N"),
        (10.0, 120.5, "X trajectory stopped by a torque of 120.50 Nm"),
        (200.0, 100.0, "X trajectory stopped by a force of 200.00 N and a torque of 100.00 Nm"),
        (199.9, 99.9, "X trajectory completed without breaching force or torque thresholds"),
    ],
)
def test_breach_texts(force, torque, text):
    assert breach_text("X", force, torque, (200.0, 100.0)) == text


def test_move_joints_end_checked_modulo_a_turn():
    goal = owl.ArmMoveJointsGoal(False, [0.84, 1.48, 7.87, -0.31, 3.47, 2.29])
    request = _request("ArmMoveJoints", goal)
    there = np.array(goal.angles) - [0, 0, 2 * math.pi, 0, 0, 0]
    ok = execution_outcome("ArmMoveJoints", request, REACHED, _state(angles=there), False)
    assert (ok.status, ok.text) == ("succeeded", "Arm joints moved successfully")
    off = execution_outcome("ArmMoveJoints", request, REACHED, _state(angles=there + 0.06), False)
    assert off.status == "aborted"
    assert off.text.startswith("Arm joints failed to reach intended target angles")


def test_cartesian_end_checked_at_one_centimetre():
    request = _request(
        "ArmMoveCartesian",
        owl.ArmMoveCartesianGoal(0, False, Pose(Point(1.6, 0, 0.2), Quaternion(0, 0, 0, 1))),
    )
    ok = execution_outcome("ArmMoveCartesian", request, REACHED, _state((1.6, 0.0, 0.209)), False)
    assert (ok.status, ok.text) == ("succeeded", "ArmMoveCartesian trajectory succeeded")
    off = execution_outcome("ArmMoveCartesian", request, REACHED, _state((1.6, 0.0, 0.215)), False)
    assert off.status == "aborted" and off.text.startswith("Failed to reach intended pose")


GUARDED_POSE = Pose(Point(1.6, 0, 0.2), Quaternion(0, 0, 0, 1))


@pytest.mark.parametrize(
    ("result", "position", "status", "text"),
    [
        (
            _breached(250.0, 3.0),
            (1.6, 0.0, 0.3),
            "succeeded",
            "ArmMoveCartesianGuarded trajectory stopped by a force of 250.00 N",
        ),
        (
            REACHED,
            (1.6, 0.0, 0.2),
            "succeeded",
            "ArmMoveCartesianGuarded trajectory completed without breaching force or torque thresholds",
        ),
        (REACHED, (1.6, 0.0, 0.25), "aborted", NO_THRESHOLD_BREACH),
        (FAILED, (1.6, 0.0, 0.25), "aborted", f"{NO_THRESHOLD_BREACH} ({FAILED.message})"),
        (FAULT, (1.6, 0.0, 0.25), "aborted", FAULT.message),
    ],
)
def test_guarded_cartesian(result, position, status, text):
    request = _request(
        "ArmMoveCartesianGuarded",
        owl.ArmMoveCartesianGuardedGoal(0, False, GUARDED_POSE, 200.0, 100.0),
    )
    outcome = execution_outcome("ArmMoveCartesianGuarded", request, result, _state(position), False)
    assert outcome.status == status
    assert outcome.text.startswith(text)


def test_guarded_joints_trip_at_once_with_a_zero_threshold():
    request = _request(
        "ArmMoveJointsGuarded",
        owl.ArmMoveJointsGuardedGoal(True, [0.0, 0, 0, 0, -0.6, 0], 0.0, 0.0),
    )
    assert request.breaches_at_once
    not_moved = ExecutionResult(True, "not moved")
    outcome = execution_outcome(
        "ArmMoveJointsGuarded", request, not_moved, _state(force=0.0, torque=0.0), False
    )
    assert outcome.status == "succeeded"
    assert (
        outcome.text
        == "ArmMoveJointsGuarded trajectory stopped by a force of 0.00 N and a torque of 0.00 Nm"
    )


def _surface(**kw):
    fields = dict(frame=0, relative=False, position=Point(1.7, 0.5, GROUND), normal=Vector3(0, 0, 1),
                  distance=0.2, overdrive=0.05, force_threshold=200.0, torque_threshold=100.0)  # fmt: skip
    fields.update(kw)
    return _request("ArmFindSurface", owl.ArmFindSurfaceGoal(**fields))


DOWN = rotation_between([0, 0, 1], [0, 0, -1])
NO_GROUND = ExecutionResult(
    False, "no ground within 0.25 m of the start of the descent", reports_ground=True
)


APPROACH_FAILED = " - Surface approach trajectory failed"
SETUP_FAILED = " - Setup trajectory failed"
FOUND = "ArmFindSurface trajectory stopped by a force of 210.00 N. Surface found at (1.700, 0.500, -0.170)"

# fmt: off
FIND_SURFACE = [
    # result, tip position, approach begun, status, text, ended before the approach
    (_breached(210.0, 12.0), (1.7, 0.5, -0.170), True, "succeeded", FOUND, False),
    (NO_GROUND, (1.7, 0.5, GROUND - 0.05), True, "succeeded", NO_SURFACE, False),
    (NO_GROUND, (1.7, 0.5, GROUND - 0.02), True, "aborted", NO_THRESHOLD_BREACH, False),
    (FAILED, (1.7, 0.5, 0.3), False, "aborted", f"Failed to reach setup pose. ({FAILED.message})", True),
    (FAILED, (1.7, 0.5, 0.0), True, "aborted", f"{NO_THRESHOLD_BREACH} ({FAILED.message})", False),
    (STOPPED, (1.7, 0.5, 0.0), True, "aborted", STOP_DURING_EXECUTION + APPROACH_FAILED, False),
    (STOPPED, (1.7, 0.5, 0.3), False, "aborted", STOP_DURING_EXECUTION + SETUP_FAILED, True),
    (FAULT, (1.7, 0.5, 0.0), True, "aborted", FAULT.message + APPROACH_FAILED, False),
]
# fmt: on


@pytest.mark.parametrize(("result", "position", "began", "status", "text", "before"), FIND_SURFACE)
def test_find_surface(result, position, began, status, text, before):
    state = _state(position, DOWN)
    outcome = execution_outcome(
        "ArmFindSurface", _surface(), result, state, result is STOPPED, began
    )
    assert (outcome.status, outcome.before_approach) == (status, before)
    assert outcome.text.startswith(text)


def test_find_surface_with_zero_thresholds_reports_the_setup_pose():
    request = _surface(force_threshold=0.0, torque_threshold=0.0)
    at_setup = _state((1.7, 0.5, GROUND + 0.2), DOWN, force=0.5, torque=0.0)
    outcome = execution_outcome("ArmFindSurface", request, REACHED, at_setup, False)
    assert outcome.status == "succeeded"
    assert outcome.text == (
        "ArmFindSurface trajectory stopped by a force of 0.50 N and a torque of 0.00 Nm. "
        f"Surface found at (1.700, 0.500, {GROUND + 0.2:.3f})"
    )
    short = execution_outcome(
        "ArmFindSurface", request, REACHED, _state((1.7, 0.5, 0.1), DOWN), False
    )
    assert short.status == "aborted" and short.text.startswith("Failed to reach setup pose.")


def test_a_motion_that_did_not_get_there_has_oceanwaters_text_and_our_reason():
    joints = _request("ArmMoveJoints", owl.ArmMoveJointsGoal(False, list(ARM)))
    outcome = execution_outcome("ArmMoveJoints", joints, FAILED, _state(), False)
    assert outcome.status == "aborted"
    assert outcome.text == f"Arm joints failed to reach intended target angles ({FAILED.message})"
    grind = _request("TaskGrind", owl.TaskGrindGoal(1.65, 0.0, 0.05, 0.6, 1.0, GROUND))
    outcome = execution_outcome("TaskGrind", grind, FAILED, _state(), False)
    assert (outcome.status, outcome.text) == ("aborted", f"TaskGrind failed ({FAILED.message})")


def test_cancel_is_a_preempt_and_arm_stop_an_abort():
    request = _request("ArmUnstow", owl.ArmUnstowGoal())
    cancelled = execution_outcome("ArmUnstow", request, STOPPED, _state(), stop_called=False)
    assert cancelled.status == "preempted"
    stopped = execution_outcome("ArmUnstow", request, STOPPED, _state(), stop_called=True)
    assert (stopped.status, stopped.text) == ("aborted", STOP_DURING_EXECUTION)


def test_surface_approach_begins_at_the_setup_pose():
    approach = SurfaceApproach(_surface())

    def pose(position, rotation):
        X = np.eye(4)
        X[:3, :3], X[:3, 3] = rotation, position
        return X

    near = np.array([1.7, 0.5, GROUND + 0.205])  # 5 mm above the setup point
    approach.update(pose([1.5, 0.0, 0.4], DOWN))
    assert not approach.begun
    tilted = rotation_between([0, 0, 1], [0.0, 0.1, -1.0])  # 0.1 rad from facing down
    approach.update(pose(near, tilted))
    assert not approach.begun  # passing the point turned otherwise
    approach.update(pose(near, DOWN))
    assert approach.begun
    approach.update(pose([1.5, 0.0, 0.4], DOWN))
    assert approach.begun
