"""The mission file's fault schedule (ow_mission.fault_schedule through MissionConfig)."""

from __future__ import annotations

import pytest

from ow_mission.errors import ConfigError
from ow_mission.fault_schedule import MISSION_STEPS, ScheduledFault
from ow_mission.mission import STEPS
from ow_mission.mission_config import MissionConfig


def test_the_schedule_knows_the_mission_steps():
    assert [s.name for s in STEPS] == list(MISSION_STEPS)


def test_a_schedule_at_a_step_and_at_a_time():
    config = MissionConfig.from_dict(
        {
            "faults": [
                {
                    "at_step": "grind",
                    "after_s": 3,
                    "set": {"shou_pitch_joint_locked_failure": True},
                },
                {
                    "at_time_s": 120.0,
                    "set": {"high_power_draw": 200, "activate_high_power_draw": True},
                },
            ]
        }
    )
    step, timed = config.faults
    assert step == ScheduledFault({"shou_pitch_joint_locked_failure": True}, "grind", 3.0)
    assert step.due_s({"unstow": 0.0}) is None
    assert step.due_s({"grind": 50.0}) == pytest.approx(53.0)
    assert timed.due_s({}) == 120.0
    assert step.describe() == "shou_pitch_joint_locked_failure: true at grind + 3 s"
    assert timed.describe() == ("high_power_draw: 200, activate_high_power_draw: true at t = 120 s")


@pytest.mark.parametrize(
    ("faults", "message"),
    [
        (
            [{"at_step": "grind", "set": {"elbow_locked_failure": True}}],
            "mission/faults[0]/set: unknown fault parameter 'elbow_locked_failure'",
        ),
        (
            [{"at_step": "grind", "set": {"high_power_draw": 500.0}}],
            "mission/faults[0]/set: high_power_draw = 500.0 W is outside [1, 360] W",
        ),
        (
            [{"at_step": "grind", "set": {"enable": "yes"}}],
            "mission/faults[0]/set: enable = 'yes' must be a boolean",
        ),
        (
            [{"at_step": "grnd", "set": {"enable": True}}],
            "mission/faults[0]/at_step = 'grnd' is not a step of the mission (steps: unstow, "
            "guarded_move, grind, dig_spoil, discard_spoil, grind_bottom, dig_sample, "
            "deliver_sample, stow) (did you mean 'grind'?)",
        ),
        (
            [{"set": {"enable": True}}],
            "mission/faults[0] needs exactly one of at_step and at_time_s",
        ),
        (
            [{"at_time_s": -1.0, "set": {"enable": True}}],
            "mission/faults[0]/at_time_s = -1.0 must be a number >= 0 s",
        ),
        (
            [{"at_step": "grind", "after_s": "soon", "set": {"enable": True}}],
            "mission/faults[0]/after_s = 'soon' must be a number >= 0 s",
        ),
        (
            [{"at_step": "grind", "set": {"enable": True}, "when": 3}],
            "unknown key 'mission/faults[0]/when'",
        ),
        ([{"at_step": "grind", "set": {}}], "mission/faults[0]/set must map fault parameters"),
        ({"at_step": "grind"}, "mission/faults must be a list of entries"),
    ],
)
def test_bad_schedules_are_refused_naming_key_and_value(faults, message):
    with pytest.raises(ConfigError) as error:
        MissionConfig.from_dict({"faults": faults})
    assert message in str(error.value)
