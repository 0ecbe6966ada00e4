"""OceanWATERS' joint telemetry from the real simulation: every topic's type, its array order
against /joint_states by name, the arm pose by forward kinematics, and one message of each topic
per joint state, stepped and with the simulation running as fast as it can."""

from __future__ import annotations

import re
import threading
import time

import numpy as np
import pytest
import rospy
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64, Header
from std_srvs.srv import Trigger

from ow_bringup.testing import FLAT, advertise, subscribe, wait_connected
from ow_description.description import ARM_JOINTS, UNSTOWED
from ow_description.model import LanderModel
from ow_msgs.srv import StepSimulation
from ow_sim_bullet.config import CONTROLLER_NAMES
from owl_msgs.msg import (
    ArmJointAccelerations,
    ArmJointPositions,
    ArmJointTorques,
    ArmJointVelocities,
    ArmPose,
    PanTiltPosition,
)

ARM_ORDER = (
    "j_dist_pitch",
    "j_grinder",
    "j_hand_yaw",
    "j_prox_pitch",
    "j_scoop_yaw",
    "j_shou_pitch",
    "j_shou_yaw",
)
TOPICS = {
    "/arm_joint_positions": ArmJointPositions,
    "/arm_joint_velocities": ArmJointVelocities,
    "/arm_joint_accelerations": ArmJointAccelerations,
    "/arm_joint_torques": ArmJointTorques,
    "/pan_tilt_position": PanTiltPosition,
    "/arm_pose": ArmPose,
}
RECEIPTS = "/sim/setpoint_received"


class Recorder:
    """Every message of a topic."""

    def __init__(self, topic: str, msg_type: type) -> None:
        self.lock = threading.Lock()
        self.messages: list = []
        self.sub = subscribe(topic, msg_type, self._on)

    def _on(self, msg) -> None:
        with self.lock:
            self.messages.append(msg)

    def take(self) -> list:
        with self.lock:
            return list(self.messages)

    def clear(self) -> None:
        with self.lock:
            self.messages.clear()


@pytest.fixture(scope="module")
def stack(ros_stack):
    ros_stack.start_node(
        "ow_sim_bullet",
        "sim",
        params={"real_time_factor": 0.0, "terrain": FLAT, "start_paused": True},
        wait_for_services=["/sim/step"],
    )
    telemetry = ros_stack.start_node("ow_lander", "telemetry", wait_for_topics=list(TOPICS))
    recorders = {topic: Recorder(topic, cls) for topic, cls in TOPICS.items()}
    recorders["/joint_states"] = Recorder("/joint_states", JointState)
    recorders[RECEIPTS] = Recorder(RECEIPTS, Header)
    for recorder in recorders.values():  # written to before the first step of the paused sim
        wait_connected(recorder.sub)
    return ros_stack, telemetry, recorders


def wait_until_complete(recorders, until: float, timeout_s: float = 30.0) -> list[JointState]:
    """The joint states recorded, once the one stamped ``until`` (s) is there and every topic has
    as many messages (or at the timeout)."""
    deadline = time.monotonic() + timeout_s
    while True:
        states = recorders["/joint_states"].take()
        counts = {t: len(recorders[t].take()) for t in TOPICS}
        last = states[-1].header.stamp.to_sec() if states else -1.0
        if last >= until - 1e-6 and all(c >= len(states) for c in counts.values()):
            return states
        if time.monotonic() > deadline:
            return states
        time.sleep(0.1)


def command_arm(recorders, pose: dict[str, float]) -> None:
    """Send the set-points and return once the paused simulation has taken every one (their
    receipts come on the module's one subscription: a new one might connect too late)."""
    receipts = recorders[RECEIPTS]
    before = len(receipts.take())
    for joint, value in pose.items():
        topic = f"/{CONTROLLER_NAMES[joint]}_position_controller/command"
        publisher = wait_connected(advertise(topic, Float64, queue_size=1))
        publisher.publish(Float64(value))
    deadline = time.monotonic() + 20.0
    while len(taken := [m.frame_id for m in receipts.take()[before:]]) < len(pose):
        assert time.monotonic() < deadline, f"set-points taken: {taken} of {sorted(pose)}"
        time.sleep(0.02)
    assert sorted(taken) == sorted(pose), taken


def test_topic_types_are_owl_msgs(stack):
    types = dict(rospy.get_published_topics())
    for topic, cls in TOPICS.items():
        assert types[topic] == cls._type, topic
    assert types["/arm_end_effector_force_torque"] == "owl_msgs/ArmEndEffectorForceTorque"


def test_every_joint_state_gives_one_message_per_topic_in_the_oceanwaters_order(stack):
    ros_stack, _, recorders = stack
    for recorder in recorders.values():
        recorder.clear()
    command_arm(recorders, {"j_shou_yaw": 0.4, "j_dist_pitch": 2.5, "j_hand_yaw": 0.3})
    response = ros_stack.service("/sim/step", StepSimulation)(300)
    assert response.success, response.message
    # The last joint state is stamped one step before the clock.
    states = wait_until_complete(recorders, response.sim_time - 0.01)
    assert len(states) >= 299  # one per step (the first stamped one step after the start)
    stamps = [s.header.stamp for s in states]
    for topic in TOPICS:
        assert [m.header.stamp for m in recorders[topic].take()] == stamps, topic

    by_stamp = {t: {m.header.stamp: m for m in recorders[t].take()} for t in TOPICS}
    model = LanderModel()
    previous = None
    moved = 0.0
    for state in states:
        position = dict(zip(state.name, state.position, strict=True))
        velocity = dict(zip(state.name, state.velocity, strict=True))
        effort = dict(zip(state.name, state.effort, strict=True))
        get = {topic: by_stamp[topic][state.header.stamp] for topic in TOPICS}
        assert list(get["/arm_joint_positions"].value) == [position[j] for j in ARM_ORDER]
        assert list(get["/arm_joint_velocities"].value) == [velocity[j] for j in ARM_ORDER]
        assert list(get["/arm_joint_torques"].value) == [effort[j] for j in ARM_ORDER]
        assert list(get["/pan_tilt_position"].value) == [
            position["j_ant_pan"],
            position["j_ant_tilt"],
        ]
        accelerations = np.array(get["/arm_joint_accelerations"].value)
        if previous is not None:
            dt = (state.header.stamp - previous.header.stamp).to_sec()
            before = dict(zip(previous.name, previous.velocity, strict=True))
            expected = [(velocity[j] - before[j]) / dt for j in ARM_ORDER]
            assert np.allclose(accelerations, expected, rtol=1e-6, atol=1e-9)
            moved = max(moved, float(np.max(np.abs(accelerations))))
        previous = state
        pose = get["/arm_pose"]
        assert pose.header.frame_id == "base_link"
        X = model.fk(model.q_from(position), "l_scoop")
        p = pose.value.position
        assert np.allclose([p.x, p.y, p.z], X[:3, 3], atol=1e-9)
    assert moved > 0.01  # the arm accelerated: the differences were not all zero


def test_the_node_keeps_up_with_the_simulation_running_as_fast_as_it_can(stack, record_property):
    ros_stack, telemetry, recorders = stack
    command_arm(recorders, {j: UNSTOWED[j] for j in ARM_JOINTS})
    for recorder in recorders.values():
        recorder.clear()
    assert ros_stack.service("/sim/resume", Trigger)().success
    time.sleep(5.0)
    assert ros_stack.service("/sim/pause", Trigger)().success
    sim_time = ros_stack.service("/sim/step", StepSimulation)(1).sim_time
    states = wait_until_complete(recorders, sim_time - 0.01)
    assert len(states) > 500  # over 5 s of sim time
    stamps = [s.header.stamp for s in states]
    for topic in TOPICS:
        assert [m.header.stamp for m in recorders[topic].take()] == stamps, topic

    telemetry.stop()
    match = re.search(
        r"telemetry: (\d+) joint states, (\d+) us of process CPU each \((\d+) us in the callback",
        telemetry.log(),
    )
    assert match, telemetry.log()[-2000:]
    record_property("telemetry_joint_states", int(match.group(1)))
    record_property("telemetry_cpu_us_per_joint_state", int(match.group(2)))
    record_property("telemetry_callback_cpu_us_per_joint_state", int(match.group(3)))
    print(match.group(0))
