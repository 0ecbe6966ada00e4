"""Power faults on a real master: the battery node fed with ``/power`` by this test (a constant
load on simulation time), the ``faults`` server and the detector. A high power draw of 200 W
drains the extra charge it should; a low state of charge sets LOW_STATE_OF_CHARGE at 0.1;
FaultClear refuses a value that is not a goal error."""

from __future__ import annotations

import threading
import time

import pytest
import rospy
from actionlib_msgs.msg import GoalStatus
from dynamic_reconfigure.client import Client
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import BatteryState
from std_msgs.msg import Header

from ow_bringup.testing import action_client, advertise, subscribe
from ow_msgs.msg import Power
from ow_power.config import BatteryConfig
from owl_msgs.msg import (
    BatteryStateOfCharge,
    FaultClearAction,
    FaultClearGoal,
    PowerFaultsStatus,
    SystemFaultsStatus,
)

LOAD_W = 60.0
WINDOW_S = 10


class Feed:
    """/clock and /power at 100 Hz of simulation time, one second per call."""

    def __init__(self) -> None:
        self.clock = advertise("/clock", Clock, queue_size=10)
        self.power = advertise("/power", Power, queue_size=1000)
        self.time_s = 100.0

    def seconds(self, n: int) -> None:
        for _ in range(n * 100):
            self.time_s += 0.01
            stamp = rospy.Time.from_sec(round(self.time_s, 6))
            self.clock.publish(Clock(clock=stamp))
            self.power.publish(Power(header=Header(stamp=stamp), electrical_power=LOAD_W))
            time.sleep(0.001)


class Messages:
    def __init__(self, topic: str, msg_type: type) -> None:
        self.items: list = []
        self.lock = threading.Lock()
        self.sub = subscribe(topic, msg_type, self._on)

    def _on(self, msg) -> None:
        with self.lock:
            self.items.append(msg)

    def after(self, stamp_s: float) -> list:
        with self.lock:
            return [m for m in self.items if m.header.stamp.to_sec() > stamp_s + 1e-6]

    def wait_count(self, count: int, timeout_s: float = 30.0) -> list:
        """The first ``count`` messages, once they have arrived."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            with self.lock:
                if len(self.items) >= count:
                    return self.items[:count]
            time.sleep(0.02)
        pytest.fail(f"fewer than {count} messages on {self.sub.name}")


@pytest.fixture(scope="module")
def stack(ros_stack):
    ros_stack.start_node("ow_faults", "faults", wait_for_services=["/faults/set_parameters"])
    ros_stack.start_node("ow_faults", "detector", wait_for_topics=["/system_faults_status"])
    ros_stack.start_node(
        "ow_power", "battery", params={"initial_soc": 0.5}, wait_for_topics=["/battery_state"]
    )
    ros_stack.feed = Feed()
    ros_stack.client = Client("/faults", timeout=30)
    ros_stack.soc = Messages("/battery_state_of_charge", BatteryStateOfCharge)
    ros_stack.state = Messages("/battery_state", BatteryState)
    ros_stack.power_faults = Messages("/power_faults_status", PowerFaultsStatus)
    ros_stack.system_faults = Messages("/system_faults_status", SystemFaultsStatus)
    deadline = time.monotonic() + 30
    while ros_stack.feed.power.get_num_connections() == 0 and time.monotonic() < deadline:
        time.sleep(0.02)
    return ros_stack


def drain(stack) -> tuple[float, float]:
    """SOC drop over ``WINDOW_S`` battery periods (1 s each) and the charge drawn meanwhile
    (C, from the published current), after two seconds to settle."""
    before = len(stack.soc.items)
    stack.feed.seconds(2)
    first = len(stack.soc.wait_count(before + 1))
    stack.feed.seconds(WINDOW_S)
    socs = stack.soc.wait_count(first + WINDOW_S)
    states = stack.state.wait_count(first + WINDOW_S)[first : first + WINDOW_S]
    charge_c = sum(-m.current for m in states)  # A over 1 s each
    return socs[first - 1].value - socs[-1].value, charge_c


def test_high_power_draw_of_200_w_adds_its_current_to_the_drain(stack):
    nominal_drop, nominal_charge = drain(stack)
    stack.client.update_configuration({"high_power_draw": 200.0, "activate_high_power_draw": True})
    faulted_drop, faulted_charge = drain(stack)
    stack.client.update_configuration({"activate_high_power_draw": False})
    # the charge drawn grows as the load: (60 + 200) / 60 at nearly the same pack voltage
    assert faulted_charge / nominal_charge == pytest.approx((LOAD_W + 200.0) / LOAD_W, rel=0.03)
    # and the SOC falls by that charge over the pack's capacity
    capacity_c = BatteryConfig().mobile_charge_c
    assert faulted_drop == pytest.approx(faulted_charge / capacity_c, rel=0.05)
    assert nominal_drop == pytest.approx(nominal_charge / capacity_c, rel=0.05)


def test_low_state_of_charge_sets_its_bit_at_the_threshold(stack):
    stack.feed.seconds(1)
    assert all(m.value == 0 for m in stack.power_faults.after(0.0))
    stack.client.update_configuration({"low_state_of_charge": True})
    count = len(stack.soc.items)
    stack.feed.seconds(2)
    assert stack.soc.wait_count(count + 2)[-1].value <= 0.1
    deadline = time.monotonic() + 10
    while not any(
        m.value & PowerFaultsStatus.LOW_STATE_OF_CHARGE for m in stack.power_faults.after(0)
    ):
        assert time.monotonic() < deadline, "LOW_STATE_OF_CHARGE not set"
        time.sleep(0.02)
    first = next(
        m for m in stack.power_faults.after(0) if m.value & PowerFaultsStatus.LOW_STATE_OF_CHARGE
    )
    # set by the first SOC at or below 0.1, none before it
    socs = {round(m.header.stamp.to_sec(), 3): m.value for m in stack.soc.after(0)}
    assert socs[round(first.header.stamp.to_sec(), 3)] <= 0.1
    assert all(v > 0.1 for t, v in socs.items() if t < first.header.stamp.to_sec() - 1e-3)
    assert any(
        m.value & SystemFaultsStatus.POWER_EXECUTION_ERROR for m in stack.system_faults.after(0)
    )


def test_fault_clear_refuses_a_value_that_is_not_a_goal_error(stack):
    client = action_client("FaultClear", FaultClearAction)
    client.send_goal(FaultClearGoal(fault=SystemFaultsStatus.POWER_EXECUTION_ERROR))
    assert client.wait_for_end(30)
    assert client.get_state() == GoalStatus.ABORTED
    assert client.get_goal_status_text().startswith("Fault index, 256, is not valid.")
    client.send_goal(FaultClearGoal(fault=SystemFaultsStatus.ARM_GOAL_ERROR))
    assert client.wait_for_end(30)
    assert client.get_state() == GoalStatus.SUCCEEDED
    assert all(node.alive() for node in stack.nodes)
