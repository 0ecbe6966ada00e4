"""The mission's steps through OceanWATERS' actions (rospy/actionlib wiring of
:mod:`ow_mission.action_steps`)."""

from __future__ import annotations

from typing import Any

from actionlib_msgs.msg import GoalStatus

import owl_msgs.msg
from ow_lander.conversions import fill_fields
from ow_mission.action_steps import StepResponse, action_goal, step_response
from ow_runtime.action_client import ActionClient, connect


class ActionStepClient:
    """Runs mission steps as action goals (``interface: actions``), one client per action.

    Uses the action servers of ``arm_services`` (owl_msgs, plain names).

    Args:
        dig: the mission's dig, "linear" or "circular".
    """

    def __init__(self, dig: str) -> None:
        self.dig = dig
        self._clients: dict[str, ActionClient] = {}

    def call(self, step: str, fields: dict[str, Any], timeout_s: float) -> StepResponse:
        """Run step ``step`` (its service request ``fields``) as a goal and wait for its end.

        Raises:
            TimeoutError: no server, or no end within ``timeout_s`` s of wall time (the goal is
                then cancelled).
        """
        action, goal = action_goal(step, fields, self.dig)
        client = self._clients.get(action)
        if client is None:
            client = connect(action, getattr(owl_msgs.msg, f"{action}Action"), timeout_s)
            self._clients[action] = client
        client.send_goal(fill_fields(getattr(owl_msgs.msg, f"{action}Goal")(), goal))
        if not client.wait_for_end(timeout_s):
            client.cancel_goal()
            raise TimeoutError
        succeeded = client.get_state() == GoalStatus.SUCCEEDED
        return step_response(action, succeeded, client.get_goal_status_text(), client.get_result())
