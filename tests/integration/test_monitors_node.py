"""``rosrun ow_mission monitors``: the power node, the battery, the telemetry, the fault
detector and the viz node as components of one node, on a real master with the real simulation
and fault server (the mission's stack runs them so)."""

from __future__ import annotations

import time

import pytest
import rosgraph
import rospy
from dynamic_reconfigure.client import Client
from sensor_msgs.msg import BatteryState, JointState
from visualization_msgs.msg import Marker

from ow_bringup.stack import HarnessError
from ow_bringup.testing import subscribe, wait_connected
from ow_msgs.msg import FaultChangeApplied, Power
from owl_msgs.msg import ArmJointPositions

P0_W = 37.0


class Stamps:
    """The stamps (s) of every message of a topic, and the messages."""

    def __init__(self, topic: str, msg_type: type) -> None:
        self.messages: list = []
        self.sub = subscribe(topic, msg_type, self.messages.append)

    def stamps(self) -> list[float]:
        return [m.header.stamp.to_sec() for m in list(self.messages)]


def _wait(condition, what: str, timeout_s: float = 30.0) -> None:
    deadline = time.monotonic() + timeout_s
    while not condition():
        if time.monotonic() > deadline:
            pytest.fail(f"timed out waiting for {what}")
        time.sleep(0.02)


@pytest.fixture(scope="module")
def stack(ros_stack):
    ros_stack.start_node("ow_faults", "faults", wait_for_services=["/faults/set_parameters"])
    ros_stack.start_node("ow_sim_bullet", "sim", wait_for_topics=["/joint_states"])
    ros_stack.start_node(
        "ow_bringup",
        "monitors",
        params={"power": {"auxiliary_power_w": P0_W}, "telemetry": {"rate_hz": 0.0}},
        wait_for_topics=["/power", "/arm_joint_positions", "/system_faults_status"],
    )
    ros_stack.client = Client("/faults", timeout=30)
    return ros_stack


def test_every_joint_state_gives_a_power_and_a_telemetry_message(stack):
    joints = Stamps("/joint_states", JointState)
    power = Stamps("/power", Power)
    telemetry = Stamps("/arm_joint_positions", ArmJointPositions)
    for recorder in (joints, power, telemetry):  # written to by their publishers from now on
        wait_connected(recorder.sub)
    # Ten joint states later (0.1 s): the monitors' messages of any joint state that reaches
    # us from then on were published after every connection was up.
    start = len(joints.stamps()) + 10
    _wait(lambda: len(joints.stamps()) >= start + 90, "100 joint states")
    window = joints.stamps()[start : start + 90]
    _wait(
        lambda: set(window) <= set(power.stamps()) and set(window) <= set(telemetry.stamps()),
        "the power and telemetry of those joint states",
    )
    assert power.messages[-1].auxiliary_power == P0_W  # the component's own parameters


def test_the_battery_takes_the_power_components_messages_without_a_connection(stack):
    """/power reaches the battery in the node's own process: the node does not subscribe to
    it, and the battery's load over each period is still that period's /power."""
    _, subscribers, _ = rosgraph.Master("/test").getSystemState()
    assert "/monitors" not in dict(subscribers).get("/power", [])
    power = Stamps("/power", Power)
    batteries = Stamps("/battery_state", BatteryState)
    wait_connected(power.sub)
    # From the first /power received: a battery period before it has no loads here (with no
    # message yet, a start of 0 s let one through under load).
    _wait(lambda: power.stamps(), "a /power message")
    start_s = max(power.stamps())
    _wait(lambda: [t for t in batteries.stamps() if t > start_s + 2.0], "two battery periods")
    last = next(m for m in batteries.messages if m.header.stamp.to_sec() > start_s + 2.0)
    end_s = last.header.stamp.to_sec()
    loads = [
        m.electrical_power
        for m in list(power.messages)
        if end_s - 0.995 < m.header.stamp.to_sec() < end_s + 0.005  # stamps to the ns
    ]
    assert len(loads) == 100  # one second of joint states at 100 Hz
    assert -last.current * last.voltage == pytest.approx(sum(loads) / len(loads), rel=0.01)


def test_the_viz_component_draws_under_the_viz_namespace(stack):
    marker = rospy.wait_for_message("/viz/terrain", Marker, timeout=20)
    assert marker.type == Marker.TRIANGLE_LIST and marker.points
    assert rospy.get_param("/robot_description").startswith("<?xml")


def test_a_fault_change_is_acknowledged_once_by_the_node_after_every_component(stack):
    """The battery and the detector both follow /faults; the node says it has applied a change
    once, after both (a mission waits for each node that acknowledges)."""
    applied = Stamps("/faults/applied", FaultChangeApplied)
    # The node's publisher adds our connection last: an acknowledgement before then is lost
    # (under load the battery applied the change the very millisecond it was added).
    wait_connected(applied.sub)
    stack.client.update_configuration({"high_power_draw": 50.0, "activate_high_power_draw": True})
    try:
        _wait(lambda: any(m.node == "/monitors" for m in applied.messages), "an acknowledgement")
        _wait(lambda: any(m.node == "/sim" for m in applied.messages), "the simulation's")
        time.sleep(1.0)  # a second acknowledgement of the change would be here by now
        mine = [m.version for m in applied.messages if m.node == "/monitors"]
        assert len(mine) == len(set(mine)) == 1
    finally:
        stack.client.update_configuration({"activate_high_power_draw": False})


def _refused(ros_stack, name: str, params: dict, match: str) -> None:
    """A monitors node started with ``params`` stops, its log matching ``match``."""
    with pytest.raises(HarnessError, match=match):
        ros_stack.start_node(
            "ow_bringup",
            "monitors",
            name=name,
            params=params,
            wait_for_topics=["/never"],
            timeout_s=30.0,
        )


def test_a_wrong_parameter_stops_the_node_naming_it(ros_stack):
    _refused(ros_stack, "monitors_bad", {"power": {"motor_efficiency": 2.0}}, "motor_efficiency")


def test_a_battery_that_cannot_start_stops_the_node_naming_why(ros_stack):
    """The monitors build the battery after their topics are up (ProgPy's imports are the
    longest part of a mission's start); a pack that cannot start still stops the node, with
    the battery's reason in its log."""
    params = {"battery": {"initial_soc": 0.01}}
    _refused(ros_stack, "monitors_flat_battery", params, r"initial cell voltage .* at SOC 0\.01")
