"""``rospy.init_node`` for every node of the stack, with a node that stops in ~0.1 s, not ~0.6 s.

rospy's registration thread (``RegManager.run``) waits on a condition for up to 0.5 s at a time.
Its pre-shutdown cleanup wakes it before rospy raises its shutdown flag, so the thread goes back
to waiting, and ``rospy.signal_shutdown`` then joins it: every node took about 0.6 s to stop,
however little it did (a mission stops its stack in two waves; the tests stop one per module).
:func:`init_node` wakes the thread again once the flag is up, so it sees the flag and ends.
"""

from __future__ import annotations

from typing import Any

import rospy
import rospy.core
from rospy.impl.registration import RegManager, get_registration_listeners


def init_node(name: str, **kwargs: Any) -> None:
    """``rospy.init_node(name, **kwargs)``, then :func:`stop_promptly`."""
    rospy.init_node(name, **kwargs)
    stop_promptly()


def stop_promptly() -> None:
    """After ``rospy.init_node``: wake rospy's registration thread when the node shuts down,
    once rospy's shutdown flag is up (a shutdown hook runs after it is raised and before the
    threads are joined)."""
    # The cleanup empties the listeners before the shutdown hooks run: keep the managers now.
    managers = [m for m in get_registration_listeners().listeners if isinstance(m, RegManager)]

    def wake(reason: str) -> None:
        for manager in managers:
            with manager.cond:
                # An empty update: a thread not yet waiting does not wait (it checks the updates
                # under this lock), one waiting is woken; either way it then sees the flag.
                manager.updates.append((None, None))
                manager.cond.notify_all()

    rospy.core.add_shutdown_hook(wake)
