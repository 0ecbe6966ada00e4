"""One periodic status timer for all the actionlib servers of a node.

Each ``actionlib.ActionServer`` publishes its status from a ``rospy.Timer`` of its own: a thread
that sleeps in simulation time, and rospy wakes every such thread at every ``/clock`` message
to look at the time. The arm services hold 14 servers, so every ``/clock`` woke 14 threads to
find, nearly always, that none was due (about 46 000 wakeups over a default mission).
:func:`share_status_timer` stops the servers' own timers and publishes all their statuses from
one timer at the same rate: the same messages at the same period, one thread woken.

rospy's timer catches up when it falls behind (a ``/clock`` jump past its period, its thread
late under load): it fires again at once for each period it missed, up to two. A status is a
heartbeat, not a count of periods owed, so a firing less than half a period of simulation time
after the last status is dropped: at most one status per period. A clock set back (a simulation
restarted under the running nodes) restarts the timer from the new time.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import rospy

from ow_lander.errors import ConfigError


def share_status_timer(servers: Sequence[Any]) -> rospy.Timer | None:
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

    period = 1.0 / frequency
    last = float("-inf")  # s of sim time of the last status

    def publish(event: rospy.timer.TimerEvent) -> None:
        nonlocal last
        now = event.current_real.to_sec()
        if 0.0 <= now - last < 0.5 * period:  # a catch-up firing (not a clock set back)
            return
        last = now
        for server in servers:
            server.publish_status_async(event)

    # reset: a clock set back (a simulation restarted under running nodes) restarts the timer
    # from the new time; rospy's default ends its thread with ROSTimeMovedBackwardsException.
    return rospy.Timer(rospy.Duration(period), publish, reset=True)
