"""One periodic status timer for all the actionlib servers of a node.

Each ``actionlib.ActionServer`` publishes its status from a ``rospy.Timer`` of its own: a thread
that sleeps in simulation time, and rospy wakes every such thread at every ``/clock`` message
to look at the time. The arm services hold 14 servers, so every ``/clock`` woke 14 threads to
find, nearly always, that none was due (about 46 000 wakeups over a default mission).
:func:`share_status_timer` stops the servers' own timers and publishes all their statuses from
one timer at the same rate: the same messages at the same period, one thread woken.
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

    def publish(event: rospy.timer.TimerEvent) -> None:
        for server in servers:
            server.publish_status_async(event)

    return rospy.Timer(rospy.Duration(1.0 / frequency), publish)
