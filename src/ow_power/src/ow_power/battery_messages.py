"""Battery messages from :class:`~ow_power.battery.BatteryState` (genpy messages, no rospy).

OceanWATERS' telemetry types (``owl_msgs``: Header + value) for the state of charge, the
remaining useful life and the temperature, and ``sensor_msgs/BatteryState`` for everything else
(pack voltage, current, charge, per-cell voltages).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import genpy
from sensor_msgs.msg import BatteryState as BatteryStateMsg
from std_msgs.msg import Header

from owl_msgs.msg import BatteryRemainingUsefulLife, BatteryStateOfCharge, BatteryTemperature

if TYPE_CHECKING:  # ow_power.battery imports ProgPy (~1 s)
    from ow_power.battery import BatteryState

#: Frame of the battery messages: the pack is in the lander body.
FRAME_ID = "base_link"

#: Largest remaining useful life an int32 carries (s, about 68 years): sent when no load is
#: drawn (the life is then unbounded).
MAX_RUL_S = 2**31 - 1

#: C per Ah.
COULOMBS_PER_AH = 3600.0


def rul_int32(rul_s: float) -> int:
    """Whole seconds of ``rul_s`` (rounded down) within [0, :data:`MAX_RUL_S`]."""
    if math.isnan(rul_s):
        return 0
    return int(min(max(math.floor(rul_s), 0), MAX_RUL_S)) if math.isfinite(rul_s) else MAX_RUL_S


def battery_messages(
    state: BatteryState, stamp: genpy.Time, cells_in_series: int, capacity_c: float
) -> tuple[BatteryStateOfCharge, BatteryRemainingUsefulLife, BatteryTemperature, BatteryStateMsg]:
    """The four messages of one update, all with the same header.

    Args:
        state: the battery after the update.
        stamp: simulation time of the update.
        cells_in_series: cells of the pack (disconnected ones report a NaN cell voltage).
        capacity_c: C, charge between SOC 1 and SOC 0.

    Returns:
        State of charge (0-1), remaining useful life (int32 s), temperature (degrees C) and
        ``sensor_msgs/BatteryState``.
    """
    header = Header(stamp=stamp, frame_id=FRAME_ID)
    cell_v = state.voltage_v / state.cells_connected
    disconnected = cells_in_series - state.cells_connected
    status = (
        BatteryStateMsg.POWER_SUPPLY_STATUS_DISCHARGING
        if state.load_w > 0.0 and not state.depleted
        else BatteryStateMsg.POWER_SUPPLY_STATUS_NOT_CHARGING
    )
    full = BatteryStateMsg(
        header=header,
        voltage=state.voltage_v,
        temperature=state.temperature_c,
        current=-state.current_a,
        charge=state.soc * capacity_c / COULOMBS_PER_AH,
        capacity=capacity_c / COULOMBS_PER_AH,
        design_capacity=capacity_c / COULOMBS_PER_AH,
        percentage=state.soc,
        power_supply_status=status,
        power_supply_health=BatteryStateMsg.POWER_SUPPLY_HEALTH_DEAD
        if state.depleted
        else BatteryStateMsg.POWER_SUPPLY_HEALTH_GOOD,
        power_supply_technology=BatteryStateMsg.POWER_SUPPLY_TECHNOLOGY_LION,
        present=True,
        cell_voltage=[cell_v] * state.cells_connected + [math.nan] * disconnected,
        cell_temperature=[state.temperature_c] * state.cells_connected + [math.nan] * disconnected,
        location="lander",
        serial_number="",
    )
    return (
        BatteryStateOfCharge(header=header, value=state.soc),
        BatteryRemainingUsefulLife(header=header, value=rul_int32(state.rul_s)),
        BatteryTemperature(header=header, value=state.temperature_c),
        full,
    )
