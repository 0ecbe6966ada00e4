"""actionlib servers whose every goal's end reaches actionlib's own clients, however soon the
server ends the goal (rospy/actionlib wiring).

A stock client can miss a goal's end in two ways. A result must not reach it first, and it must
reach it at all:

* **Before ``send_goal`` returns.** actionlib's ``SimpleActionClient`` (Python and C++) takes
  its goal handle only from ``send_goal``'s return. A result that reaches it earlier takes the
  goal to DONE and the client drops every transition ("Got a transition callback on a goal
  handle that we're not tracking"), so ``wait_for_result`` never returns. A second copy of the
  result would not help. Both clients ignore a result for a goal already DONE and log an error.
  This happens when the server ends a goal within a millisecond (a refusal) and the client's
  thread loses the CPU just after writing the goal (a loaded machine).
* **Before the server writes to the client.** The client's ``wait_for_server`` counts its
  result subscription as soon as the server has answered the handshake. The server writes to
  that subscription only from a moment later, and a result published in between is lost.

Only a result can end a goal for a client: a status array only takes it as far as
WAITING_FOR_RESULT. One that reaches the client before ``send_goal`` returns has its transitions
dropped (and logged), and the goal still ends with its result. So :class:`ActionServer` holds
a result back until its goal arrived :data:`SEND_GOAL_GRACE_S` s (wall time) ago and the server
writes results to the node that sent the goal, waiting at most :data:`CONNECTION_WAIT_S` for
that. A goal that has run that long already has its result sent at once.

A held result is still built when the goal ends: its stamp is the simulation time of the end,
and it carries the goal's terminal status and text. The status arrays are published as before,
the terminal one at the end too. The goal stays in them until its result is out, which is the
invariant actionlib's clients rely on. Only the moment the result is written moves. Where the
simulation stands (held by the lockstep between a mission's steps, or paused) that moment takes
no simulation time. A hold measured in simulation time would never end there: the clock stands.
"""

from __future__ import annotations

import copy
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import actionlib
import rospy
from actionlib.action_server import nop_cb

#: s of wall time: a goal's result is written no sooner than this after the goal arrived, when a
#: stock client whose thread lost the CPU right after writing the goal has returned from
#: ``send_goal`` (a CPU's time slice under load, a few ms, and Python's 5 ms switch interval).
SEND_GOAL_GRACE_S = 0.1
#: s of wall time a result waits at most, counted from its goal's arrival, for the server to
#: write results to the goal's sender (a node that sent a goal without subscribing to results,
#: e.g. ``rostopic pub``, never gets that connection).
CONNECTION_WAIT_S = 2.0
#: s of wall time between checks of a held result.
_POLL_S = 0.005


@dataclass(frozen=True)
class _Arrival:
    """Where a goal came from and when.

    Attributes:
        at_s: s, ``time.monotonic()`` when the server took the goal message.
        sender: caller id of the node that sent it (None: unknown).
    """

    at_s: float
    sender: str | None


class ActionServer(actionlib.ActionServer):
    """``actionlib.ActionServer`` whose results reach actionlib's own clients (see the module's
    text); the same constructor and API, but ``auto_start`` is False unless given: call
    ``start``."""

    def __init__(
        self,
        ns: str,
        action: Any,
        goal_cb: Callable[[Any], None],
        cancel_cb: Callable[[Any], None] = nop_cb,
        auto_start: bool = False,
    ) -> None:
        self._arrivals: dict[str, _Arrival] = {}  # goals without a result yet, by id
        super().__init__(ns, action, goal_cb, cancel_cb, auto_start)

    def internal_goal_callback(self, goal: Any) -> None:
        header = getattr(goal, "_connection_header", None) or {}
        with self.lock:
            arrival = _Arrival(time.monotonic(), header.get("callerid"))
            self._arrivals.setdefault(goal.goal_id.id, arrival)  # a goal sent again is not new
        super().internal_goal_callback(goal)

    def publish_result(self, status: Any, result: Any) -> None:
        """Publish the result of the goal of ``status`` (its tracker's ``GoalStatus``), now or,
        for a goal that arrived just now, once its client can take it; the status now."""
        with self.lock:
            message = self.ActionResult()
            message.header.stamp = rospy.Time.now()
            message.status = copy.deepcopy(status)
            message.result = result
            arrival = self._arrivals.pop(status.goal_id.id, None)
            if arrival is None or self._may_send(arrival):
                self._write(message)
            else:
                self._hold(message, status, arrival)
            self.publish_status()

    def _may_send(self, arrival: _Arrival) -> bool:
        """Whether a result of the goal of ``arrival`` can be written now."""
        since = time.monotonic() - arrival.at_s
        if since < SEND_GOAL_GRACE_S:
            return False
        if arrival.sender is None or since >= CONNECTION_WAIT_S:
            return True
        return bool(self.result_pub.impl.has_connection(arrival.sender))

    def _write(self, message: Any) -> None:
        if self.started and not rospy.is_shutdown():
            self.result_pub.publish(message)

    def _hold(self, message: Any, status: Any, arrival: _Arrival) -> None:
        """Write ``message`` from a thread once :meth:`_may_send`; meanwhile its goal stays in
        the status arrays (a destruction time of 0 is never due)."""
        tracker = next((st for st in self.status_list if st.status is status), None)
        due = None
        if tracker is not None:
            due, tracker.handle_destruction_time = tracker.handle_destruction_time, rospy.Time()
        threading.Thread(
            target=self._write_when_due,
            args=(message, arrival, tracker, due),
            name="result_hold",
            daemon=True,
        ).start()

    def _write_when_due(self, message: Any, arrival: _Arrival, tracker: Any, due: Any) -> None:
        while self.started and not rospy.is_shutdown() and not self._may_send(arrival):
            time.sleep(_POLL_S)
        with self.lock:
            if tracker is not None and tracker.handle_destruction_time == rospy.Time():
                tracker.handle_destruction_time = due  # removed from then on, as it would be
            self._write(message)


class SimpleActionServer(actionlib.SimpleActionServer):
    """``actionlib.SimpleActionServer`` over an :class:`ActionServer`; the same constructor and
    API, but ``auto_start`` is False unless given: call ``start``."""

    def __init__(
        self,
        name: str,
        action: Any,
        execute_cb: Callable[[Any], None] | None = None,
        auto_start: bool = False,
    ) -> None:
        super().__init__(name, action, execute_cb, auto_start=False)
        # actionlib's own server, made above, was never started: it holds no topics.
        self.action_server = ActionServer(
            name, action, self.internal_goal_callback, self.internal_preempt_callback
        )
        if auto_start:
            self.start()
