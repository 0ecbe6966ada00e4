"""An actionlib client that sees every goal's end, however fast the server ends it, and waits in
wall time (rospy/actionlib wiring)."""

from __future__ import annotations

import threading
import time
from typing import Any

import actionlib
import rospy

from ow_runtime.connections import wait_sending

#: s of wall time at most between checks for shutdown while a goal's end is awaited.
_WAKE_S = 0.1


class ActionClient(actionlib.SimpleActionClient):
    """actionlib's ``SimpleActionClient`` without its lost-end race: it assigns the goal handle
    only when ``send_goal`` returns, and drops a transition that arrives before ("Got a
    transition callback on a goal handle that we're not tracking"); a goal the server ends at
    once (a rejection) then never ends for the client, and ``wait_for_result`` waits forever.
    Here transitions and feedback wait until ``send_goal`` has returned.

    Wait with :meth:`wait_for_end` (wall time): ``wait_for_result`` counts ROS time, which under
    ``/use_sim_time`` runs tens of times faster than the wall clock, so its timeout is a matter of
    the machine's load (30 s of simulated time were under a second of wall time in CI while a
    goal's rejection was still on its way)."""

    def __init__(self, ns: str, action_spec: type) -> None:
        self._sending = threading.RLock()
        super().__init__(ns, action_spec)

    def send_goal(
        self, goal: Any, done_cb: Any = None, active_cb: Any = None, feedback_cb: Any = None
    ) -> None:
        with self._sending:
            super().send_goal(goal, done_cb, active_cb, feedback_cb)

    def wait_for_end(self, timeout_s: float) -> bool:
        """Wait until the goal has ended, at most ``timeout_s`` s of wall time; whether it did.

        Raises:
            ValueError: no goal was sent.
        """
        if self.gh is None:
            msg = "wait_for_end: no goal was sent"
            raise ValueError(msg)
        deadline = time.monotonic() + timeout_s
        with self.done_condition:
            while self.simple_state != actionlib.SimpleGoalState.DONE:
                left = deadline - time.monotonic()
                if left <= 0.0 or rospy.is_shutdown():
                    return False
                self.done_condition.wait(min(left, _WAKE_S))
        return True

    def _handle_transition(self, gh: Any) -> None:
        with self._sending:
            pass
        super()._handle_transition(gh)

    def _handle_feedback(self, gh: Any, feedback: Any) -> None:
        with self._sending:
            pass
        super()._handle_feedback(gh, feedback)


def connect(name: str, action: type, timeout_s: float) -> ActionClient:
    """An :class:`ActionClient` of action ``name`` once its server and the client's result and
    feedback subscriptions are connected, on the server's side too
    (:func:`~ow_runtime.connections.wait_sending`): ``wait_for_server`` only checks the
    goal and cancel publishers and one status message, and a result the server sends before it
    writes to the result subscription is lost (the goal never ends for the client).

    Raises:
        TimeoutError: no server, or no connection, within ``timeout_s`` s of wall time.
    """
    client = ActionClient(name, action)
    deadline = time.monotonic() + timeout_s
    while not server_connected(client.action_client):
        if time.monotonic() >= deadline or rospy.is_shutdown():
            msg = f"no {name} action server in {timeout_s} s"
            raise TimeoutError(msg)
        time.sleep(0.01)
    for sub in (client.action_client.result_sub, client.action_client.feedback_sub):
        if not wait_sending(sub, deadline - time.monotonic()):
            msg = f"{name}: {sub.name} not connected in {timeout_s} s"
            raise TimeoutError(msg)
    return client


def server_connected(client: actionlib.ActionClient) -> bool:
    """Whether ``client`` has heard a server's status and is connected to that server on its
    goal, cancel, result and feedback topics: the check of actionlib's ``wait_for_server`` made
    once. Its own loop counts ROS time, which under ``/use_sim_time`` runs many times faster
    than the wall clock (a 30 s timeout was seen to pass in under a second of a loaded CI) or
    not at all while the clock is paused."""
    status = client.last_status_msg
    if status is None:
        return False
    server = status._connection_header["callerid"]
    if not (
        client.pub_goal.impl.has_connection(server)
        and client.pub_cancel.impl.has_connection(server)
    ):
        return False
    return all(
        any(c.callerid_pub == server for c in sub.impl.connections)
        for sub in (client.result_sub, client.feedback_sub)
    )
