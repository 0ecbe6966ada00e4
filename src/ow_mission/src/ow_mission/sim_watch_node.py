"""Where the mission's simulation stands, from what it publishes (rospy wiring only): the newest
``/clock`` and, without the lockstep, the newest ``/joint_states`` stamp."""

from __future__ import annotations

import threading
import time
from typing import Any

import rospy
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState

#: What it subscribes to, with the message classes (a recorder in the same node subscribes to
#: them typed: :mod:`ow_power.hosted_record_node`).
SUBSCRIBES: dict[str, Any] = {"/clock": Clock, "/joint_states": JointState}


class SimWatch:
    """The simulation's newest time and joint state, as received.

    Subscribes: :data:`SUBSCRIBES` (``/joint_states`` with ``joints`` only).

    Args:
        joints: follow ``/joint_states`` (a mission without the lockstep, where the steps'
            windows are the stamps of its last joint states).

    Attributes:
        clock: s (sim), the newest ``/clock``.
    """

    def __init__(self, joints: bool) -> None:
        self.clock = 0.0
        self._joint_stamp = 0.0  # s (sim), the newest received
        self._lock = threading.Lock()
        rospy.Subscriber("/clock", Clock, self._on_clock, queue_size=10)
        if joints:
            rospy.Subscriber("/joint_states", JointState, self._on_joints, queue_size=10)

    def _on_clock(self, msg: Any) -> None:
        self.clock = msg.clock.to_sec()

    def _on_joints(self, msg: Any) -> None:
        with self._lock:
            self._joint_stamp = msg.header.stamp.to_sec()

    def last_joint_stamp(self, quiet_s: float = 0.05, limit_s: float = 2.0) -> float:
        """s, the last /joint_states stamp once none came for ``quiet_s`` (wall): a paused
        simulation's (at most ``limit_s`` of wall time waited)."""
        deadline = time.monotonic() + limit_s
        while True:
            with self._lock:
                stamp = self._joint_stamp
            time.sleep(quiet_s)
            with self._lock:
                if self._joint_stamp == stamp or time.monotonic() > deadline:
                    return self._joint_stamp
