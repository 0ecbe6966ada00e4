"""Taking a node's inputs in the order of their stamps across streams that arrive apart (no
ROS): a stream the node hears continuously (the simulation's lock flags, with every joint state)
paces the others.

The fault detector publishes its whole status, stamped with the input that changed it. An input
from the arm services (a goal's end) can arrive before the simulation's flags of earlier stamps
(each topic on its own connection; the simulation writes to the detector's node in batches):
taken first, its status, stamped later, lacked a lock flagged earlier, and a run's bag showed the
lock cleared at the goal's end.
"""

from __future__ import annotations

import math
import threading

#: s: stamps this close count as equal.
SLACK_S = 1e-6


class PacingStream:
    """The newest stamp of the pacing stream, and waits for it.

    A stamp ``t`` of another input is due once the pacing stream has reached ``t`` less one of
    its periods: where the simulation stands at ``t`` (held, paused) its newest joint state is
    one period before.
    """

    def __init__(self) -> None:
        self._arrived = threading.Condition()
        #: s, the newest stamp taken, and the stream's period (the last gap between stamps).
        self.newest = -math.inf
        self.period = 0.0

    def taken(self, stamp_s: float) -> None:
        """The pacing stream's message of ``stamp_s`` (s) has been taken (call after)."""
        with self._arrived:
            if stamp_s > self.newest:
                if math.isfinite(self.newest):
                    self.period = stamp_s - self.newest
                self.newest = stamp_s
            self._arrived.notify_all()

    def wait_for(self, stamp_s: float, timeout_s: float) -> bool:
        """Wait (``timeout_s`` of wall time at most) until the pacing stream has reached
        ``stamp_s`` (s) less one period; at once when it has never arrived (nothing paces).
        False when the wait ran out."""
        with self._arrived:
            return self._arrived.wait_for(
                lambda: (
                    not math.isfinite(self.newest) or self.newest >= stamp_s - self.period - SLACK_S
                ),
                timeout_s,
            )
