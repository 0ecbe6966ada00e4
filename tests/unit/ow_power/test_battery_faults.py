"""The power faults on the battery without ROS (ow_power.battery_faults): extra load, custom
profile, disconnected cells, forced low SOC, capacity loss, thermal failure."""

from __future__ import annotations

import pytest

from ow_faults.injection import FORCED_TEMPERATURE_C, FaultSet, read_power_profile
from ow_power.battery import Battery
from ow_power.battery_faults import PowerFaults
from ow_power.config import BatteryConfig


@pytest.fixture()
def faults():
    return PowerFaults(Battery(BatteryConfig()))


def step(faults: PowerFaults, load_w: float = 50.0, seconds: int = 1):
    for _ in range(seconds):
        faults.battery.set_extra_load(faults.extra_load_w())
        state = faults.battery.update(load_w, 1.0)
    return state


def test_high_power_draw_adds_its_watts_only_while_activated(faults):
    faults.update(FaultSet(high_power_draw=200.0))
    assert faults.extra_load_w() == 0.0
    faults.update(FaultSet(high_power_draw=200.0, activate_high_power_draw=True))
    assert step(faults).load_w == pytest.approx(250.0)
    faults.update(FaultSet(high_power_draw=200.0))
    assert step(faults).load_w == pytest.approx(50.0)


def test_the_custom_profile_runs_from_its_activation(faults):
    step(faults, seconds=3)
    events = faults.update(FaultSet(activate_custom_fault=True))
    assert events == ["custom power profile example_fault.csv started"]
    watts = read_power_profile("example_fault.csv").watts
    loads = [step(faults).load_w - 50.0 for _ in range(len(watts) + 2)]
    assert loads == pytest.approx([*watts, 0.0, 0.0])


def test_disconnected_cells_stay_disconnected(faults):
    faults.update(FaultSet(battery_nodes_to_disconnect=2))
    assert faults.battery.cells_connected == 6
    events = faults.update(FaultSet(battery_nodes_to_disconnect=2, disconnect_battery_nodes=True))
    assert events == ["2 cells disconnected"] and faults.battery.cells_connected == 4


def test_low_soc_capacity_loss_and_thermal_failure_cross_the_detector_thresholds(faults):
    faults.update(FaultSet(low_state_of_charge=True))
    assert faults.battery.state.soc <= 0.1
    before = step(faults).soc
    faults.update(FaultSet(low_state_of_charge=True, instantaneous_capacity_loss=True))
    after = step(faults).soc
    assert (before - after) / before >= 0.05
    faults.update(FaultSet(thermal_failure=True))
    assert all(step(faults).temperature_c >= 70.0 for _ in range(5))
    assert faults.battery.state.temperature_c == pytest.approx(FORCED_TEMPERATURE_C, abs=0.05)
    faults.update(FaultSet())
    assert step(faults, seconds=30).temperature_c < 70.0
