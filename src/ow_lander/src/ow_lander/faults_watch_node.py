"""Following OceanWATERS' fault telemetry from the arm services and the pan/tilt node (rospy
wiring only; the decisions are :class:`~ow_lander.fault_reaction.FaultReaction`'s)."""

from __future__ import annotations

import threading
from collections.abc import Callable

import rospy

from ow_lander.conversions import EVERY_MESSAGE
from ow_lander.fault_reaction import (
    APPLIED_TOPIC,
    CHANGES_TOPIC,
    FaultReaction,
    group_of,
    watches_force,
)
from ow_msgs.msg import FaultChange, FaultChangeApplied
from owl_msgs.msg import ArmFaultsStatus, PanTiltFaultsStatus, SystemFaultsStatus

#: Called with the sim time (s) of a new fault status, on rospy's thread.
StatusCallback = Callable[[float], None]


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


class FaultWatch:
    """The fault telemetry and the injector's behaviour parameters, for the reaction.

    Subscribes: ``/system_faults_status`` (owl_msgs/SystemFaultsStatus), ``/arm_faults_status``
        (owl_msgs/ArmFaultsStatus), ``/pan_tilt_faults_status`` (owl_msgs/PanTiltFaultsStatus),
        all latched by the detector (``rosrun ow_faults detector``); ``/faults/changes``
        (ow_msgs/FaultChange, latched by ``rosrun ow_faults faults``, through
        :class:`ChangeFollower`):
        ``arm_motion_continues_in_fault``, ``auto_clear_goal_errors`` and the locked joints.
        Without those nodes nothing is ever faulted.

    Args:
        on_status: called (with the status's stamp, s sim) after every new status message.
    """

    def __init__(self, on_status: StatusCallback | None = None) -> None:
        self._lock = threading.Lock()
        self._state = FaultReaction()
        self._on_status = on_status
        self.follower = ChangeFollower(self._on_change)
        for topic, cls, attribute in (
            ("/arm_faults_status", ArmFaultsStatus, "arm"),
            ("/pan_tilt_faults_status", PanTiltFaultsStatus, "pan_tilt"),
            ("/system_faults_status", SystemFaultsStatus, "system"),
        ):
            rospy.Subscriber(
                topic, cls, self._on_bits, callback_args=attribute, queue_size=EVERY_MESSAGE
            )

    def _on_change(self, msg: FaultChange, _stamp_s: float) -> None:
        values = {kv.name: kv.value for kv in msg.config.bools}
        with self._lock:
            self._state.on_parameters(values)

    def _on_bits(self, msg: ArmFaultsStatus, attribute: str) -> None:
        with self._lock:
            setattr(self._state, attribute, int(msg.value))
        if self._on_status is not None:
            self._on_status(msg.header.stamp.to_sec())

    def now(self) -> FaultReaction:
        """A copy of the telemetry and parameters now (ask it why to stop or refuse)."""
        with self._lock:
            state = self._state
            return FaultReaction(
                state.system,
                state.arm,
                state.pan_tilt,
                state.motion_continues,
                state.auto_clear,
                state.locked,
            )

    def refusal(self, name: str, ground_detector: str = "velocity") -> str | None:
        """Why a goal of action ``name`` or a request of service ``name`` is refused now (see
        :meth:`~ow_lander.fault_reaction.FaultReaction.refusal`), or None."""
        return self.now().refusal(group_of(name), watches_force(name, ground_detector))
