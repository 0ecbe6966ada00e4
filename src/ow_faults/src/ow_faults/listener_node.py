"""Following the ``/faults`` server from another node (rospy wiring only)."""

from __future__ import annotations

from collections.abc import Callable

import rospy
from dynamic_reconfigure.msg import Config

from ow_faults.conversions import FAULTS_TOPIC, faults_from_msg
from ow_faults.errors import FaultError
from ow_faults.injection import FaultSet


class FaultsListener:
    """Calls ``on_faults`` with the injected faults whenever the ``/faults`` server changes them.

    Subscribes: ``/faults/parameter_updates`` (dynamic_reconfigure/Config, latched: a node
    started after an injection learns it at once; none while no ``faults`` node runs).

    Args:
        on_faults: called on rospy's thread with each new :class:`FaultSet`.
        name: the calling node's name, for the log.
    """

    def __init__(self, on_faults: Callable[[FaultSet], None], name: str) -> None:
        self._on_faults = on_faults
        self._name = name
        #: the faults now (none until the server's first message).
        self.faults = FaultSet()
        self._subscriber = rospy.Subscriber(FAULTS_TOPIC, Config, self._on_config, queue_size=10)

    def _on_config(self, msg: Config) -> None:
        try:
            faults = faults_from_msg(msg)
        except FaultError as error:
            rospy.logerr(f"{self._name}: fault configuration ignored: {error}")
            return
        self.faults = faults
        self._on_faults(faults)
