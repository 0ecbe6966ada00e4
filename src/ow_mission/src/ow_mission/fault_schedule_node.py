"""A mission's fault schedule applied through the ``/faults`` server (rospy wiring only; the
timing is :class:`ow_mission.fault_schedule.ScheduleTimer`'s)."""

from __future__ import annotations

import threading
from collections.abc import Iterable
from typing import Any

import rospy
from dynamic_reconfigure import DynamicReconfigureCallbackException
from dynamic_reconfigure.client import Client
from rosgraph_msgs.msg import Clock

from ow_mission.fault_schedule import AppliedFault, ScheduledFault, ScheduleTimer

#: s of wall time to wait for the ``/faults`` server when the runner starts.
FAULTS_SERVER_TIMEOUT_S = 10.0


class FaultScheduleRunner:
    """Sends each change of a mission's fault schedule to ``/faults`` when the simulation time
    reaches it, in the mission's process.

    Subscribes: ``/clock`` (rosgraph_msgs/Clock): an entry is applied at the first clock at or
        after its due time (the simulation keeps running meanwhile: ``applied_s`` says when the
        server had accepted it).
    Services used: ``/faults/set_parameters`` (dynamic_reconfigure/Reconfigure), through
        dynamic_reconfigure's client. A change the server refuses is recorded with its message;
        the mission goes on.
    Told by the mission: :meth:`step_started` at each step's start (s of sim time, the
        simulation paused): an entry due then (``after_s: 0``) is applied before the step runs.

    Args:
        schedule: the mission file's entries; none: no client, no subscription.
    """

    def __init__(self, schedule: Iterable[ScheduledFault]) -> None:
        self.timer = ScheduleTimer(schedule)
        self.applied: list[AppliedFault] = []
        self._lock = threading.Lock()
        self._client: Any = None
        if self.timer.schedule:
            self._client = Client("/faults", timeout=FAULTS_SERVER_TIMEOUT_S)
            rospy.Subscriber("/clock", Clock, self._on_clock, queue_size=1)

    def _on_clock(self, msg: Any) -> None:
        self.poll(msg.clock.to_sec())

    def step_started(self, step: str, start_s: float) -> None:
        """Note a step's start (s, sim) and apply what is due at it."""
        with self._lock:
            self.timer.step_started(step, start_s)
        self.poll(start_s)

    def poll(self, now_s: float) -> None:
        """Apply every entry due at or before ``now_s`` (s, sim), earliest first."""
        with self._lock:
            for index, entry, due_s in self.timer.due(now_s):
                self.applied.append(self._apply(index, entry, due_s, now_s))

    def _apply(self, index: int, entry: ScheduledFault, due_s: float, now_s: float) -> AppliedFault:
        record = AppliedFault(index, entry.describe(), dict(entry.changes), due_s=due_s)
        try:
            self._client.update_configuration(dict(entry.changes))
        except (DynamicReconfigureCallbackException, rospy.ROSException) as exc:
            # The server's message is on the service exception the client raised from.
            record.error = str(exc.__context__ or exc)
            rospy.logerr(f"mission: fault {record.description} refused: {record.error}")
            return record
        record.applied_s = max(rospy.get_time(), now_s)
        rospy.loginfo(
            f"mission: fault {record.description} applied at t = {record.applied_s:.3f} s"
        )
        return record

    def results(self) -> list[AppliedFault]:
        """Every entry: those applied or refused, in the order they came due, then those that
        never came due."""
        with self._lock:
            return [*self.applied, *self.timer.never_due()]
