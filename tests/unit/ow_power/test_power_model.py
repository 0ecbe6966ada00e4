"""The power model (eqs. 1-4) and its configuration, without ROS."""

import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from ow_power.config import CONFIG_FILE, PowerConfig, RecorderConfig
from ow_power.errors import ConfigError, PowerError
from ow_power.model import PowerIntegrator, integrate_j, intervals_s, joint_power


def test_joint_power_is_looked_up_by_name_in_the_requested_order():
    names, power = joint_power(["b", "a", "c"], [1.0, 2.0, 3.0], [10.0, 20.0, 30.0], ["c", "a"])
    assert names == ("c", "a")
    assert np.allclose(power, [90.0, 40.0])


def test_joint_power_without_selection_keeps_message_order():
    names, power = joint_power(["b", "a"], [1.0, -2.0], [3.0, 4.0])
    assert names == ("b", "a")
    assert np.allclose(power, [3.0, -8.0])


@pytest.mark.parametrize(
    ("names", "velocity", "effort", "joints", "match"),
    [
        (["a", "b"], [1.0], [1.0, 2.0], (), "2 names, 1 velocities and 2 efforts"),
        (["a", "b"], [1.0, 2.0], [], (), "0 efforts"),
        (["a"], [1.0], [1.0], ("a", "j_grinder"), "'j_grinder' is not in the joint state"),
        (["a", "b"], [1.0, math.nan], [1.0, 1.0], (), "joint 'b' has a non-finite"),
    ],
)
def test_joint_power_rejects_what_it_cannot_use(names, velocity, effort, joints, match):
    with pytest.raises(PowerError, match=match):
        joint_power(names, velocity, effort, joints)


def test_constant_torque_and_velocity_give_the_closed_form_power_and_energy():
    config = PowerConfig(auxiliary_power_w=43.0, motor_efficiency=0.8)
    integrator = PowerIntegrator(config)
    tau, omega = np.array([20.0, -5.0]), np.array([0.1, 0.2])  # 2 W and -1 W
    stamps = 100.0 + 0.01 * np.arange(501)  # 5 s at 100 Hz
    for t in stamps:
        sample = integrator.update(t, ["j1", "j2"], omega, tau)
    assert np.allclose(sample.joint_power_w, [2.0, -1.0])
    assert sample.mechanical_power_w == pytest.approx(1.0)
    assert sample.mechanical_power_abs_w == pytest.approx(3.0)
    assert sample.total_power_w == pytest.approx(44.0)
    assert sample.electrical_power_w == pytest.approx(3.0 / 0.8 + 43.0)
    assert sample.mechanical_energy_j == pytest.approx(1.0 * 5.0)
    assert sample.mechanical_energy_abs_j == pytest.approx(3.0 * 5.0)
    assert sample.energy_j == pytest.approx(44.0 * 5.0)
    assert sample.electrical_energy_j == pytest.approx((3.0 / 0.8 + 43.0) * 5.0)


def test_holding_still_costs_p0_times_the_duration():
    integrator = PowerIntegrator(PowerConfig(auxiliary_power_w=43.0))
    for t in np.linspace(0.0, 10.0, 1001):
        sample = integrator.update(t, ["j"], [0.0], [150.0])
    assert sample.mechanical_energy_j == 0.0
    assert sample.energy_j == pytest.approx(430.0)


def test_dt_comes_from_the_stamps_and_gaps_or_time_going_back_are_not_integrated():
    integrator = PowerIntegrator(PowerConfig(auxiliary_power_w=0.0, max_dt_s=0.5))
    energies = [
        integrator.update(t, ["j"], [1.0], [2.0]).mechanical_energy_j
        for t in (0.0, 0.1, 0.3, 0.3, 5.0, 5.2, 1.0, 1.1)
    ]
    #          first, +0.1, +0.2, same,  gap, +0.2, back, +0.1   (x 2 W)
    assert np.allclose(energies, [0.0, 0.2, 0.6, 0.6, 0.6, 1.0, 1.0, 1.2])
    assert integrator.skipped_intervals == 2


def test_batch_integration_follows_the_same_rule_as_the_stream():
    rng = np.random.default_rng(3)
    t = np.cumsum(rng.uniform(-0.2, 0.8, 200))
    p = rng.normal(0.0, 10.0, 200)
    integrator = PowerIntegrator(PowerConfig(auxiliary_power_w=0.0, max_dt_s=0.5))
    dts = []
    for tk, pk in zip(t, p, strict=True):
        sample = integrator.update(tk, ["j"], [pk], [1.0])
        dts.append(sample.dt_s)
    assert sample.mechanical_energy_j == pytest.approx(integrate_j(t, p, max_dt_s=0.5))
    assert dts == intervals_s(t, max_dt_s=0.5).tolist()  # the same doubles
    assert intervals_s([]).size == 0


def test_a_bad_sample_adds_nothing():
    integrator = PowerIntegrator(PowerConfig(auxiliary_power_w=10.0))
    integrator.update(0.0, ["j"], [1.0], [1.0])
    with pytest.raises(PowerError):
        integrator.update(0.5, ["j"], [1.0], [])
    assert integrator.update(1.0, ["j"], [1.0], [1.0]).energy_j == pytest.approx(11.0)


def test_the_workspace_yaml_is_valid_and_holds_the_defaults():
    in_the_workspace = Path(__file__).resolve().parents[3] / "src/ow_power/config/power.yaml"
    assert in_the_workspace == CONFIG_FILE
    document = yaml.safe_load(CONFIG_FILE.read_text())
    assert PowerConfig.from_dict(document["power"]) == PowerConfig()
    assert RecorderConfig.from_dict(document["record"]) == RecorderConfig()


@pytest.mark.parametrize(
    ("cls", "params", "match"),
    [
        (
            PowerConfig,
            {"auxiliary_power_W": 1.0},
            "unknown key 'power/auxiliary_power_W' \\(did you mean 'auxiliary_power_w'\\?\\)",
        ),
        (PowerConfig, {"auxiliary_power_w": "43"}, "power/auxiliary_power_w must be a number"),
        (
            PowerConfig,
            {"auxiliary_power_w": -1.0},
            "power/auxiliary_power_w = -1 W is outside \\[0, inf\\] W",
        ),
        (
            PowerConfig,
            {"motor_efficiency": 0.0},
            "power/motor_efficiency = 0 is outside \\(0, 1\\]",
        ),
        (PowerConfig, {"motor_efficiency": 1.5}, "power/motor_efficiency = 1.5 is outside"),
        (PowerConfig, {"max_dt_s": True}, "power/max_dt_s must be a number, got True"),
        (PowerConfig, {"max_dt_s": 0}, "power/max_dt_s = 0 s is outside \\(0, inf\\] s"),
        (PowerConfig, {"joints": "j_shou_yaw"}, "power/joints must be a list"),
        (PowerConfig, {"joints": ["a", "a"]}, "power/joints lists a name twice"),
        (RecorderConfig, {"compression": "lz4"}, "record/compression = 'lz4' is not one of none"),
        (RecorderConfig, {"topics": []}, "record/topics is empty"),
        (RecorderConfig, {"prefix": "a/b"}, "record/prefix = 'a/b'"),
        (RecorderConfig, {"split_size_mb": -1}, "record/split_size_mb = -1 MB is outside"),
        (RecorderConfig, {"queue_size": 0}, "record/queue_size = 0 is outside \\[1, inf\\]"),
        (RecorderConfig, {"queue_size": 2.5}, "record/queue_size must be an integer, got 2.5"),
        (RecorderConfig, "ow", "record must be a mapping of names to values, got 'ow'"),
    ],
)
def test_config_errors_name_the_key(cls, params, match):
    with pytest.raises(ConfigError, match=match):
        cls.from_dict(params)


def test_config_reports_every_problem_at_once():
    with pytest.raises(ConfigError) as error:
        RecorderConfig.from_dict({"prefix": "", "compresion": "bz2", "split_duration_s": -5})
    lines = str(error.value).splitlines()
    assert lines[0] == "3 problems in record:"
    assert "  - record/prefix = '' must be a non-empty file name without '/'" in lines
    assert "  - record/split_duration_s = -5 s is outside [0, inf] s" in lines
    assert "  - unknown key 'record/compresion' (did you mean 'compression'?)" in lines


def test_config_converts_types():
    config = PowerConfig.from_dict({"auxiliary_power_w": 40, "joints": ["j_b", "j_a"]})
    assert config.auxiliary_power_w == 40.0 and isinstance(config.auxiliary_power_w, float)
    assert config.joints == ("j_b", "j_a")
    assert RecorderConfig.from_dict({"compression": "BZ2"}).compression == "bz2"
