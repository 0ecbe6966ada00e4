"""OceanWATERS' detection rules without ROS (ow_faults.detection): bits, thresholds, goal errors."""

from __future__ import annotations

import pytest

from ow_faults.detection import FT_TIMEOUT_S, FaultDetector, action_group, cleared_text
from ow_faults.errors import FaultError
from ow_faults.injection import LOCKABLE_JOINTS, FaultSet
from owl_msgs.msg import ArmFaultsStatus as Arm
from owl_msgs.msg import CameraFaultsStatus as Camera
from owl_msgs.msg import PanTiltFaultsStatus as PanTilt
from owl_msgs.msg import PowerFaultsStatus as Power
from owl_msgs.msg import SystemFaultsStatus as System


def flags(*locked: str) -> tuple[tuple[str, ...], list[bool]]:
    return LOCKABLE_JOINTS, [j in locked for j in LOCKABLE_JOINTS]


def test_oceanwaters_bit_values():
    assert (Arm.HARDWARE, Arm.NO_FORCE_DATA) == (1, 128)
    assert (PanTilt.PAN_JOINT_LOCKED, PanTilt.TILT_JOINT_LOCKED) == (1, 2)
    assert (Power.LOW_STATE_OF_CHARGE, Power.INSTANTANEOUS_CAPACITY_LOSS, Power.THERMAL_FAULT) == (
        1,
        2,
        4,
    )
    assert (System.ARM_GOAL_ERROR, System.ARM_EXECUTION_ERROR, System.TASK_GOAL_ERROR) == (2, 4, 8)
    assert (
        System.PAN_TILT_GOAL_ERROR,
        System.PAN_TILT_EXECUTION_ERROR,
        System.POWER_EXECUTION_ERROR,
    ) == (64, 128, 256)
    assert (Camera.NO_IMAGE, System.CAMERA_GOAL_ERROR, System.CAMERA_EXECUTION_ERROR) == (1, 16, 32)


def test_an_arm_joint_lock_is_hardware_and_an_execution_error_until_released():
    detector = FaultDetector()
    assert detector.on_joint_flags(*flags("j_shou_pitch"), 1.0)
    assert detector.status.arm == Arm.HARDWARE
    assert detector.status.system == System.ARM_EXECUTION_ERROR
    assert not detector.on_joint_flags(*flags("j_shou_pitch"), 1.01)  # no change
    assert detector.on_joint_flags(*flags(), 1.02)
    assert detector.status.arm == 0 and detector.status.system == 0


def test_antenna_locks_are_pan_tilt_bits():
    detector = FaultDetector()
    detector.on_joint_flags(*flags("j_ant_pan", "j_ant_tilt"), 1.0)
    assert detector.status.pan_tilt == PanTilt.PAN_JOINT_LOCKED | PanTilt.TILT_JOINT_LOCKED
    assert detector.status.system == System.PAN_TILT_EXECUTION_ERROR and detector.status.arm == 0


def test_no_force_data_from_the_injector_or_a_silent_sensor():
    detector = FaultDetector()
    detector.on_injected(FaultSet(zero_signal_failure=True))  # not enabled
    assert detector.status.arm == 0
    detector.on_injected(FaultSet(enable=True, zero_signal_failure=True))
    assert detector.status.arm == Arm.NO_FORCE_DATA
    assert detector.status.system == System.ARM_EXECUTION_ERROR
    detector.on_injected(FaultSet())
    detector.on_wrist(10.0)
    detector.on_joint_flags(*flags(), 10.02)
    detector.on_joint_flags(*flags(), 10.0 + FT_TIMEOUT_S)
    assert detector.status.arm == 0
    detector.on_joint_flags(*flags(), 10.03 + FT_TIMEOUT_S)  # over the timeout without a reading
    assert detector.status.arm == Arm.NO_FORCE_DATA
    detector.on_wrist(10.02 + FT_TIMEOUT_S)
    assert detector.status.arm == 0


def test_readings_arriving_late_are_not_silence():
    # A lagging detector: flags stamped 2 s after the newest reading it has processed, while
    # readings still arrive between them.
    detector = FaultDetector()
    detector.on_wrist(10.0)
    for k in range(1, 50):
        detector.on_joint_flags(*flags(), 12.0 + 0.02 * k)
        detector.on_wrist(10.0 + 0.02 * k)
        assert detector.status.arm == 0


@pytest.mark.parametrize(("soc", "bit"), [(0.1001, 0), (0.1, Power.LOW_STATE_OF_CHARGE)])
def test_low_soc_at_the_threshold(soc, bit):
    detector = FaultDetector()
    detector.on_soc(0.1002)
    detector.on_soc(soc)
    assert detector.status.power == bit


def test_capacity_loss_is_a_relative_drop_between_messages():
    detector = FaultDetector()
    detector.on_soc(0.8)
    detector.on_soc(0.8 * 0.951)
    assert detector.status.power == 0
    detector.on_soc(0.8 * 0.951 * 0.95)
    assert detector.status.power == Power.INSTANTANEOUS_CAPACITY_LOSS
    assert detector.status.system == System.POWER_EXECUTION_ERROR
    detector.on_soc(0.8 * 0.951 * 0.95 - 1e-4)
    assert detector.status.power == 0


def test_thermal_fault_at_70_degrees():
    detector = FaultDetector()
    detector.on_temperature(69.99)
    assert detector.status.power == 0
    detector.on_temperature(70.0)
    assert detector.status.power == Power.THERMAL_FAULT


def test_goal_errors_auto_cleared_or_cleared_by_fault_clear():
    detector = FaultDetector()
    detector.on_goal_status("TaskGrind", "g1", 1)
    detector.on_goal_status("TaskGrind", "g1", 4)
    assert detector.status.system == System.TASK_GOAL_ERROR
    detector.on_goal_status("TaskGrind", "g2", 1)  # auto_clear_goal_errors (default)
    assert detector.status.system == 0
    detector.on_injected(FaultSet(auto_clear_goal_errors=False))
    detector.on_goal_status("ArmUnstow", "g3", 4)
    detector.on_goal_status("ArmUnstow", "g4", 1)
    assert detector.status.system == System.ARM_GOAL_ERROR  # stands
    assert detector.clear(System.ARM_GOAL_ERROR)
    assert detector.status.system == 0
    assert not detector.on_goal_status("ArmUnstow", "g4", 1)  # repeated status arrays


def test_fault_clear_refuses_other_values():
    with pytest.raises(
        FaultError,
        match=r"Fault index, 4, is not valid. \(fault = 4 is not a goal error; FaultClear takes "
        r"one of \[2, 8, 16, 64\]\)",
    ):
        FaultDetector().clear(System.ARM_EXECUTION_ERROR)
    assert cleared_text(System.ARM_GOAL_ERROR) == "ARM goal faults have been cleared."
    assert cleared_text(System.PAN_TILT_GOAL_ERROR) == "PAN_TILT goal faults have been cleared."


def test_a_second_trigger_without_a_left_image_is_no_image_until_an_image_arrives():
    detector = FaultDetector()
    detector.on_camera_trigger()
    assert detector.status.camera == 0  # the first failed capture is not flagged (OceanWATERS)
    assert detector.on_camera_trigger()
    assert detector.status.camera == Camera.NO_IMAGE
    assert detector.status.system == System.CAMERA_EXECUTION_ERROR
    assert detector.on_camera_image()
    assert (detector.status.camera, detector.status.system) == (0, 0)
    detector.on_camera_trigger()
    detector.on_camera_image()
    assert not detector.on_camera_trigger()  # answered: nothing pending, nothing flagged


def test_an_aborted_camera_goal_is_a_camera_goal_error():
    detector = FaultDetector()
    detector.on_goal_status("CameraCapture", "g1", 4)
    assert detector.status.system == System.CAMERA_GOAL_ERROR
    assert detector.status.camera == 0  # a goal error is no camera fault
    assert detector.clear(System.CAMERA_GOAL_ERROR)
    assert detector.status.system == 0
    detector.on_goal_status("CameraSetExposure", "g2", 4)
    assert detector.status.system == System.CAMERA_GOAL_ERROR
    assert detector.on_goal_status("CameraCapture", "g3", 1)  # a new goal clears it (auto)
    assert detector.status.system == 0


@pytest.mark.parametrize(
    ("action", "group"),
    [
        ("CameraCapture", "camera"),
        ("CameraSetExposure", "camera"),
        ("LightSetIntensity", None),  # OceanWATERS' lights belong to no fault group
        ("PanTiltMoveJoints", "pan_tilt"),
        ("TaskGrind", "task"),
        ("ArmUnstow", "arm"),
    ],
)
def test_action_groups_are_oceanwaters(action, group):
    assert action_group(action) == group
