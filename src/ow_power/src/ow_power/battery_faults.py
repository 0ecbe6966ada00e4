"""The power faults of ``/faults`` acting on the battery, free of ROS.

:class:`PowerFaults` follows the injected :class:`~ow_faults.injection.FaultSet` and changes
the :class:`~ow_power.battery.Battery` through its fault hooks:

* ``high_power_draw`` (W) while ``activate_high_power_draw``, plus the custom profile's row of
  the second since ``activate_custom_fault`` (``custom_fault_profile``), is the extra load of
  every update (:meth:`extra_load_w`);
* ``disconnect_battery_nodes`` disconnects ``battery_nodes_to_disconnect`` cells, for good;
* ``low_state_of_charge`` drains the cells at once to SOC
  :data:`~ow_faults.injection.FORCED_LOW_SOC` (when they hold more), on each activation;
* ``instantaneous_capacity_loss`` loses :data:`~ow_faults.injection.FORCED_CAPACITY_LOSS` of
  the charge at once, on each activation;
* ``thermal_failure`` holds the cells at :data:`~ow_faults.injection.FORCED_TEMPERATURE_C` while
  set; cleared, they cool back to their surroundings.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ow_faults.injection import (
    FORCED_CAPACITY_LOSS,
    FORCED_LOW_SOC,
    FORCED_TEMPERATURE_C,
    FaultSet,
    PowerProfile,
    read_power_profile,
)

if TYPE_CHECKING:  # ow_power.battery imports ProgPy (~1 s), which a battery built later defers
    from ow_power.battery import Battery


class PowerFaults:
    """The injected power faults of one battery.

    Args:
        battery: the battery they act on.
    """

    def __init__(self, battery: Battery) -> None:
        self.battery = battery
        self.faults = FaultSet()
        self._profile: PowerProfile | None = None
        self._profile_start_s = 0.0

    def update(self, faults: FaultSet) -> list[str]:
        """Take the power faults of ``faults`` now (battery time ``battery.state.time_s``).

        Returns:
            What changed, one sentence each (for the log).

        Raises:
            FaultError: the custom profile cannot be read (it was checked when set; the file
                may have changed since).
        """
        old, battery, now = self.faults, self.battery, self.battery.state.time_s
        events = []
        profile_on = faults.activate_custom_fault
        if profile_on and (not old.activate_custom_fault or self._profile is None):
            self._profile = read_power_profile(faults.custom_fault_profile)
            self._profile_start_s = now
            events.append(f"custom power profile {self._profile.path.name} started")
        elif not profile_on and self._profile is not None:
            self._profile = None
            events.append("custom power profile stopped")
        if faults.cells_disconnected > battery.config.cells_in_series - battery.cells_connected:
            battery.disconnect_cells(faults.cells_disconnected)
            events.append(f"{faults.cells_disconnected} cells disconnected")
        if faults.low_state_of_charge and not old.low_state_of_charge:
            battery.force_soc(min(FORCED_LOW_SOC, battery.true_soc))
            events.append(f"state of charge forced to {battery.state.soc:.3f}")
        if faults.instantaneous_capacity_loss and not old.instantaneous_capacity_loss:
            battery.lose_capacity(FORCED_CAPACITY_LOSS)
            events.append(f"lost {FORCED_CAPACITY_LOSS:.1%} of the charge")
        if faults.thermal_failure and not old.thermal_failure:
            battery.force_thermal_failure(FORCED_TEMPERATURE_C)
            events.append(f"cells held at {FORCED_TEMPERATURE_C:g} degC")
        elif old.thermal_failure and not faults.thermal_failure:
            battery.clear_thermal_failure()
            events.append("thermal failure cleared")
        if faults.extra_load_w != old.extra_load_w:
            events.append(f"high power draw {faults.extra_load_w:g} W")
        self.faults = faults
        return events

    def extra_load_w(self) -> float:
        """W, the injected load of the update starting now: the high power draw plus the
        custom profile's row of this second."""
        load = self.faults.extra_load_w
        if self._profile is not None:
            load += self._profile.load_at(self.battery.state.time_s - self._profile_start_s)
        return load
