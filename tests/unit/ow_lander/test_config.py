"""The arm services' parameters: the shipped file, defaults, and errors that name the key."""

import pytest
import yaml

from ow_description.description import DEFAULT_GROUND_Z
from ow_lander.config import CONFIG_FILE, ArmServicesConfig
from ow_lander.errors import ConfigError


def test_the_shipped_file_holds_the_built_in_defaults():
    values = yaml.safe_load(CONFIG_FILE.read_text(encoding="utf-8"))["arm_services"]
    config = ArmServicesConfig.from_dict(values)
    assert config == ArmServicesConfig()
    assert config.fallback_ground_z == DEFAULT_GROUND_Z


@pytest.mark.parametrize(
    ("values", "message"),
    [
        ({"bogus": 1}, "unknown key 'arm_services/bogus'"),
        ({"plan_and_execut": True}, "(did you mean 'plan_and_execute'?)"),
        ({"planner": {"seed": 0}}, "arm_services/planner/seed must be > 0"),
        ({"planner": {"seed": 1.5}}, "arm_services/planner/seed must be an integer, got 1.5"),
        ({"planner": {"rrt_range_rad": "far"}}, "planner/rrt_range_rad must be a number"),
        ({"planner": {"rrt_attempts": 0}}, "planner/rrt_attempts = 0 is outside [1, inf]"),
        ({"planner": {"rrt_goal_bias": 1.5}}, "planner/rrt_goal_bias = 1.5 is outside [0, 1]"),
        ({"planner": 3}, "arm_services/planner must be a mapping, got 3"),
        ({"timing": {"velocity_scale": 2.0}}, "timing/velocity_scale = 2 is outside (0, 1]"),
        ({"timing": {"dig_velocity_scale": 0.0}}, "timing/dig_velocity_scale = 0 is outside"),
        (
            {"timing": {"acceleration_limits": {"j_x": 1.0}}},
            "unknown key 'arm_services/timing/acceleration_limits/j_x'",
        ),
        (
            {"timing": {"acceleration_limits": {"j_shou_yaw": -1}}},
            "acceleration_limits/j_shou_yaw = -1 rad/s^2 is outside",
        ),
        ({"plan_and_execute": 1}, "arm_services/plan_and_execute must be true or false, got 1"),
        ({"fallback_ground_z": float("nan")}, "fallback_ground_z must be finite"),
        (
            {"execution": {"interface": "position_controller"}},
            "(did you mean 'position_controllers'?)",
        ),
        ({"execution": {"ground_detector": "sonar"}}, "is not one of velocity, force"),
        ({"execution": {"start_delay_s": -0.1}}, "execution/start_delay_s = -0.1 is outside"),
        ({"execution": {"ground_relative_tolerance": 1.0}}, "= 1 is outside [0, 1)"),
    ],
)
def test_config_errors_name_the_key(values, message):
    with pytest.raises(ConfigError) as error:
        ArmServicesConfig.from_dict(values)
    assert message in str(error.value)


def test_every_problem_is_reported_at_once():
    with pytest.raises(ConfigError) as error:
        ArmServicesConfig.from_dict(
            {"plan_and_execute": "yes", "planner": {"sed": 3}, "timing": {"sample_period_s": 0}}
        )
    text = str(error.value)
    assert text.startswith("3 problems in arm_services:")
    assert "unknown key 'arm_services/planner/sed' (did you mean 'seed'?)" in text
    assert "timing/sample_period_s = 0 is outside (0, inf]" in text
    assert "plan_and_execute must be true or false, got 'yes'" in text


def test_config_defaults_and_overrides():
    config = ArmServicesConfig.from_dict(
        {
            "plan_and_execute": True,
            "planner": {"seed": 7, "rrt_max_iterations": 200.0},
            "timing": {"acceleration_limits": {"j_shou_yaw": 0.5}},
            "execution": {"interface": "position_controllers"},
        }
    )
    assert config.plan_and_execute and config.planner.seed == 7
    assert config.planner.rrt_max_iterations == 200
    assert isinstance(config.planner.rrt_max_iterations, int)
    assert config.timing.acceleration_limits["j_shou_yaw"] == 0.5
    assert config.timing.acceleration_limits["j_prox_pitch"] == 0.2
    assert config.execution.interface == "position_controllers"
    assert config.execution.goal_tolerance_rad == 0.02
