"""The battery (ow_power.battery and its parts) against figures computed independently of it.

* State of charge: over a window at constant load, the drop equals the charge drawn (the current
  ``P / V`` from the reported pack voltage, summed over the steps) over the pack's mobile charge
  from the configuration.
* Remaining useful life: a separate simulation of ProgPy's cell model at the same constant
  power, stepped explicitly to its end-of-discharge voltage, gives the energy the pack still
  delivers (the integral of ``n v i dt``); RUL must be that energy over the power.
* Fault hooks: drain ratios against power ratios and cell counts.
"""

from __future__ import annotations

import dataclasses
import functools
import math

import genpy
import numpy as np
import pytest
import yaml

from ow_power.battery import Battery, BatteryState
from ow_power.battery_feed import LoadFeed, LoadPeriod
from ow_power.battery_messages import MAX_RUL_S, battery_messages, rul_int32
from ow_power.battery_model import make_cell_model, state_at_soc
from ow_power.battery_prediction import predict_eod
from ow_power.config import CONFIG_FILE, BatteryConfig
from ow_power.errors import ConfigError, PowerError

STEP_S = 10.0  # s per update in these tests (the battery steps its cell every 1 s inside)


def _run(battery: Battery, load_w: float, seconds: float, step_s: float = STEP_S) -> list:
    return [battery.update(load_w, step_s) for _ in range(round(seconds / step_s))]


@functools.cache
def _soc_rate(load_w: float, extra_w: float = 0.0, disconnected: int = 0) -> float:
    """SOC per s over 600 s at a constant load, after 100 s to settle."""
    battery = Battery(BatteryConfig(initial_soc=0.8))
    battery.set_extra_load(extra_w)
    battery.disconnect_cells(disconnected)
    _run(battery, load_w, 100.0)
    start = battery.state.soc
    _run(battery, load_w, 600.0)
    return (start - battery.state.soc) / 600.0


# ------------------------------------------------------------------------- state of charge
@pytest.mark.parametrize("load_w", [43.0, 150.0, 300.0])
def test_the_soc_drop_is_the_charge_drawn_over_the_capacity(load_w):
    config = BatteryConfig(initial_soc=0.8)
    battery = Battery(config)
    _run(battery, load_w, 100.0)
    start = battery.state
    charge_c = 0.0
    for _ in range(180):  # 1800 s
        voltage_v = battery.state.voltage_v  # the pack voltage the step starts from
        battery.update(load_w, STEP_S)
        charge_c += load_w / voltage_v * STEP_S
    expected = charge_c / config.mobile_charge_c
    drop = start.soc - battery.state.soc
    assert drop == pytest.approx(expected, rel=0.05)
    assert battery.state.soc == pytest.approx(battery.true_soc, abs=1e-6)  # the UKF tracks


def test_the_initial_state_is_the_configured_one():
    state = Battery(BatteryConfig()).state
    assert state.soc == pytest.approx(0.95)
    assert state.temperature_c == pytest.approx(20.0)
    assert state.rul_s == math.inf  # no load yet
    assert 6 * 3.0 < state.voltage_v < 6 * 4.2  # six Li-ion cells, above VEOD 18 V


# -------------------------------------------------------------------- remaining useful life
def _remaining_energy_j(config: BatteryConfig, power_w: float, after_s: float) -> float:
    """J the pack still delivers at ``power_w`` after ``after_s`` s, from a plain simulation."""
    model = make_cell_model(config)
    n = config.cells_in_series
    x = model.StateContainer(state_at_soc(model, config.initial_soc, 293.15)[:, None])
    energy_j, t = 0.0, 0.0
    while True:
        v = float(model.output(x)["v"])
        if v < model.parameters["VEOD"]:
            return energy_j
        i = power_w / n / v
        if t >= after_s:
            energy_j += n * v * i * 1.0
        x = model.next_state(x, model.InputContainer({"i": i}), 1.0)
        t += 1.0


@pytest.mark.parametrize(
    ("soc", "power_w", "after_s"), [(0.3, 240.0, 600.0), (0.2, 100.0, 1000.0), (0.12, 43.0, 500.0)]
)
def test_rul_is_the_remaining_energy_over_the_power(soc, power_w, after_s):
    config = BatteryConfig(initial_soc=soc)
    remaining_j = _remaining_energy_j(config, power_w, after_s)
    battery = Battery(config)
    _run(battery, power_w, after_s)
    assert battery.state.rul_s == pytest.approx(remaining_j / power_w, rel=0.10)


def test_rul_shrinks_with_the_load_and_is_unbounded_without_one():
    model = make_cell_model(BatteryConfig())
    x = state_at_soc(model, 0.5, 293.15)
    light, heavy = predict_eod(model, x, 10.0), predict_eod(model, x, 40.0)
    assert heavy < light / 3.5
    assert predict_eod(model, x, 0.0) == math.inf
    assert predict_eod(model, state_at_soc(model, 0.0001, 293.15), 10.0) == 0.0
    with pytest.raises(ValueError, match="state has 3 values, expected 8"):
        predict_eod(model, x[:3], 10.0)


# ---------------------------------------------------------------------------- fault hooks
def test_an_extra_load_drains_in_proportion_to_the_power():
    ratio = _soc_rate(43.0, extra_w=200.0) / _soc_rate(43.0)
    assert ratio == pytest.approx(243.0 / 43.0, rel=0.05)


@pytest.mark.parametrize("disconnected", [1, 2, 3])
def test_disconnected_cells_leave_the_load_to_the_others(disconnected):
    ratio = _soc_rate(100.0, disconnected=disconnected) / _soc_rate(100.0)
    assert ratio == pytest.approx(6 / (6 - disconnected), rel=0.05)


def test_disconnection_is_irreversible_and_lowers_the_pack_voltage():
    battery = Battery(BatteryConfig())
    full = battery.state.voltage_v
    battery.disconnect_cells(2)
    battery.disconnect_cells(2)  # the same count again: nothing changes
    assert battery.cells_connected == 4
    assert battery.state.voltage_v == pytest.approx(full * 4 / 6)
    with pytest.raises(PowerError, match="cells to disconnect = 1 is below the 2 already"):
        battery.disconnect_cells(1)


def test_a_capacity_loss_drops_the_soc_by_that_share_and_shortens_the_life():
    battery = Battery(BatteryConfig(initial_soc=0.6))
    before = battery.update(60.0, STEP_S)
    battery.lose_capacity(0.1)
    assert battery.state.soc == pytest.approx(0.9 * before.soc, rel=1e-9)
    after = battery.update(60.0, STEP_S)
    # The life shortens by most of the time the lost charge would have lasted (not all of it: the
    # positive electrode, untouched, is emptier at the same charge, so its voltage holds longer).
    lost_s = 0.1 * before.soc * battery.capacity_c / before.current_a
    shortened_s = before.rul_s - STEP_S - after.rul_s
    assert 0.5 * lost_s < shortened_s <= lost_s


def test_forced_low_soc_and_thermal_failure_show_at_once_and_hold():
    battery = Battery(BatteryConfig())
    battery.force_soc(0.09)
    assert battery.state.soc == pytest.approx(0.09, abs=1e-6)
    assert battery.update(43.0, STEP_S).soc < 0.09
    battery.force_thermal_failure(75.0)
    assert battery.state.temperature_c == pytest.approx(75.0)
    assert _run(battery, 43.0, 300.0)[-1].temperature_c == pytest.approx(75.0, abs=0.5)
    battery.clear_thermal_failure()
    assert _run(battery, 43.0, 600.0)[-1].temperature_c < 21.0  # 100 s time constant


def test_the_end_of_discharge_stops_the_battery():
    battery = Battery(BatteryConfig(initial_soc=0.08))
    states = _run(battery, 300.0, 3000.0)
    last = states[-1]
    assert last.depleted and last.rul_s == 0.0 and last.soc < 0.01
    assert last.current_a == 0.0
    assert last.voltage_v < 18.0
    first_depleted = next(s for s in states if s.depleted)
    assert 0.0 < first_depleted.time_s < 3000.0


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (lambda b: b.update(-1.0, 1.0), r"load_w = -1 W is below 0 W"),
        (lambda b: b.update(math.nan, 1.0), r"load_w must be finite, got nan W"),
        (lambda b: b.update(10.0, 0.0), r"dt_s = 0 s must be above 0 s"),
        (lambda b: b.set_extra_load(-5.0), r"extra load -5 W is below 0 W"),
        (lambda b: b.disconnect_cells(4), r"cells to disconnect = 4 is outside \[0, 3\]"),
        (lambda b: b.disconnect_cells(1.5), r"cells to disconnect must be an integer, got 1.5"),
        (lambda b: b.lose_capacity(1.0), r"capacity loss 1 is outside \[0, 1\)"),
        (lambda b: b.force_soc(0.99), r"forced SOC 0.99 is outside \[0, 0.95\]"),
        (
            lambda b: b.force_thermal_failure(300.0),
            r"forced temperature 300 degC is outside \(-273.15, 200\] degC",
        ),
    ],
)
def test_bad_requests_raise_power_errors_naming_value_and_limit(call, match):
    with pytest.raises(PowerError, match=match):
        call(Battery(BatteryConfig()))


# ---------------------------------------------------------------------------- determinism
def _profile(config: BatteryConfig) -> list[BatteryState]:
    battery = Battery(config)
    states = [battery.update(43.0 + 50.0 * math.sin(k / 7.0) ** 2, 1.0) for k in range(120)]
    battery.set_extra_load(200.0)
    battery.disconnect_cells(1)
    battery.lose_capacity(0.06)
    states += [battery.update(60.0, 2.5) for _ in range(40)]
    return states


@pytest.mark.parametrize("noise", [0.0, 0.05])
def test_the_same_inputs_give_bit_identical_outputs(noise):
    config = BatteryConfig(voltage_noise_v=noise, temperature_noise_c=noise, noise_seed=7)
    assert _profile(config) == _profile(config)  # dataclass equality: every float exactly


def test_the_noise_seed_changes_the_run_and_the_estimate_stays_close():
    noisy = _profile(BatteryConfig(voltage_noise_v=0.05, temperature_noise_c=0.2, noise_seed=1))
    other = _profile(BatteryConfig(voltage_noise_v=0.05, temperature_noise_c=0.2, noise_seed=2))
    exact = _profile(BatteryConfig())
    assert noisy != other
    assert np.allclose([s.soc for s in noisy], [s.soc for s in exact], atol=2e-3)


# ------------------------------------------------------------------------------- the feed
def test_the_feed_turns_100_hz_samples_into_1_s_means_with_the_same_energy():
    feed = LoadFeed(period_s=1.0, max_gap_s=1.0)
    periods: list[LoadPeriod] = []
    energy_j = 0.0
    for k in range(351):  # 3.5 s at 100 Hz, a step from 40 W to 100 W at 1.5 s
        power = 40.0 if k <= 150 else 100.0
        periods += feed.add(100.0 + k * 0.01, power)
        if 0 < k <= 300:
            energy_j += power * 0.01
    assert [p.end_s for p in periods] == pytest.approx([101.0, 102.0, 103.0])
    assert [p.mean_load_w for p in periods] == pytest.approx([40.0, 70.0, 100.0])
    assert sum(p.mean_load_w * p.duration_s for p in periods) == pytest.approx(energy_j)


def test_the_feed_splits_a_sample_across_period_ends_and_restarts_after_gaps():
    feed = LoadFeed(period_s=1.0, max_gap_s=5.0)
    assert feed.add(0.0, 10.0) == []
    done = feed.add(2.5, 20.0)  # one sample covering two whole periods and half a third
    assert [(p.end_s, p.mean_load_w) for p in done] == [(1.0, 20.0), (2.0, 20.0)]
    assert feed.add(9.0, 30.0) == [] and feed.restarts == 1  # a 6.5 s gap
    assert feed.add(8.0, 30.0) == [] and feed.restarts == 2  # back in time
    assert [p.end_s for p in feed.add(9.0, 30.0)] == [9.0]
    with pytest.raises(PowerError, match=r"sample \(nan s, 1.0 W\) is not finite"):
        feed.add(math.nan, 1.0)
    with pytest.raises(PowerError, match=r"period_s = 0.0 s must be finite and above 0 s"):
        LoadFeed(period_s=0.0, max_gap_s=1.0)


# ------------------------------------------------------------------------------- messages
@pytest.mark.parametrize(
    ("rul_s", "value"),
    [(12.9, 12), (-3.0, 0), (math.inf, MAX_RUL_S), (1e12, MAX_RUL_S), (math.nan, 0)],
)
def test_the_rul_goes_out_as_whole_seconds_within_int32(rul_s, value):
    assert rul_int32(rul_s) == value


def test_the_messages_share_one_header_and_mark_disconnected_cells():
    battery = Battery(BatteryConfig())
    battery.disconnect_cells(2)
    state = battery.update(100.0, 1.0)
    soc, rul, temperature, full = battery_messages(state, genpy.Time(12, 5), 6, 80387.0)
    assert soc.header == rul.header == temperature.header == full.header
    assert soc.header.stamp == genpy.Time(12, 5) and soc.header.frame_id == "base_link"
    assert (soc.value, rul.value, temperature.value) == (
        state.soc,
        rul_int32(state.rul_s),
        state.temperature_c,
    )
    assert full.cell_voltage[:4] == pytest.approx([state.voltage_v / 4] * 4)
    assert all(math.isnan(v) for v in full.cell_voltage[4:]) and len(full.cell_voltage) == 6
    assert full.current == pytest.approx(-state.current_a, rel=1e-6)  # float32
    assert state.current_a == pytest.approx(100.0 / state.voltage_v, rel=0.01)
    assert full.capacity == pytest.approx(80387.0 / 3600.0)


# ---------------------------------------------------------------------------- configuration
def test_the_workspace_yaml_holds_the_battery_defaults():
    document = yaml.safe_load(CONFIG_FILE.read_text())
    assert BatteryConfig.from_dict(document["battery"]) == BatteryConfig()
    assert BatteryConfig().period_s == 1.0


@pytest.mark.parametrize(
    ("params", "match"),
    [
        (
            {"initial_SOC": 0.5},
            r"unknown key 'battery/initial_SOC' \(did you mean 'initial_soc'\?\)",
        ),
        ({"initial_soc": 0.0}, r"battery/initial_soc = 0 is outside \(0, 1\]"),
        ({"cells_in_series": 2.5}, r"battery/cells_in_series must be an integer, got 2.5"),
        (
            {"eod_voltage_v": 30.0},
            r"battery/eod_voltage_v = 30 V is 5 V per cell for 6 cells, outside \[2.5, 4\] V",
        ),
        ({"update_rate_hz": 0.0}, r"battery/update_rate_hz = 0 Hz is outside \(0, inf\] Hz"),
        ({"voltage_noise_v": -0.1}, r"battery/voltage_noise_v = -0.1 V is outside \[0, inf\] V"),
    ],
)
def test_bad_battery_parameters_are_reported_by_key(params, match):
    with pytest.raises(ConfigError, match=match):
        BatteryConfig.from_dict(params)


def test_a_pack_that_starts_at_its_end_of_discharge_is_refused():
    config = dataclasses.replace(BatteryConfig(), initial_soc=0.01)
    with pytest.raises(PowerError, match=r"initial cell voltage .* at SOC 0.01 is not above"):
        Battery(config)
