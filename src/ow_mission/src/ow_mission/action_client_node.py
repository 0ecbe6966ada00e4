"""The mission's steps through OceanWATERS' actions (rospy/actionlib wiring of
:mod:`ow_mission.action_steps`)."""

from __future__ import annotations

import time
from typing import Any

import actionlib
import rospy
from actionlib_msgs.msg import GoalStatus

import owl_msgs.msg
from ow_lander.conversions import fill_fields
from ow_mission.action_steps import StepResponse, action_goal, step_response

#: s of wall time between checks that a new client's result subscription is connected.
_POLL_S = 0.01


class ActionStepClient:
    """Runs mission steps as action goals (``interface: actions``), one client per action.

    Uses the action servers of ``arm_services`` (owl_msgs, plain names).

    Args:
        dig: the mission's dig, "linear" or "circular".
    """

    def __init__(self, dig: str) -> None:
        self.dig = dig
        self._clients: dict[str, actionlib.SimpleActionClient] = {}

    def call(self, step: str, fields: dict[str, Any], timeout_s: float) -> StepResponse:
        """Run step ``step`` (its service request ``fields``) as a goal and wait for its end.

        Raises:
            TimeoutError: no server, or no end within ``timeout_s`` s of wall time (the goal is
                then cancelled).
        """
        action, goal = action_goal(step, fields, self.dig)
        client = self._clients.get(action)
        if client is None:
            client = actionlib.SimpleActionClient(action, getattr(owl_msgs.msg, f"{action}Action"))
            if not client.wait_for_server(rospy.Duration(timeout_s)):
                raise TimeoutError
            _wait_result_connection(client, timeout_s)
            self._clients[action] = client
        client.send_goal(fill_fields(getattr(owl_msgs.msg, f"{action}Goal")(), goal))
        if not client.wait_for_result(rospy.Duration(timeout_s)):
            client.cancel_goal()
            raise TimeoutError
        succeeded = client.get_state() == GoalStatus.SUCCEEDED
        return step_response(action, succeeded, client.get_goal_status_text(), client.get_result())


def _wait_result_connection(client: actionlib.SimpleActionClient, timeout_s: float) -> None:
    """Wait until the client's result subscription is connected: actionlib's wait_for_server does
    not, and a result the server sends before then is lost (the goal never ends here).

    Raises:
        TimeoutError: not within ``timeout_s`` s of wall time.
    """
    deadline = time.monotonic() + timeout_s
    while client.action_client.result_sub.get_num_connections() == 0:
        if time.monotonic() > deadline:
            raise TimeoutError
        time.sleep(_POLL_S)
