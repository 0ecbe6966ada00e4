"""``rospy.init_node`` for every node of the stack, with a node that stops in ~0.1 s, not ~0.6 s.

rospy's registration thread (``RegManager.run``) waits on a condition for up to 0.5 s at a time.
Its pre-shutdown cleanup wakes it before rospy raises its shutdown flag, so the thread goes back
to waiting, and ``rospy.signal_shutdown`` then joins it: every node took about 0.6 s to stop,
however little it did (a mission stops its stack in two waves; the tests stop one per module).
:func:`init_node` wakes the thread again once the flag is up, so it sees the flag and ends.
"""

from __future__ import annotations

import sys
from typing import Any

import rosgraph.names
import rospy
import rospy.core
import rospy.names
from rospy.impl.registration import RegManager, get_registration_listeners


def init_node(name: str, **kwargs: Any) -> None:
    """``rospy.init_node(name, **kwargs)`` with this process's own command line (``argv``,
    default ``sys.argv``), then :func:`stop_promptly`.

    rospy reads the command line's remappings (``__name:=``, ``a:=b``) and the namespace
    (``__ns:=``, ``ROS_NAMESPACE``) when it is imported, and ``init_node`` reads them again only
    when given ``argv``. A node forked from a process that imported rospy before it
    (:mod:`ow_mission.forkserver`) would otherwise have that process's.
    """
    argv = kwargs.setdefault("argv", sys.argv)
    namespace = rosgraph.names.get_ros_namespace(argv=argv)
    rospy.names._set_caller_id(rosgraph.names.ns_join(namespace, "unnamed"))
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
