"""Loads drawn besides the motors (ow_power.loads) and their place in the power model (no ROS)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ow_power.config import PowerConfig
from ow_power.errors import PowerError
from ow_power.loads import COMMS_POWER_W, LoadSum
from ow_power.model import PowerIntegrator


def test_the_sum_keeps_the_latest_load_of_each_source():
    loads = LoadSum()
    assert loads.total_w == 0.0
    loads.update("/pan_tilt", COMMS_POWER_W)
    loads.update("/camera", 1.6)
    assert loads.total_w == pytest.approx(11.2)
    loads.update("/pan_tilt", 0.0)
    assert loads.total_w == pytest.approx(1.6)


@pytest.mark.parametrize("value", [-1.0, math.nan, math.inf])
def test_a_bad_load_is_refused_and_the_previous_one_kept(value):
    loads = LoadSum()
    loads.update("/pan_tilt", 9.6)
    with pytest.raises(PowerError, match=f"load of /pan_tilt = {value} W"):
        loads.update("/pan_tilt", value)
    assert loads.total_w == pytest.approx(9.6)


def test_a_dated_load_counts_in_the_samples_after_its_time_and_nowhere_else():
    loads = LoadSum()
    loads.update("/mast", COMMS_POWER_W, since_s=1.0)
    loads.update("/mast", 0.0, since_s=5.0)
    stamps = 0.01 * np.arange(1, 701)
    drawn = np.array([loads.at(t) for t in stamps])
    loaded = stamps[drawn > 0]
    assert set(drawn) == {0.0, COMMS_POWER_W}
    assert (loaded[0], loaded[-1]) == (pytest.approx(1.01), pytest.approx(5.0))
    assert len(loaded) == 400


def test_a_load_with_no_date_counts_from_the_next_sample_read():
    loads = LoadSum()
    assert loads.at(1.0) == 0.0
    loads.update("/camera", 1.6)
    assert loads.at(1.01) == pytest.approx(1.6)


def test_a_load_dated_before_a_sample_already_read_is_refused_naming_both_times():
    loads = LoadSum()
    loads.update("/mast", COMMS_POWER_W, since_s=0.5)
    loads.at(2.0)
    with pytest.raises(PowerError, match=r"since 1\.000000 s: .* integrated up to 2\.000000 s"):
        loads.update("/mast", 0.0, since_s=1.0)
    with pytest.raises(PowerError, match="since nan s: the time is not finite"):
        loads.update("/mast", 0.0, since_s=math.nan)
    assert loads.at(2.01) == COMMS_POWER_W


def test_a_later_change_replaces_what_its_source_had_scheduled_after_it():
    loads = LoadSum()
    loads.update("/mast", COMMS_POWER_W, since_s=1.0)
    loads.update("/mast", 0.0, since_s=9.0)
    loads.update("/mast", 2.0, since_s=3.0)  # the 0 at 9 s is gone with it
    assert [loads.at(t) for t in (1.0, 2.0, 4.0, 10.0)] == [0.0, COMMS_POWER_W, 2.0, 2.0]


def test_a_reset_clock_keeps_what_each_source_draws_then():
    loads = LoadSum()
    loads.update("/mast", COMMS_POWER_W, since_s=1.0)
    assert loads.at(3.0) == COMMS_POWER_W
    assert loads.at(0.5) == COMMS_POWER_W  # back in time: the schedule starts afresh
    loads.update("/mast", 0.0, since_s=0.5)
    assert loads.at(0.6) == 0.0


def test_a_load_adds_to_p0_in_every_power_and_its_energy():
    config = PowerConfig(auxiliary_power_w=43.0, motor_efficiency=0.9)
    integrator = PowerIntegrator(config)
    names, omega, tau = ["j1"], np.array([0.1]), np.array([9.0])  # 0.9 W of motor
    stamps = 0.01 * np.arange(301)  # 3 s at 100 Hz; comms drawn over (1, 2] s
    for t in stamps:
        load = COMMS_POWER_W if 1.0 < t <= 2.0 + 1e-9 else 0.0
        sample = integrator.update(t, names, omega, tau, load)
        if load:
            assert sample.auxiliary_power_w == pytest.approx(43.0 + 9.6)
            assert sample.total_power_w == pytest.approx(0.9 + 52.6)
            assert sample.electrical_power_w == pytest.approx(1.0 + 52.6)
    assert sample.auxiliary_power_w == pytest.approx(43.0)
    assert sample.energy_j == pytest.approx(3.0 * (0.9 + 43.0) + 1.0 * 9.6)
    assert sample.electrical_energy_j == pytest.approx(3.0 * (1.0 + 43.0) + 1.0 * 9.6)
    assert sample.mechanical_energy_j == pytest.approx(3.0 * 0.9)


def test_a_load_dated_at_the_sample_just_read_counts_from_the_next_one():
    loads = LoadSum()
    assert loads.at(16.18) == 0.0
    loads.update("/mast", COMMS_POWER_W, since_s=16.18 - 1e-9)  # the stamp, written back
    assert loads.at(16.18 + 1e-9) == 0.0  # the same sample
    assert loads.at(16.19) == COMMS_POWER_W
