"""Action feedback stamped with the simulation time of the state it describes, none dropped
(rospy/actionlib wiring only)."""

from __future__ import annotations

import math
from typing import Any

import rospy

#: Messages rospy may queue per subscriber of a feedback topic before dropping the oldest
#: (actionlib's default is 50: a server lagging a simulation that runs tens of times faster than
#: real time dropped feedback).
FEEDBACK_QUEUE = 100000


class StampedFeedback:
    """Publishes the feedback of an ``actionlib.ActionServer`` (started, before any client
    connects) with ``header.stamp`` = the simulation time of the joint state it was computed
    from, not the time it is sent: the same states give the same feedback stamps whatever the
    machine's load. actionlib stamps ``rospy.Time.now()``, which runs ahead of the states when
    the server lags a fast simulation.

    Args:
        server: the action server; its feedback publisher is given a queue of
            :data:`FEEDBACK_QUEUE` (rospy keeps one publisher per topic in a process, and the
            last queue size given applies to the connections made after).
        period_s: s of sim time between feedback messages of a goal (:meth:`due`).
    """

    def __init__(self, server: Any, period_s: float) -> None:
        self.server = server
        self.period_s = period_s
        self._last: dict[str, float] = {}
        server.feedback_pub = rospy.Publisher(
            server.feedback_pub.resolved_name, server.ActionFeedback, queue_size=FEEDBACK_QUEUE
        )

    def due(self, handle: Any, stamp_s: float) -> bool:
        """Whether feedback of the goal of ``handle`` is due for the joint state at ``stamp_s``
        (s, sim): the first one, then one ``period_s`` or more after the last one sent."""
        goal = handle.get_goal_id().id
        if stamp_s < self._last.get(goal, -math.inf) + self.period_s:
            return False
        self._last = {goal: stamp_s}  # one goal at a time: only its time is kept
        return True

    def publish(self, handle: Any, feedback: Any, stamp_s: float) -> None:
        """Publish ``feedback`` of the goal of ``handle`` (a ServerGoalHandle), stamped
        ``stamp_s`` (s, sim)."""
        server = self.server
        with server.lock:
            msg = server.ActionFeedback()
            msg.header.stamp = rospy.Time.from_sec(stamp_s)
            msg.status = handle.status_tracker.status
            msg.feedback = feedback
            if not rospy.is_shutdown():
                server.feedback_pub.publish(msg)
