"""Following the ``/faults`` server from another node (rospy wiring only)."""

from __future__ import annotations

from collections.abc import Callable

import rospy

from ow_faults.change_follower_node import ChangeFollower
from ow_faults.conversions import faults_from_msg
from ow_faults.errors import FaultError
from ow_faults.injection import FaultSet
from ow_msgs.msg import FaultChange

#: ``on_faults(faults, stamp_s)``: the injected faults from sim time ``stamp_s`` (s) on. It
#: returns once they are applied: the follower then says so.
FaultsCallback = Callable[[FaultSet, float], None]


class FaultsListener:
    """Calls ``on_faults`` with the injected faults whenever the ``/faults`` server changes them,
    then says it has applied them (:class:`~ow_faults.change_follower_node.ChangeFollower`).

    Subscribes: ``/faults/changes`` (ow_msgs/FaultChange, latched: a node started after an
        injection learns it at once; none while no ``faults`` node runs).
    Publishes: ``/faults/applied`` (ow_msgs/FaultChangeApplied) once ``on_faults`` has returned.

    Args:
        on_faults: called on rospy's thread with each new :class:`FaultSet` and the sim time
            (s) it holds from: data stamped after it must see the change.
        name: the calling node's name, for the log.
    """

    def __init__(self, on_faults: FaultsCallback, name: str) -> None:
        self._on_faults = on_faults
        self._name = name
        #: the faults now (none until the server's first message).
        self.faults = FaultSet()
        self._follower = ChangeFollower(self._on_change)

    def _on_change(self, msg: FaultChange, stamp_s: float) -> None:
        try:
            faults = faults_from_msg(msg.config)
        except FaultError as error:
            rospy.logerr(f"{self._name}: fault configuration ignored: {error}")
            return
        self.faults = faults
        self._on_faults(faults, stamp_s)
