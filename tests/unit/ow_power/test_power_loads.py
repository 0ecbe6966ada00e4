"""Loads drawn besides the motors (ow_power.loads) and their place in the power model (no ROS)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ow_power.config import PowerConfig
from ow_power.errors import PowerError
from ow_power.loads import COMMS_POWER_W, LoadSum
from ow_power.model import PowerIntegrator


def test_the_sum_keeps_the_latest_load_of_each_publisher():
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
