"""OceanWATERS' single-joint mast actions, Pan and Tilt: their goal check and settle rule,
decided on joint-state stamps (no ROS)."""

from __future__ import annotations

import math

import pytest

from ow_lander.errors import GoalError
from ow_lander.mast.pan_tilt import (
    PAN,
    SETTLE_CHECKS,
    TILT,
    SettleWatch,
)

STILL = (0.0, 0.0)
MOVING = (0.3, 0.0)


@pytest.mark.parametrize(
    ("joint", "value", "text"),
    [
        (PAN, 4.0, "Requested pan 4.0 is not within allowed limits."),
        (PAN, -3.21, "Requested pan -3.21 is not within allowed limits."),
        (PAN, math.nan, "Requested pan nan is not within allowed limits."),
        (TILT, 1.57, "Requested tilt 1.57 is not within allowed limits."),
        (TILT, -math.inf, "Requested tilt -inf is not within allowed limits."),
    ],
)
def test_goals_outside_the_limits_are_refused_with_oceanwaters_text(joint, value, text):
    with pytest.raises(GoalError) as caught:
        joint.check_goal(value)
    assert str(caught.value) == text


@pytest.mark.parametrize(("joint", "value"), [(PAN, 3.2), (PAN, -3.2), (TILT, 1.56), (TILT, 0.0)])
def test_the_limits_themselves_are_allowed(joint, value):
    assert joint.check_goal(value) == value


def _checks(watch: SettleWatch, stamps: list[float]) -> list[float]:
    return [t for t in stamps if watch.due(t)]


def test_checks_come_every_period_from_one_period_after_the_first_state():
    watch = SettleWatch(PAN, 1.0)
    stamps = [10.0 + 0.01 * k for k in range(101)]  # 1 s of joint states at 100 Hz
    checks = _checks(watch, stamps)
    assert checks == pytest.approx([10.2, 10.4, 10.6, 10.8, 11.0])
    assert watch.checks == 5


def test_a_gap_in_the_states_gives_one_check_and_keeps_the_phase():
    watch = SettleWatch(PAN, 1.0)
    assert _checks(watch, [0.0, 0.2, 0.95, 1.0, 1.1, 1.2]) == [0.2, 0.95, 1.0, 1.2]
    assert watch.checks == 6  # the gap counts the three periods it spans: 30 s stay 30 s


def test_the_move_goes_on_while_a_joint_turns():
    watch = SettleWatch(PAN, 1.0)
    assert watch.judge((0.5, 0.0), MOVING, preempted=False) is None
    assert watch.judge((0.5, 0.0), (0.0, 2e-4), preempted=False) is None  # the tilt swings


def test_a_settled_joint_at_its_goal_succeeds_modulo_two_pi():
    end = SettleWatch(PAN, 3.1).judge((3.1 - 2 * math.pi + 0.04, 0.0), STILL, preempted=False)
    assert end is not None
    assert (end.outcome, end.text, end.hold) == ("succeeded", "Reached commanded pan value", False)


def test_a_settled_joint_away_from_its_goal_fails_and_is_held():
    end = SettleWatch(TILT, 0.5).judge((0.0, 0.44), STILL, preempted=False)
    assert end is not None
    assert end.outcome == "aborted"
    assert end.text == "Tilt joint failed to reach its goal position."
    assert end.hold


def test_only_the_actions_joint_is_judged():
    end = SettleWatch(PAN, -1.0).judge((-1.0, 1.2), STILL, preempted=False)
    assert end is not None and end.outcome == "succeeded"


def test_a_move_that_never_settles_is_judged_at_its_last_check_thirty_seconds_on():
    watch = SettleWatch(PAN, 1.0)
    judged = []
    for k in range(3100):
        stamp = 0.01 * k
        if watch.due(stamp):
            judged.append((stamp, watch.judge((1.0, 0.0), MOVING, preempted=False)))
    assert all(end is None for _, end in judged[: SETTLE_CHECKS - 1])
    stamp, end = judged[SETTLE_CHECKS - 1]
    assert stamp == pytest.approx(30.0)
    assert end is not None
    assert end.outcome == "succeeded"


def test_unmeasured_speeds_never_count_as_settled():
    watch = SettleWatch(PAN, 1.0)
    assert watch.judge((1.0, 0.0), (math.nan, 0.0), preempted=False) is None


def test_a_cancel_ends_the_move_before_it_is_judged():
    end = SettleWatch(PAN, 1.0).judge((1.0, 0.0), STILL, preempted=True)
    assert end is not None
    assert (end.outcome, end.text, end.hold) == ("preempted", "Action was preempted", True)
