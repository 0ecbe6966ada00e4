"""The antenna mast's goals and look-at solution (no ROS), checked with forward kinematics."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ow_description.description import UNSTOWED
from ow_lander.errors import GoalError
from ow_lander.mast.pan_tilt import (
    PAN_LIMIT_RAD,
    TILT_LIMIT_RAD,
    AntennaPointing,
    MoveWatch,
    check_joints_goal,
    reached,
)


@pytest.fixture(scope="module")
def mast():
    return AntennaPointing()


@pytest.mark.parametrize(
    ("pan", "tilt", "message"),
    [
        (3.3, 0.0, "pan = 3.3 rad is outside the limits [-3.2, 3.2] rad"),
        (-3.21, 0.0, "pan = -3.21 rad is outside the limits [-3.2, 3.2] rad"),
        (0.0, 1.6, "tilt = 1.6 rad is outside the limits [-1.56, 1.56] rad"),
        (0.0, -2.0, "tilt = -2 rad is outside the limits [-1.56, 1.56] rad"),
        (math.nan, 0.0, "pan = nan is not a finite number"),
        (0.0, math.inf, "tilt = inf is not a finite number"),
    ],
)
def test_bad_joint_goals_are_refused_naming_field_value_and_limit(pan, tilt, message):
    with pytest.raises(GoalError) as error:
        check_joints_goal(pan, tilt)
    assert str(error.value) == message


@pytest.mark.parametrize(
    ("pan", "tilt"), [(0.0, 0.0), (PAN_LIMIT_RAD, TILT_LIMIT_RAD), (-PAN_LIMIT_RAD, -1.0)]
)
def test_joint_goals_within_the_limits_are_kept(pan, tilt):
    assert check_joints_goal(pan, tilt) == (pan, tilt)


@pytest.mark.parametrize(
    ("pan", "tilt", "expected"),
    [(0.5, 0.2, True), (0.549, 0.151, True), (0.56, 0.2, False), (0.5, 0.26, False)],
)
def test_arrival_is_within_0_05_rad_on_both_joints(pan, tilt, expected):
    assert reached(pan, tilt, (0.5, 0.2)) is expected


def test_at_zero_the_camera_is_above_the_tilt_axis_looking_along_minus_y(mast):
    pointing = mast.pointing(np.zeros(mast.model.nq))
    assert np.allclose(pointing.axis, [0.0, -1.0, 0.0], atol=1e-4)
    assert pointing.origin[2] > mast.tilt_origin[2] + 0.5


def test_a_positive_tilt_looks_down_and_a_positive_pan_turns_towards_plus_x(mast):
    down = mast.pointing(mast.model.q_from({"j_ant_tilt": 0.5})).axis
    turned = mast.pointing(mast.model.q_from({"j_ant_pan": 0.5})).axis
    assert down[2] < -0.4 and turned[0] > 0.4


POINTS = [
    (1.5, 0.0, -0.155),  # the workspace in front of the arm
    (1.46, -0.4, -0.05),  # OceanWATERS' test: the mound in front of the lander
    (0.0, 3.0, 0.9),
    (-2.0, -1.0, 3.0),
    (2.0, 2.0, 0.0),
    (125800.0, -81170.0, -80533.0),  # OceanWATERS' test: Jupiter
]


@pytest.mark.parametrize("point", POINTS)
def test_look_at_puts_the_point_on_the_pointing_axis_by_fk(mast, point):
    p = np.array(point)
    pan, tilt = mast.look_at(p)
    pointing = mast.pointing(mast.model.q_from({"j_ant_pan": pan, "j_ant_tilt": tilt}))
    miss, ahead = pointing.miss(p)
    assert miss < 1e-6 * max(1.0, ahead)  # on the axis (1 urad)
    assert ahead > 0.0  # in front of the camera, not behind it
    d = p - mast.tilt_origin
    oceanwaters_pan = (math.atan2(d[1], d[0]) + math.pi / 2 + math.pi) % (2 * math.pi) - math.pi
    assert math.cos(pan - oceanwaters_pan) == pytest.approx(1.0, abs=1e-6)


def test_a_tool_frame_point_is_taken_at_the_arm_configuration(mast):
    q = mast.model.q_from(UNSTOWED)
    tip = mast.model.fk(q, "l_scoop_tip")
    offset = np.array([0.1, -0.2, 0.05])
    assert np.allclose(mast.to_base(1, offset, q), tip[:3, :3] @ offset + tip[:3, 3])
    assert np.allclose(mast.to_base(0, offset, q), offset)
    pan, tilt = mast.look_at(mast.to_base(1, np.zeros(3), q), q)
    on_tip = mast.pointing(mast.model.q_from({"j_ant_pan": pan, "j_ant_tilt": tilt}, q))
    assert on_tip.miss(tip[:3, 3])[0] < 1e-6


@pytest.mark.parametrize(
    ("frame", "point", "message"),
    [
        (2, (1.0, 0.0, 0.0), "frame = 2 is neither 0 (base_link) nor 1 (tool, l_scoop_tip)"),
        (-1, (1.0, 0.0, 0.0), "frame = -1 is neither 0"),
        (0, (math.nan, 0.0, 0.0), "point.x = nan is not a finite number"),
        (1, (0.0, 0.0, -math.inf), "point.z = -inf is not a finite number"),
    ],
)
def test_bad_cartesian_goals_are_refused(mast, frame, point, message):
    with pytest.raises(GoalError) as error:
        mast.to_base(frame, np.array(point), np.zeros(mast.model.nq))
    assert message in str(error.value)


def test_points_the_mast_cannot_look_at_are_refused_with_the_reason(mast):
    with pytest.raises(GoalError, match=r"within the camera's lever of 0\.538 m"):
        mast.look_at(mast.tilt_origin + np.array([0.2, 0.0, 0.1]))
    with pytest.raises(GoalError, match=r"needs tilt = 1\.\d+ rad, outside the limits \[-1\.56"):
        mast.look_at(mast.tilt_origin + np.array([0.0, 0.0, -5.0]))  # straight down


def test_move_watch_gives_feedback_every_period_of_stamps_whatever_the_sample_spacing():
    dense = MoveWatch((1.0, 0.0), 30.0, 0.05)
    due = [k * 0.01 for k in range(101) if dense.feedback_due(k * 0.01)]
    assert len(due) == 21 and due[1] == pytest.approx(0.05)  # 0, 0.05, ..., 1.0
    sparse = MoveWatch((1.0, 0.0), 30.0, 0.05)
    assert all(sparse.feedback_due(k * 0.2) for k in range(6))  # each sample late: each due


def test_move_watch_ends_on_arrival_cancel_fault_or_the_timeout_by_stamps():
    watch = MoveWatch((1.0, 0.5), 30.0, 0.05)
    assert watch.end(10.0, 0.0, 0.0, None, preempted=False) is None
    assert watch.end(39.99, 0.5, 0.5, None, preempted=False) is None  # 29.99 s of stamps
    timeout = watch.end(40.01, 0.5, 0.5, None, preempted=False)
    assert timeout.outcome == "aborted" and timeout.hold
    assert "did not reach (1.000, 0.500) rad within 30 s: stopped at pan 0.500" in timeout.text
    arrived = watch.end(11.0, 0.96, 0.53, None, preempted=False)
    assert arrived.outcome == "succeeded" and not arrived.hold
    assert arrived.text == "reached pan 0.960, tilt 0.530 rad (goal 1.000, 0.500)"
    cancelled = watch.end(11.0, 0.96, 0.53, None, preempted=True)  # a cancel before arrival
    assert (cancelled.outcome, cancelled.hold) == ("preempted", True)
    fault = "pan/tilt execution error: j_ant_pan locked (PAN_JOINT_LOCKED)"
    faulted = watch.end(11.0, 0.96, 0.53, fault, preempted=True)  # a fault before anything
    assert faulted.outcome == "aborted" and faulted.text.startswith(fault)
