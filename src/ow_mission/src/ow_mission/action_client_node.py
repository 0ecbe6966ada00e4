"""The mission's steps through OceanWATERS' actions (rospy/actionlib wiring of
:mod:`ow_mission.action_steps`), and DockIngestSample after the delivery."""

from __future__ import annotations

from typing import Any

from actionlib_msgs.msg import GoalStatus

import owl_msgs.msg
from ow_lander.conversions import fill_fields
from ow_lander.msg import DockIngestSampleAction, DockIngestSampleGoal
from ow_mission.action_steps import StepResponse, action_goal, step_response
from ow_mission.mission import DOCK_INGEST_SAMPLE, Ingestion
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


def ingest_sample(timeout_s: float) -> Ingestion:
    """Send OceanWATERS' ``DockIngestSample`` (actionlib's client; served by the stack's
    monitors node) and wait for its end, at most ``timeout_s`` s of wall time.

    Returns:
        What it ingested (``sample_ingested``) or why not, its ``wall_time_s`` and
        ``sim_time_s`` left for the caller.
    """
    try:
        client = connect(DOCK_INGEST_SAMPLE, DockIngestSampleAction, timeout_s)
    except TimeoutError:
        return Ingestion(message=f"no {DOCK_INGEST_SAMPLE} server within {timeout_s:g} s (wall)")
    client.send_goal(DockIngestSampleGoal())
    try:
        if not client.wait_for_end(timeout_s):
            client.cancel_goal()
            return Ingestion(message=f"no end within {timeout_s:g} s (wall)")
        result = client.get_result()
        return Ingestion(
            sample_ingested=bool(result is not None and result.sample_ingested),
            succeeded=client.get_state() == GoalStatus.SUCCEEDED,
            message=client.get_goal_status_text(),
        )
    finally:
        # The mission ingests once: the server's status heartbeat need not come to it after.
        ac = client.action_client
        for topic in (ac.status_sub, ac.result_sub, ac.feedback_sub, ac.pub_goal, ac.pub_cancel):
            topic.unregister()
