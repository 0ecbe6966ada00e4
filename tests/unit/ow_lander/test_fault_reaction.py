"""The arm's and the mast's reaction rules (ow_lander.execution.fault_reaction), table-driven."""

from __future__ import annotations

import pytest

from ow_lander.execution import fault_reaction as fr
from ow_lander.execution.fault_reaction import FaultReaction, group_of, watches_force
from owl_msgs.msg import ArmFaultsStatus, PanTiltFaultsStatus, SystemFaultsStatus

LOCKED = {"shou_pitch_joint_locked_failure": True, "ant_pan_joint_locked_failure": False}


def test_bit_values_are_owl_msgs():
    assert (fr.ARM_GOAL_ERROR, fr.ARM_EXECUTION_ERROR, fr.TASK_GOAL_ERROR) == (
        SystemFaultsStatus.ARM_GOAL_ERROR,
        SystemFaultsStatus.ARM_EXECUTION_ERROR,
        SystemFaultsStatus.TASK_GOAL_ERROR,
    )
    assert (fr.PAN_TILT_GOAL_ERROR, fr.PAN_TILT_EXECUTION_ERROR) == (
        SystemFaultsStatus.PAN_TILT_GOAL_ERROR,
        SystemFaultsStatus.PAN_TILT_EXECUTION_ERROR,
    )
    assert (fr.HARDWARE, fr.NO_FORCE_DATA) == (
        ArmFaultsStatus.HARDWARE,
        ArmFaultsStatus.NO_FORCE_DATA,
    )
    assert (fr.PAN_JOINT_LOCKED, fr.TILT_JOINT_LOCKED) == (
        PanTiltFaultsStatus.PAN_JOINT_LOCKED,
        PanTiltFaultsStatus.TILT_JOINT_LOCKED,
    )


@pytest.mark.parametrize(
    ("name", "group"),
    [
        ("TaskGrind", "task"),
        ("ArmUnstow", "arm"),
        ("PanTiltMoveJoints", "pan_tilt"),
        ("grind", "task"),
        ("dig_linear", "task"),
        ("unstow", "arm"),
        ("guarded_move", "arm"),
        ("publish_trajectory", "arm"),
    ],
)
def test_groups(name, group):
    assert group_of(name) == group


@pytest.mark.parametrize(
    ("name", "detector", "watches"),
    [
        ("ArmFindSurface", "velocity", True),
        ("ArmMoveJointsGuarded", "velocity", True),
        ("ArmMoveJoints", "force", False),
        ("guarded_move", "velocity", False),
        ("guarded_move", "force", True),
    ],
)
def test_watches_force(name, detector, watches):
    assert watches_force(name, detector) is watches


def locked_arm(**kwargs) -> FaultReaction:
    state = FaultReaction(system=fr.ARM_EXECUTION_ERROR, arm=fr.HARDWARE, **kwargs)
    state.on_parameters(LOCKED)
    return state


def test_an_arm_execution_error_stops_and_refuses_naming_the_joint():
    state = locked_arm()
    error = "arm execution error: j_shou_pitch locked (HARDWARE)"
    assert state.arm_error() == error
    assert state.stop_reason(False) == f"{error} (arm_motion_continues_in_fault is false)"
    assert state.refusal("task") == state.stop_reason(False)
    assert state.refusal("pan_tilt") is None


def test_motion_continues_in_fault_unless_the_guard_needs_force_data():
    state = locked_arm()
    state.on_parameters({**LOCKED, "arm_motion_continues_in_fault": True})
    assert state.stop_reason(True) is None
    assert state.refusal("arm") is None
    state.arm |= fr.NO_FORCE_DATA
    assert state.stop_reason(False) is None
    assert state.stop_reason(True) == (
        "arm execution error: j_shou_pitch locked (HARDWARE); no force data from the wrist F/T "
        "sensor (NO_FORCE_DATA): contact cannot be detected"
    )


def test_flagged_arm_joints_give_the_reaction_the_detectors_status_will():
    """In the lockstep the arm acts on the simulation's lock flags: the same stop reason as
    once the detector's HARDWARE status has arrived."""
    flagged = FaultReaction().with_locked({"j_shou_pitch"})
    assert flagged == locked_arm()
    assert flagged.stop_reason(False) == locked_arm().stop_reason(False)
    assert FaultReaction().with_locked({"j_ant_pan"}) == FaultReaction()  # the mast: not the arm
    assert FaultReaction().with_locked(set()).stop_reason(False) is None


def test_the_system_bit_without_the_arm_status_yet_is_not_acted_on():
    assert FaultReaction(system=fr.ARM_EXECUTION_ERROR).arm_error() is None


@pytest.mark.parametrize("auto_clear", [True, False])
def test_goal_errors_refuse_only_without_auto_clear(auto_clear):
    state = FaultReaction(system=fr.TASK_GOAL_ERROR | fr.PAN_TILT_GOAL_ERROR)
    state.on_parameters({"auto_clear_goal_errors": auto_clear})
    refused = state.refusal("task")
    assert state.refusal("arm") is None
    if auto_clear:
        assert refused is None and state.refusal("pan_tilt") is None
    else:
        assert refused == (
            "Action group, TASK, is faulted. Use the FaultClear action to make the group "
            "operable again. (TASK_GOAL_ERROR stands and auto_clear_goal_errors is false; "
            "fault: 8)"
        )
        assert "Action group, PAN_TILT, is faulted" in str(state.refusal("pan_tilt"))


def test_a_locked_antenna_joint_fails_pan_tilt_goals():
    state = FaultReaction(system=fr.PAN_TILT_EXECUTION_ERROR, pan_tilt=fr.TILT_JOINT_LOCKED)
    assert (
        state.pan_tilt_error() == "pan/tilt execution error: j_ant_tilt locked (TILT_JOINT_LOCKED)"
    )
    assert state.refusal("pan_tilt") == state.pan_tilt_error()
    assert state.refusal("arm") is None
