"""The battery node: the ProgPy battery fed by ``/power`` on simulation time (rospy wiring only)."""

from __future__ import annotations

import math
import sys
import threading
import warnings
from collections import deque
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import rospy
from sensor_msgs.msg import BatteryState as BatteryStateMsg

from ow_faults.errors import FaultError
from ow_faults.injection import FaultSet
from ow_faults.listener_node import FaultsListener
from ow_msgs.msg import Power
from ow_power.battery_faults import PowerFaults
from ow_power.battery_feed import LoadFeed
from ow_power.battery_messages import battery_messages
from ow_power.config import BatteryConfig
from ow_power.errors import ConfigError, PowerError
from ow_runtime.latched import latched_publisher
from ow_runtime.names import EVERY_MESSAGE
from ow_runtime.node import init_node, quiet_at_shutdown, spin
from owl_msgs.msg import BatteryRemainingUsefulLife, BatteryStateOfCharge, BatteryTemperature

if TYPE_CHECKING:
    from ow_power.battery import Battery

#: The battery topics' rospy queue: None, written in the callback. A queue drops its oldest
#: messages beyond its size, and the battery publishes in bursts: the periods it catches up on
#: once built (build_later), or after its node was descheduled. With 10, a mission's bag lost
#: /battery_temperature and /battery_remaining_useful_life of nine periods in a row.
PUBLISH_QUEUE = None


class BatteryNode:
    """Publishes the battery's state of charge, remaining useful life and temperature.

    The battery is stepped once per period of simulation time (``1 / ~update_rate_hz``, 1 s),
    on the stamps of ``/power``: with the mean of ``electrical_power`` over the period. It does
    not move while no ``/power`` arrives (a paused simulation).

    ROS API:
        Subscribes:
            ``power`` (ow_msgs/Power, every message): ``electrical_power`` (W: the motors'
            electrical power and P0), held over the interval ending at each stamp.
            ``/faults/changes`` (ow_msgs/FaultChange, latched; acknowledged on
            ``/faults/applied``): the power faults (:mod:`ow_power.battery_faults`): extra
            load, custom profile, disconnected cells, forced low SOC, capacity loss and thermal
            failure, applied before the first ``/power`` stamped after the change's stamp.
        Publishes (latched, queue 10; one message each per period, stamped with the period's
        end, ``frame_id`` ``base_link``):
            ``battery_state_of_charge`` (owl_msgs/BatteryStateOfCharge): ``value`` 0-1, the
            UKF estimate.
            ``battery_remaining_useful_life`` (owl_msgs/BatteryRemainingUsefulLife): ``value``
            int32 s to end of discharge at the period's load; 2147483647 at no load, 0 once
            discharged.
            ``battery_temperature`` (owl_msgs/BatteryTemperature): ``value`` degrees C, the
            UKF estimate.
            ``battery_state`` (sensor_msgs/BatteryState): pack ``voltage`` V, ``current`` A
            (negative: discharging), ``charge``/``capacity`` Ah, ``percentage`` 0-1,
            ``cell_voltage`` V per cell (NaN for disconnected cells).
        Parameters (private, read once; see :class:`~ow_power.config.BatteryConfig`):
            ``~initial_soc`` (float in (0, 1], default 0.95).
            ``~temperature_c`` (float, degrees C, default 20.0): initial and ambient.
            ``~cells_in_series`` (int, default 6).
            ``~mobile_charge_c`` (float, C, default 80387.0): the pack's qMobile.
            ``~internal_resistance_ohm`` (float, ohm, default 0.0232): the pack's Ro.
            ``~eod_voltage_v`` (float, V, default 18.0): the pack's VEOD.
            ``~update_rate_hz`` (float, Hz of simulation time, default 1.0).
            ``~max_gap_s`` (float, s, default 1.0): longer gaps between stamps are not drained.
            ``~voltage_noise_v``, ``~temperature_noise_c`` (float, default 0: exact
            measurements), ``~noise_seed`` (int, default 0).
    """

    def __init__(
        self, config: BatteryConfig, subscribe: bool = True, build_later: bool = False
    ) -> None:
        """Make the battery, advertise its topics and subscribe to ``power``.

        Args:
            config: the node's parameters.
            subscribe: take ``power`` from the topic; False: the caller hands every message to
                :meth:`on_power` (a power node in the same process, ``ow_mission monitors``).
            build_later: build the battery on a thread of its own, after the node's topics are
                up (ProgPy's imports take ~1 s, the longest part of a mission's start): what
                arrives before it is built is kept and taken, in order of arrival, once it
                is. A pack that cannot start is then logged and shuts the node down
                (:attr:`failure`).

        Raises:
            PowerError: the configured pack cannot start (initial voltage at end of discharge),
                when built at once.
        """
        self.config = config
        self._built: tuple[Battery, PowerFaults] | None = None
        #: why the battery could not be built on its own thread (the node shut down), or None.
        self.failure: str | None = None
        self._lock = threading.Lock()  # the battery: /power and /faults arrive on two threads
        self._feed = LoadFeed(config.period_s, config.max_gap_s)
        #: what arrived before the battery was built (build_later), in order; None once built.
        self._early: list[tuple[Callable[..., None], tuple[Any, ...]]] | None = []
        if not build_later:
            self._build()
        with warnings.catch_warnings():  # rospy warns of queue_size None
            warnings.simplefilter("ignore", SyntaxWarning)
            self._publishers = [
                latched_publisher(topic, msg_type, queue_size=PUBLISH_QUEUE)
                for topic, msg_type in (
                    ("battery_state_of_charge", BatteryStateOfCharge),
                    ("battery_remaining_useful_life", BatteryRemainingUsefulLife),
                    ("battery_temperature", BatteryTemperature),
                    ("battery_state", BatteryStateMsg),
                )
            ]
        self._subscriber = (
            # Every /power message: a dropped one would stretch the next interval.
            rospy.Subscriber("power", Power, self.on_power, queue_size=EVERY_MESSAGE)
            if subscribe
            else None
        )
        #: (s sim, faults) received and holding from a time no /power has passed yet
        self._pending: deque[tuple[float, FaultSet]] = deque()
        self._last_power_s = -math.inf  # s (sim), the newest /power taken
        self._faults = FaultsListener(self._on_faults, "battery")
        if build_later:
            threading.Thread(target=self._build_and_catch_up, name="battery", daemon=True).start()

    def _build(self) -> None:
        """Build the battery and its faults; take what arrived before, in order."""
        from ow_power.battery import Battery  # ProgPy, scipy, pandas, matplotlib: ~1 s

        battery = Battery(self.config)
        with self._lock:
            self._built = battery, PowerFaults(battery)
            early, self._early = self._early or [], None
            for take, args in early:
                take(*args)

    def _build_and_catch_up(self) -> None:
        try:
            self._build()
        except Exception as exc:  # a pack that cannot start, or a broken install: say why
            self.failure = f"battery: {exc}"
            rospy.logfatal(self.failure)
            rospy.signal_shutdown(self.failure)

    def built(self) -> tuple[Battery, PowerFaults]:
        """The battery and its injected power faults (RuntimeError until they are built)."""
        if self._built is None:
            msg = "the battery is not built yet"
            raise RuntimeError(msg)
        return self._built

    def _on_faults(self, faults: FaultSet, stamp_s: float) -> None:
        """Faults holding from sim time ``stamp_s``: applied before the first ``/power``
        stamped after it (at once when one has already been taken), whenever each arrives."""
        with self._lock:
            if self._early is not None:
                self._early.append((self._take_faults, (faults, stamp_s)))
            else:
                self._take_faults(faults, stamp_s)

    def _take_faults(self, faults: FaultSet, stamp_s: float) -> None:
        if stamp_s < self._last_power_s:
            self._apply_faults(faults)
        else:
            self._pending.append((stamp_s, faults))

    def _apply_faults(self, faults: FaultSet) -> None:
        try:
            events = self.built()[1].update(faults)
        except (FaultError, PowerError) as error:
            rospy.logerr(f"battery: power fault not applied: {error}")
            return
        for event in events:
            rospy.logwarn(f"battery: {event} at {self.built()[0].state.time_s:.1f} s")

    def on_power(self, msg: Power) -> None:
        """Take one ``power`` message (in stamp order, each once)."""
        with self._lock:
            if self._early is not None:
                self._early.append((self._take_message, (msg,)))
            else:
                self._take_message(msg)

    def _take_message(self, msg: Power) -> None:
        stamp = msg.header.stamp.to_sec()
        while self._pending and self._pending[0][0] < stamp:
            self._apply_faults(self._pending.popleft()[1])
        self._last_power_s = max(self._last_power_s, stamp)
        self._take_power(msg)

    @quiet_at_shutdown
    def _take_power(self, msg: Power) -> None:
        restarts = self._feed.restarts
        try:
            periods = self._feed.add(msg.header.stamp.to_sec(), msg.electrical_power)
        except PowerError as exc:
            rospy.logwarn_throttle(5.0, f"battery: /power message skipped: {exc}")
            return
        if self._feed.restarts > restarts:
            rospy.logwarn_throttle(
                5.0,
                f"battery: /power at {msg.header.stamp.to_sec():.3f} s follows a gap longer than "
                f"{self.config.max_gap_s} s or goes back in time; gap not drained",
            )
        battery, power_faults = self.built()
        for period in periods:
            was_depleted = battery.state.depleted
            battery.set_extra_load(power_faults.extra_load_w())
            state = battery.update(period.mean_load_w, period.duration_s)
            if state.depleted and not was_depleted:
                rospy.logerr(
                    f"battery: end of discharge at {period.end_s:.1f} s "
                    f"({state.voltage_v:.2f} V at {state.load_w:.1f} W)"
                )
            messages = battery_messages(
                state,
                rospy.Time.from_sec(period.end_s),
                self.config.cells_in_series,
                battery.capacity_c,
            )
            for publisher, message in zip(self._publishers, messages, strict=True):
                publisher.publish(message)


def main(argv: list[str] | None = None) -> int:
    """Run the battery node until shutdown; 1 on a configuration error."""
    init_node("battery", argv=argv)
    try:
        config = BatteryConfig.from_dict(rospy.get_param("~", {}))
        node = BatteryNode(config)
    except (ConfigError, PowerError) as exc:
        rospy.logfatal(f"battery: {exc}")
        return 1
    state = node.built()[0].state
    rospy.loginfo(
        f"battery: {config.cells_in_series} cells in series, SOC {state.soc:.3f}, "
        f"{state.voltage_v:.2f} V, {state.temperature_c:.1f} degC, "
        f"update every {config.period_s:g} s of simulation time"
    )
    spin()
    return 0


if __name__ == "__main__":
    sys.exit(main())
