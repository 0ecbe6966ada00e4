"""Following OceanWATERS' fault telemetry from the arm services and the pan/tilt node (rospy
wiring only; the decisions are :class:`~ow_lander.execution.fault_reaction.FaultReaction`'s)."""

from __future__ import annotations

import threading
from collections.abc import Callable

import rospy

from ow_faults.change_follower_node import ChangeFollower
from ow_lander.execution.fault_reaction import FaultReaction, group_of, watches_force
from ow_msgs.msg import FaultChange
from ow_runtime.names import (
    ARM_FAULTS_STATUS,
    EVERY_MESSAGE,
    PAN_TILT_FAULTS_STATUS,
    SYSTEM_FAULTS_STATUS,
)
from owl_msgs.msg import ArmFaultsStatus, PanTiltFaultsStatus, SystemFaultsStatus

#: Called with the sim time (s) of a new fault status, on rospy's thread.
StatusCallback = Callable[[float], None]


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
            (ARM_FAULTS_STATUS, ArmFaultsStatus, "arm"),
            (PAN_TILT_FAULTS_STATUS, PanTiltFaultsStatus, "pan_tilt"),
            (SYSTEM_FAULTS_STATUS, SystemFaultsStatus, "system"),
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
        :meth:`~ow_lander.execution.fault_reaction.FaultReaction.refusal`), or None."""
        return self.now().refusal(group_of(name), watches_force(name, ground_detector))
