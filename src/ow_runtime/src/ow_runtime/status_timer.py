"""One periodic status timer for all the actionlib servers of a node.

Each ``actionlib.ActionServer`` publishes its status from a ``rospy.Timer`` of its own: a thread
that sleeps in simulation time, and rospy wakes every such thread at every ``/clock`` message
to look at the time. The arm services hold 14 servers, so every ``/clock`` woke 14 threads to
find, nearly always, that none was due (about 46 000 wakeups over a default mission).
:func:`share_status_timer` stops the servers' own timers and publishes all their statuses from
one timer at the same rate: the same messages at the same period, one thread woken.

The shared timer is a :class:`StatusHeartbeat`, not a ``rospy.Timer``. rospy's timer catches up
when it falls behind (a ``/clock`` jump past its period, its thread late under load): it fires
again at once for each period it missed, up to two; and a clock set back ends its thread with
``ROSTimeMovedBackwardsException``. The heartbeat fires once at each boundary of its period
(simulation time, the phase of its start) that it sees: a boundary it sees late still gives
its status, the ones it slept through give none (a status is a heartbeat, not a count of periods
owed), and the next is the first boundary after now. A clock set back (a simulation restarted
under the running nodes) gives a status at once and restarts the boundaries from there.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Sequence
from typing import Any

import rospy

from ow_runtime.errors import ConfigError

#: s: a time within this of a boundary is at it (a sleep's target is rounded to the nanosecond).
_EPSILON_S = 1e-6


class StatusHeartbeat(threading.Thread):
    """Publishes the status of ``servers`` at every boundary of ``period`` s of simulation time
    (a daemon thread, started at once; see the module's text).

    Attributes:
        period: s of simulation time.
    """

    def __init__(self, servers: Sequence[Any], period: float) -> None:
        super().__init__(name="status_heartbeat", daemon=True)
        self.servers = list(servers)
        self.period = period
        self._shutdown = False
        self.start()

    def shutdown(self) -> None:
        """Publish no more; the thread ends when it next wakes."""
        self._shutdown = True

    def run(self) -> None:
        last: rospy.Time | None = None
        boundary = rospy.get_rostime().to_sec() + self.period
        while not rospy.core.is_shutdown() and not self._shutdown:
            now = rospy.get_rostime()
            if last is not None and now < last:  # set back while awake: as below
                boundary = now.to_sec()
            if now.to_sec() < boundary - _EPSILON_S:
                try:
                    rospy.sleep(boundary - now.to_sec())
                    continue
                except rospy.exceptions.ROSTimeMovedBackwardsException:
                    now = rospy.get_rostime()  # set back: a status now, boundaries from here
                    boundary = now.to_sec()
                except rospy.exceptions.ROSInterruptException:
                    return  # shutting down
            if self._shutdown:
                return
            event = rospy.timer.TimerEvent(last, last, rospy.Time.from_sec(boundary), now, None)
            try:
                for server in self.servers:
                    server.publish_status_async(event)
            except rospy.ROSException:
                if rospy.core.is_shutdown_requested():
                    return  # the publishers closed before rospy's shutdown flag went up
                raise
            last = now
            missed = math.floor((now.to_sec() - boundary) / self.period)
            boundary += (max(missed, 0) + 1) * self.period  # the first boundary after now


def share_status_timer(servers: Sequence[Any]) -> StatusHeartbeat | None:
    """Publish the status of ``servers`` (started ``actionlib.ActionServer``\\ s that read the
    same ``actionlib_status_frequency``) from one timer instead of one each; None when they
    publish no periodic status (a frequency of 0).

    Raises:
        ConfigError: the servers were given different status frequencies.
    """
    frequencies = {float(server.status_frequency) for server in servers}
    if len(frequencies) != 1:
        msg = f"the action servers' status frequencies differ: {sorted(frequencies)} Hz"
        raise ConfigError(msg)
    (frequency,) = frequencies
    if frequency <= 0.0:
        return None
    for server in servers:
        server.status_timer.shutdown()  # its thread ends at its next wakeup
    return StatusHeartbeat(servers, 1.0 / frequency)
