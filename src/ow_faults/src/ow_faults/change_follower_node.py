"""Following the ``/faults`` server's changes from any node, and saying when each is applied
(rospy wiring only; the protocol's names are :mod:`ow_faults.protocol`)."""

from __future__ import annotations

import threading
from collections.abc import Callable

import rospy

from ow_faults.protocol import APPLIED_TOPIC, CHANGES_TOPIC
from ow_msgs.msg import FaultChange, FaultChangeApplied

#: Called on rospy's thread with a change of the /faults server and the sim time (s) it holds from.
ChangeCallback = Callable[[FaultChange, float], None]


class _ProcessFollowers:
    """The process's one subscription to ``/faults/changes`` and one ``/faults/applied``: every
    follower's callback runs, in the order they were added, before the process says it has
    applied a change. (Two followers each saying so for one process, as components of one node,
    would let a mission go on once the first had.)"""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._callbacks: list[ChangeCallback] = []
        self._latest: FaultChange | None = None
        self._applied = rospy.Publisher(APPLIED_TOPIC, FaultChangeApplied, queue_size=100)
        rospy.Subscriber(CHANGES_TOPIC, FaultChange, self._on_change, queue_size=None)

    def add(self, callback: ChangeCallback) -> None:
        """Follow with ``callback`` too; it is called at once with a change already received."""
        with self._lock:
            self._callbacks.append(callback)
            latest = self._latest
        if latest is not None:
            callback(latest, latest.header.stamp.to_sec())

    def _on_change(self, msg: FaultChange) -> None:
        with self._lock:
            self._latest = msg
            callbacks = list(self._callbacks)
        for callback in callbacks:
            callback(msg, msg.header.stamp.to_sec())
        applied = FaultChangeApplied(node=rospy.get_name(), version=msg.version)
        applied.header.stamp = msg.header.stamp
        self._applied.publish(applied)


_FOLLOWERS: _ProcessFollowers | None = None
_FOLLOWERS_LOCK = threading.Lock()


class ChangeFollower:
    """Follows the ``/faults`` server's changes, and says when each is applied.

    Subscribes: ``/faults/changes`` (ow_msgs/FaultChange, latched).
    Publishes: ``/faults/applied`` (ow_msgs/FaultChangeApplied: the change's stamp and version,
        this node's name) once ``on_change`` has returned, and those of every other follower of
        the process (the components of one node share one acknowledgement). Advertising it
        makes the node a follower that a mission waits for before it lets the simulation pass
        a scheduled fault (docs/determinism.md).

    Args:
        on_change: called on rospy's thread with each change and the sim time (s) it holds
            from (data stamped after it must see it).
    """

    def __init__(self, on_change: ChangeCallback) -> None:
        global _FOLLOWERS  # one per process, made by its first follower
        with _FOLLOWERS_LOCK:
            if _FOLLOWERS is None:
                _FOLLOWERS = _ProcessFollowers()
            followers = _FOLLOWERS
        followers.add(on_change)
