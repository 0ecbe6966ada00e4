"""How far each input stream of the guards has arrived, and waiting for one (no ROS).

A decision on the joint state of stamp ``s`` must have every guard reading up to ``s``: the
wrist F/T sensor ("force") or the scoop tip from tf ("tip"). The streams arrive on connections
of their own, and under load one may lag another by seconds. :class:`GuardStreams` keeps the
newest stamp of each and lets a decision wait for one; an arrival wakes the threads waiting on
the shared condition only while a decision waits for a stream (waking the execution's thread
with every wrench, at 50 Hz, cost the arm services a seventh of their CPU).
"""

from __future__ import annotations

import threading
from collections.abc import Callable

from ow_runtime.names import STAMP_SLACK_S

#: The guard input streams.
STREAMS = ("force", "tip")


class GuardStreams:
    """The newest stamp of each guard stream, under the caller's condition (every method is
    called with it held).

    Args:
        condition: the condition the node's callbacks and its decisions share.
    """

    def __init__(self, condition: threading.Condition) -> None:
        self._condition = condition
        #: s (sim), the newest stamp received of each stream (-1 before one)
        self.newest = dict.fromkeys(STREAMS, -1.0)
        self._waiting = 0

    @property
    def waiting(self) -> int:
        """Decisions waiting for a stream now."""
        return self._waiting

    def arrived(self, stream: str, stamp: float) -> None:
        """A reading of ``stream`` stamped ``stamp`` (s, sim) arrived."""
        self.newest[stream] = stamp
        if self._waiting:
            self._condition.notify_all()

    def wait(self, stream: str, stamp: float, timeout_s: float, stop: Callable[[], bool]) -> bool:
        """Wait (``timeout_s`` of wall time at most) until ``stream`` has a reading of
        ``stamp`` (s, sim; within :data:`STAMP_SLACK_S`) or later, or ``stop()`` is true;
        False on the timeout."""
        self._waiting += 1
        try:
            return self._condition.wait_for(
                lambda: self.newest[stream] >= stamp - STAMP_SLACK_S or stop(), timeout_s
            )
        finally:
            self._waiting -= 1
