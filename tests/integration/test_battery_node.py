"""The battery node on a real master, fed with ``/power`` by this test at 100 Hz of simulated time.

At a constant electrical load the published state of charge must fall at the rate the load
implies (the current ``P / V``, with ``V`` the published pack voltage, over the pack's mobile
charge), and every topic must arrive once per second of simulated time, stamped on the second.
"""

import itertools
import time

import pytest
import rospy
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import BatteryState
from std_msgs.msg import Header

from ow_bringup.testing import advertise, subscribe, wait_connected
from ow_msgs.msg import Power
from ow_power.config import BatteryConfig
from owl_msgs.msg import BatteryRemainingUsefulLife, BatteryStateOfCharge, BatteryTemperature

PERIOD_S = 0.01  # /power at 100 Hz of simulation time, as the power node publishes it
LOAD_W = 150.0
START_S = 50.0
SECONDS = 20


def _wait(condition, what, timeout_s=30.0):
    deadline = time.monotonic() + timeout_s
    while not condition():
        if time.monotonic() > deadline:
            pytest.fail(f"timed out waiting for {what}")
        time.sleep(0.02)


class Collector:
    """Every message of one topic, in arrival order."""

    def __init__(self, topic, msg_type):
        self.messages = []
        self.subscriber = subscribe(topic, msg_type, self.messages.append)


@pytest.fixture(scope="module")
def battery(ros_stack):
    ros_stack.start_node(
        "ow_power",
        "battery",
        params={"initial_soc": 0.8},
        wait_for_topics=["/battery_state_of_charge", "/battery_state"],
    )
    topics = {
        "soc": ("/battery_state_of_charge", BatteryStateOfCharge),
        "rul": ("/battery_remaining_useful_life", BatteryRemainingUsefulLife),
        "temperature": ("/battery_temperature", BatteryTemperature),
        "state": ("/battery_state", BatteryState),
    }
    collectors = {key: Collector(*spec) for key, spec in topics.items()}
    clock = advertise("/clock", Clock, queue_size=10)
    power = advertise("/power", Power, queue_size=1000)
    _wait(lambda: power.get_num_connections() >= 1, "the battery node on /power")
    for collector in collectors.values():  # the battery node writes to each
        wait_connected(collector.subscriber)
    for k in range(SECONDS * 100 + 1):
        stamp = rospy.Time.from_sec(START_S + k * PERIOD_S)
        clock.publish(Clock(clock=stamp))
        power.publish(
            Power(
                header=Header(stamp=stamp),
                auxiliary_power=43.0,
                electrical_power=LOAD_W,
            )
        )
        time.sleep(0.002)  # ~500 Hz of wall time: no queue overflows
    _wait(
        lambda: all(len(c.messages) >= SECONDS for c in collectors.values()),
        f"{SECONDS} messages on each battery topic",
    )
    return {key: c.messages for key, c in collectors.items()}


def test_every_topic_arrives_once_per_second_of_simulation_time(battery):
    for key, messages in battery.items():
        stamps = [m.header.stamp.to_sec() for m in messages]
        assert stamps == pytest.approx([START_S + k for k in range(1, SECONDS + 1)]), key
        assert all(m.header.frame_id == "base_link" for m in messages)


def test_the_soc_falls_at_the_rate_the_load_implies(battery):
    soc = [m.value for m in battery["soc"]]
    voltage = [m.voltage for m in battery["state"]]
    assert soc[0] < 0.8
    assert all(b < a for a, b in itertools.pairwise(soc))
    charge_c = sum(LOAD_W / v * 1.0 for v in voltage[:-1])  # 1 s at each period's start voltage
    expected = charge_c / BatteryConfig().mobile_charge_c
    assert soc[0] - soc[-1] == pytest.approx(expected, rel=0.05)
    # the current reported per cell is the load over the pack voltage
    last = battery["state"][-1]
    assert -last.current == pytest.approx(LOAD_W / last.voltage, rel=0.01)


def test_rul_and_temperature_are_consistent_with_the_load(battery):
    rul = [m.value for m in battery["rul"]]
    assert all(b < a for a, b in itertools.pairwise(rul))
    # 0.8 of 80387 C at ~6.5 A lasts under 10000 s; the end comes before the charge runs out
    assert 5000 < rul[-1] < 0.8 * BatteryConfig().mobile_charge_c / (LOAD_W / 24.0)
    temperatures = [m.value for m in battery["temperature"]]
    assert 20.0 < temperatures[-1] < 20.5  # warming by its own losses from 20 degrees C


def test_a_bad_parameter_stops_the_node_with_a_message(ros_stack):
    node = ros_stack.start_node(
        "ow_power",
        "battery",
        name="battery_bad",
        params={"eod_voltage_v": 30.0},
        args=["power:=/bad/power"],
        wait=False,
    )
    assert node.proc.wait(timeout=30) == 1
    assert "battery/eod_voltage_v = 30 V is 5 V per cell" in node.log()
