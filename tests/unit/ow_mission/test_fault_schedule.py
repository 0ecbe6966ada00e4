"""The mission file's fault schedule (ow_mission.fault_schedule through MissionConfig)."""

from __future__ import annotations

import pytest

from ow_mission.errors import ConfigError
from ow_mission.fault_schedule import MISSION_STEPS, ScheduledFault, ScheduleTimer
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


# ------------------------------------------------------------------------ when entries come due
LOCK = {"shou_pitch_joint_locked_failure": True}
DRAW = {"high_power_draw": 200.0, "activate_high_power_draw": True}


def _timer() -> ScheduleTimer:
    return ScheduleTimer(
        [
            ScheduledFault(LOCK, at_step="grind", after_s=3.0),
            ScheduledFault(DRAW, at_time_s=20.0),
            ScheduledFault({"enable": True}, at_step="unstow"),
        ]
    )


def test_an_entry_at_a_step_is_due_after_the_steps_start_and_not_before():
    timer = _timer()
    assert timer.due(1000.0) == [(1, timer.schedule[1], 20.0)]  # grind, unstow not started
    timer.step_started("grind", 40.0)
    assert timer.due(42.99) == []
    assert timer.due(43.0) == [(0, timer.schedule[0], 43.0)]


def test_an_entry_at_a_steps_start_is_due_at_that_start():
    timer = _timer()
    timer.step_started("unstow", 0.5)
    assert [index for index, _, _ in timer.due(0.5)] == [2]


@pytest.mark.parametrize(
    ("now_s", "expected"),
    [(19.0, [2]), (20.0, [2, 1]), (60.0, [2, 1, 0])],
)
def test_entries_come_due_once_in_order_of_due_time(now_s, expected):
    timer = _timer()
    timer.step_started("unstow", 0.0)
    timer.step_started("grind", 40.0)
    assert [index for index, _, _ in timer.due(now_s)] == expected
    assert timer.due(now_s) == []  # handed out once
    assert [f.index for f in timer.never_due()] == [i for i in (0, 1, 2) if i not in expected]


def test_the_next_due_time_is_the_earliest_known_not_handed_out():
    """What the mission holds the simulation at: entry 1 at 20 s; entry 0 (grind + 3 s) only
    once the grind has started; nothing once all are handed out."""
    timer = _timer()
    assert timer.next_due_s() == 20.0  # entry 2 waits for unstow, entry 0 for the grind
    timer.step_started("unstow", 0.5)
    assert timer.next_due_s() == 0.5
    timer.due(0.5)
    assert timer.next_due_s() == 20.0
    timer.due(20.0)
    assert timer.next_due_s() is None
    timer.step_started("grind", 40.0)
    assert timer.next_due_s() == 43.0
    timer.due(43.0)
    assert timer.next_due_s() is None


def test_a_step_started_again_keeps_its_first_start():
    timer = _timer()
    timer.step_started("grind", 40.0)
    timer.step_started("grind", 90.0)
    assert (0, timer.schedule[0], 43.0) in timer.due(43.0)


def test_entries_that_never_came_due_are_reported_not_applied():
    timer = _timer()
    timer.due(25.0)
    left = timer.never_due()
    assert [(f.index, f.due_s, f.applied_s, f.applied) for f in left] == [
        (0, None, None, False),
        (2, None, None, False),
    ]
    assert left[0].to_json() == {
        "index": 0,
        "description": "shou_pitch_joint_locked_failure: true at grind + 3 s",
        "changes": LOCK,
        "due_s": None,
        "applied_s": None,
        "error": "",
    }
