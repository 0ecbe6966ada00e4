"""Fault injection through dynamic_reconfigure on a real master: the ``faults`` server, the
simulation's locks, flags and F/T faults, refusals, and the simulation's PID gains server."""

from __future__ import annotations

import subprocess
import threading
import time

import pytest
import rospy
from dynamic_reconfigure import DynamicReconfigureCallbackException
from dynamic_reconfigure.client import Client
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64

from ow_bringup.testing import advertise, subscribe
from ow_msgs.msg import JointStatesFlag
from ow_msgs.srv import SetPidGains
from owl_msgs.msg import (
    ArmEndEffectorForceTorque,
    ArmFaultsStatus,
    PanTiltFaultsStatus,
    SystemFaultsStatus,
)


class Latest:
    """The newest message of a topic, and a way to wait for one that matches."""

    def __init__(self, topic: str, msg_type: type) -> None:
        self.msg = None
        self._changed = threading.Condition()
        self.sub = subscribe(topic, msg_type, self._on)

    def _on(self, msg) -> None:
        with self._changed:
            self.msg = msg
            self._changed.notify_all()

    def wait_for(self, predicate, what: str, timeout_s: float = 20.0):
        with self._changed:
            if not self._changed.wait_for(
                lambda: self.msg is not None and predicate(self.msg), timeout_s
            ):
                pytest.fail(f"timed out waiting for {what} on {self.sub.name}")
            return self.msg


def position(msg: JointState, joint: str) -> float:
    return msg.position[msg.name.index(joint)]


@pytest.fixture(scope="module")
def stack(ros_stack):
    ros_stack.start_node("ow_faults", "faults", wait_for_services=["/faults/set_parameters"])
    ros_stack.start_node("ow_faults", "detector", wait_for_topics=["/system_faults_status"])
    ros_stack.start_node(
        "ow_sim_bullet",
        "sim",
        params={"terrain": "flat:-0.155", "real_time_factor": 4.0},
        wait_for_services=["/sim/set_pid_gains"],
        wait_for_topics=["/joint_states"],
    )
    ros_stack.client = Client("/faults", timeout=30)
    ros_stack.joints = Latest("/joint_states", JointState)
    ros_stack.flags = Latest("/flags/joint_states", JointStatesFlag)
    ros_stack.wrist = Latest("/arm_end_effector_force_torque", ArmEndEffectorForceTorque)
    ros_stack.arm = Latest("/arm_faults_status", ArmFaultsStatus)
    ros_stack.pan_tilt = Latest("/pan_tilt_faults_status", PanTiltFaultsStatus)
    ros_stack.system = Latest("/system_faults_status", SystemFaultsStatus)
    return ros_stack


def later(stack, seconds: float) -> JointState:
    """The joint state ``seconds`` of simulation time after the newest one."""
    now = stack.joints.wait_for(lambda m: True, "a joint state").header.stamp.to_sec()
    return stack.joints.wait_for(
        lambda m: m.header.stamp.to_sec() >= now + seconds, f"sim time {now + seconds:.1f} s"
    )


def test_a_locked_joint_is_flagged_and_does_not_follow_its_command(stack):
    command = advertise("/shou_pitch_position_controller/command", Float64, queue_size=1)
    stack.client.update_configuration({"shou_pitch_joint_locked_failure": True})
    flags = stack.flags.wait_for(lambda m: any(m.flags), "a locked joint's flag")
    assert list(flags.name) == sorted(flags.name)
    assert [n for n, f in zip(flags.name, flags.flags, strict=True) if f] == ["j_shou_pitch"]
    stack.arm.wait_for(lambda m: m.value == ArmFaultsStatus.HARDWARE, "HARDWARE")
    stack.system.wait_for(
        lambda m: m.value == SystemFaultsStatus.ARM_EXECUTION_ERROR, "ARM_EXECUTION_ERROR"
    )
    start = position(later(stack, 0.1), "j_shou_pitch")
    deadline = time.monotonic() + 10
    while command.get_num_connections() == 0 and time.monotonic() < deadline:
        time.sleep(0.01)
    command.publish(Float64(start - 0.2))
    assert position(later(stack, 2.0), "j_shou_pitch") == pytest.approx(start, abs=1e-4)

    stack.client.update_configuration({"shou_pitch_joint_locked_failure": False})
    stack.flags.wait_for(lambda m: not any(m.flags), "the flag cleared")
    stack.system.wait_for(lambda m: m.value == 0, "no system fault")
    command.publish(Float64(start - 0.2))
    assert position(later(stack, 4.0), "j_shou_pitch") == pytest.approx(start - 0.2, abs=2e-3)


def test_antenna_locks_set_the_pan_tilt_bits(stack):
    stack.client.update_configuration({"ant_pan_joint_locked_failure": True})
    stack.pan_tilt.wait_for(lambda m: m.value == PanTiltFaultsStatus.PAN_JOINT_LOCKED, "PAN")
    stack.client.update_configuration({"ant_tilt_joint_locked_failure": True})
    both = PanTiltFaultsStatus.PAN_JOINT_LOCKED | PanTiltFaultsStatus.TILT_JOINT_LOCKED
    stack.pan_tilt.wait_for(lambda m: m.value == both, "PAN and TILT")
    stack.system.wait_for(
        lambda m: m.value == SystemFaultsStatus.PAN_TILT_EXECUTION_ERROR, "PAN_TILT_EXECUTION_ERROR"
    )
    stack.client.update_configuration(
        {"ant_pan_joint_locked_failure": False, "ant_tilt_joint_locked_failure": False}
    )
    stack.pan_tilt.wait_for(lambda m: m.value == 0, "no pan/tilt fault")


def test_ft_zero_signal_then_bias(stack):
    stack.client.update_configuration({"enable": True, "zero_signal_failure": True})
    zero = stack.wrist.wait_for(lambda m: m.value.force.z == 0.0, "a zero F/T signal")
    f, t = zero.value.force, zero.value.torque
    assert (f.x, f.y, f.z, t.x, t.y, t.z) == (0.0,) * 6
    stack.arm.wait_for(lambda m: m.value == ArmFaultsStatus.NO_FORCE_DATA, "NO_FORCE_DATA")
    stack.client.update_configuration({"zero_signal_failure": False, "signal_bias_failure": 0.5})
    biased = stack.wrist.wait_for(lambda m: m.value.force.z != 0.0, "a biased F/T signal")
    # the arm is at rest, stowed, touching nothing: the true reading is ~0
    assert biased.value.force.z == pytest.approx(0.5, abs=0.05)
    stack.client.update_configuration({"enable": False, "signal_bias_failure": 0.0})
    stack.wrist.wait_for(lambda m: abs(m.value.force.z) < 0.05, "the F/T signal back")


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        (
            {"signal_bias_failure": 5.0},
            "signal_bias_failure = 5.0 N, N m is outside [-1, 1] N, N m",
        ),
        ({"high_power_draw": 0.5}, "high_power_draw = 0.5 W is outside [1, 360] W"),
        (
            {"custom_fault_profile": "nowhere.csv", "activate_custom_fault": True},
            "custom_fault_profile 'nowhere.csv': cannot read",
        ),
    ],
)
def test_bad_changes_are_refused_and_nothing_changes(stack, changes, message):
    # What the server holds: it writes the parameter server before it answers a change, while
    # the client's get_configuration is the last parameter_updates message it happened to
    # receive (the previous test's change once arrived between "before" and "after").
    before = {k: rospy.get_param(f"/faults/{k}") for k in changes}
    with pytest.raises(DynamicReconfigureCallbackException) as error:
        stack.client.update_configuration(changes)
    # the client's "service call failed" is raised from the server's answer, which says why
    assert message in str(error.value.__context__)
    assert {k: rospy.get_param(f"/faults/{k}") for k in changes} == before
    assert all(node.alive() for node in stack.nodes)


def dynparam(*args: str) -> str:
    result = subprocess.run(
        ["rosrun", "dynamic_reconfigure", "dynparam", "set", "/faults", *args],
        capture_output=True,
        text=True,
        timeout=60,
    )
    return result.stdout + result.stderr


def test_dynparam_from_a_shell_refuses_bad_input_and_sets_good(stack):
    # dynparam exits 0 either way; it prints the refusal (the server's log has it too)
    assert "don't know parameter: elbow_locked" in dynparam("elbow_locked", "true")
    refused = "high_power_draw = 500.0 W is outside [1, 360] W"
    assert refused in dynparam("high_power_draw", "500")  # in the traceback it prints
    faults_log = stack.nodes[0].log()
    assert f"change refused: {refused}" in faults_log
    assert dynparam("high_power_draw", "200") == ""
    assert stack.client.get_configuration(timeout=10)["high_power_draw"] == 200.0


def served(pid: Client, expected: dict) -> dict:
    """The server's gains once they are ``expected`` (the client learns changes by topic)."""
    deadline = time.monotonic() + 10
    while True:
        config = pid.get_configuration(timeout=10)
        now = {k: config[k] for k in expected}
        if now == expected or time.monotonic() > deadline:
            return now
        time.sleep(0.02)


def test_pid_gains_are_served_and_partial_requests_keep_the_rest(stack):
    pid = Client("/hand_yaw_position_controller/pid", timeout=30)
    gains = pid.get_configuration(timeout=10)
    assert (gains["p"], gains["i"], gains["d"]) == (100.0, 0.01, 10.0)  # config/pid.yaml
    assert gains["i_clamp"] > 0.0  # the effort limit (none configured)
    set_gains = stack.service("/sim/set_pid_gains", SetPidGains)
    response = set_gains(joint="j_hand_yaw", p=150.0)
    assert response.success, response.message
    expected = {"p": 150.0, "i": 0.01, "d": 10.0, "i_clamp": gains["i_clamp"]}
    assert served(pid, expected) == expected
    response = set_gains(joint="j_hand_yaw", i=0.0, set=["i"])
    assert response.success and served(pid, {**expected, "i": 0.0})["i"] == 0.0
    pid.update_configuration({"p": 100.0, "i": 0.01})
    assert "p 100 i 0.01 d 10" in set_gains(joint="j_hand_yaw", d=10.0).message
    with pytest.raises(DynamicReconfigureCallbackException) as error:
        pid.update_configuration({"p": 2e5})
    assert "p = 200000.0 is outside [0, 100000]" in str(error.value.__context__)
    response = set_gains(joint="j_hand_yaw", set=["q"])
    assert not response.success and "unknown gains ['q']" in response.message
