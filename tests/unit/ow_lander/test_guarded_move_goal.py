"""OceanWATERS' deprecated GuardedMove action on the paper's guarded move: the request a goal
becomes and the end an execution gives (no ROS)."""

from __future__ import annotations

import numpy as np
import pytest

from ow_lander.actions.guarded_move import (
    GROUND_DETECTED,
    NO_GROUND_DETECTED,
    guarded_move_end,
    guarded_move_request,
)
from ow_lander.actions.outcomes import STOP_DURING_EXECUTION
from ow_lander.execution.monitor import ExecutionResult
from ow_lander.operations.ground import effective_parameters


def test_a_goal_becomes_the_guarded_move_request_of_the_service():
    request = guarded_move_request((2.0, 0.1, 0.3), (0.0, 0.0, 2.0), np.float32(0.5))
    assert request == {
        "use_defaults": False,
        "x": 2.0,
        "y": 0.1,
        "z": 0.3,
        "direction_x": 0.0,
        "direction_y": 0.0,
        "direction_z": 2.0,
        "search_distance": 0.5,
    }
    assert effective_parameters("guarded_move", request) == {
        k: v for k, v in request.items() if k != "use_defaults"
    }


def test_ground_found_succeeds_with_the_contact_point():
    result = ExecutionResult(
        True, "ground at t=3.2 s", ground_found=True, ground_position=np.array([1.7, 0.0, -0.15])
    )
    end = guarded_move_end(result, cancelled=False)
    assert (end.status, end.text, end.success) == ("succeeded", GROUND_DETECTED, True)
    assert end.final == pytest.approx((1.7, 0.0, -0.15))


@pytest.mark.parametrize(
    "result",
    [
        ExecutionResult(False, "no ground within 0.10 m", reports_ground=True),
        ExecutionResult(True, "reached the end of a search of no length"),
    ],
)
def test_a_search_that_ends_without_ground_succeeds_with_success_false(result):
    end = guarded_move_end(result, cancelled=False)
    assert (end.status, end.text, end.success, end.final) == (
        "succeeded",
        NO_GROUND_DETECTED,
        False,
        (0.0, 0.0, 0.0),
    )


@pytest.mark.parametrize(
    ("result", "cancelled", "status", "text"),
    [
        (
            ExecutionResult(False, "joint locked", fault="j_dist_pitch locked"),
            False,
            "aborted",
            "joint locked",
        ),
        (
            ExecutionResult(False, "stopped at t=2 s", stopped=True),
            False,
            "aborted",
            STOP_DURING_EXECUTION,
        ),
        (
            ExecutionResult(False, "stopped at t=2 s", stopped=True),
            True,
            "preempted",
            "Action was preempted: stopped at t=2 s",
        ),
        (
            ExecutionResult(False, "tracking error 0.3 rad"),
            False,
            "aborted",
            "tracking error 0.3 rad",
        ),
    ],
)
def test_failures_stops_and_cancels(result, cancelled, status, text):
    end = guarded_move_end(result, cancelled)
    assert (end.status, end.text, end.success, end.final) == (status, text, False, (0, 0, 0))
