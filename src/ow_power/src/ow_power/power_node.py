"""The power node: eqs. 1-4 of the paper for every joint state (rospy wiring only)."""

from __future__ import annotations

import sys
import threading
from collections.abc import Callable, Sequence

import rospy
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64

from ow_msgs.msg import Power
from ow_msgs.srv import SetLoad, SetLoadRequest, SetLoadResponse
from ow_power.config import PowerConfig
from ow_power.conversions import joint_state_fields, power_message
from ow_power.errors import ConfigError, PowerError
from ow_power.loads import LOADS_TOPIC, SET_LOAD_SERVICE, LoadSum
from ow_power.model import PowerIntegrator
from ow_runtime.batched_publisher import BatchedPublisher
from ow_runtime.names import EVERY_MESSAGE
from ow_runtime.node import init_node, quiet_at_shutdown, spin

# Every joint state counts (a dropped one stretches the next interval of eq. 4), and a simulation
# running many times faster than real time outpaces a node that is briefly descheduled. rospy
# drops messages beyond a subscriber's queue_size (of each socket read) and beyond a publisher's
# (its writer thread lagging): at 100, then at 1000, /power missed 0.33 s and 0.51 s of joint
# states on a loaded 2-core machine. So the subscriber's queue is unlimited, and /power is
# written in the callback (queue_size None), as the simulation and the telemetry write theirs:
# nothing is dropped for a subscriber that lags, which slows this node (and through
# /joint_states the simulation) instead. rospy's queued publisher cost 141 us of CPU per
# message against 37 us written directly (a fifth of the monitors' CPU in a mission).
#: /power's rospy queue: None, written in the callback.
PUBLISH_QUEUE = None


class PowerNode:
    """Publishes the arm's power and cumulative energy for every joint state.

    ROS API:
        Subscribes:
            ``joint_states`` (sensor_msgs/JointState, every message): position rad, velocity
            rad/s, effort = applied torque N m; joints matched by name.
            ``/electrical_power`` (std_msgs/Float64, W, latched by each publisher): the loads a
            node draws besides the motors (:mod:`ow_power.loads`; the mast's ActivateComms),
            added to P0 from the next joint state on.
        Services:
            ``/power/set_load`` (ow_msgs/SetLoad): a load from a given sim time on, in the model
            when the call returns (:mod:`ow_power.loads`); refused naming the value when it is
            negative, not finite, or dated before a sample already published.
        Publishes:
            ``power`` (ow_msgs/Power, written in the callback): one message per usable
            joint state, stamped with its stamp; energies accumulate from the node's start;
            ``auxiliary_power`` is P0 plus the loads.
        Parameters (private, read once; see :class:`~ow_power.config.PowerConfig`):
            ``~auxiliary_power_w`` (float, W, default 43.0): P0.
            ``~motor_efficiency`` (float in (0, 1], default 0.9).
            ``~joints`` (list of str, default []: every joint of the message).
            ``~max_dt_s`` (float, s, default 1.0): longer stamp gaps are not integrated.
    """

    def __init__(
        self, config: PowerConfig, listeners: Sequence[Callable[[Power], None]] = ()
    ) -> None:
        """Advertise ``power`` and subscribe to ``joint_states``.

        Args:
            config: the node's parameters.
            listeners: called with every ``power`` message as it is published, in this
                process: a component of the same node (the battery in ``ow_mission monitors``)
                takes the stream without a connection of its own.
        """
        self._integrator = PowerIntegrator(config)
        self._listeners = tuple(listeners)
        self._loads_lock = threading.Lock()
        self._loads = LoadSum()
        self._publisher = BatchedPublisher("power", Power)
        self._loads_subscriber = rospy.Subscriber(
            LOADS_TOPIC, Float64, self._on_load, queue_size=EVERY_MESSAGE
        )
        self._subscriber = rospy.Subscriber(
            "joint_states", JointState, self._on_joint_states, queue_size=EVERY_MESSAGE
        )
        self._set_load = rospy.Service(SET_LOAD_SERVICE, SetLoad, self._on_set_load)

    def _on_load(self, msg: Float64) -> None:
        publisher = msg._connection_header.get("callerid", "?")
        try:
            with self._loads_lock:
                self._loads.update(publisher, msg.data)
        except PowerError as exc:
            rospy.logwarn(f"power: {LOADS_TOPIC} ignored: {exc}")

    def _on_set_load(self, request: SetLoadRequest) -> SetLoadResponse:
        since = None if request.now else request.since.to_sec()
        try:
            with self._loads_lock:
                self._loads.update(request.source, request.power_w, since)
        except PowerError as exc:
            return SetLoadResponse(success=False, message=str(exc))
        return SetLoadResponse(success=True, message="")

    @quiet_at_shutdown
    def _on_joint_states(self, msg: JointState) -> None:
        stamp_s, names, velocity, effort = joint_state_fields(msg)
        skipped = self._integrator.skipped_intervals
        with self._loads_lock:
            load_w = self._loads.at(stamp_s)
        try:
            sample = self._integrator.update(stamp_s, names, velocity, effort, load_w)
        except PowerError as exc:
            rospy.logwarn_throttle(5.0, f"power: joint state at {stamp_s:.3f} s skipped: {exc}")
            return
        if self._integrator.skipped_intervals > skipped:
            rospy.logwarn_throttle(
                5.0,
                f"power: joint state at {stamp_s:.3f} s follows a gap longer than "
                f"{self._integrator.config.max_dt_s} s or goes back in time; gap not integrated",
            )
        power = power_message(sample, msg.header)
        self._publisher.publish(power)
        for listener in self._listeners:
            listener(power)


def main(argv: list[str] | None = None) -> int:
    """Run the power node until shutdown; 1 on a configuration error."""
    init_node("power", argv=argv)
    try:
        config = PowerConfig.from_dict(rospy.get_param("~", {}))
    except ConfigError as exc:
        rospy.logfatal(f"power: {exc}")
        return 1
    PowerNode(config)
    rospy.loginfo(
        f"power: P0 {config.auxiliary_power_w} W, efficiency {config.motor_efficiency}, "
        f"joints {list(config.joints) or 'all'}"
    )
    spin()
    return 0


if __name__ == "__main__":
    sys.exit(main())
