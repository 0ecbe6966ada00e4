"""Electrical loads besides the arm's motors: how a node tells the power model what it draws, and
the sum the model adds to P0. No ROS.

The protocol is OceanWATERS' (its ow_lander ``PowerInterface`` and ow_power_system): a node that
draws power publishes the sum of its own loads, W, on :data:`LOADS_TOPIC` (std_msgs/Float64,
latched) whenever that sum changes, 0 when it draws nothing. The power node keeps the latest value
of every publisher (:class:`LoadSum`) and adds their sum to P0 in every ``/power`` sample:
``auxiliary_power``, ``total_power``, ``electrical_power`` and their energies, hence the battery,
carry it. A publisher that goes away leaves its last value in the sum.

Loads known to the stack: :data:`COMMS_POWER_W`, drawn by the antenna mast node for OceanWATERS'
``ActivateComms`` action (``ow_lander.mast.comms_node``).
"""

from __future__ import annotations

import math

from ow_power.errors import PowerError

#: OceanWATERS' name of the loads topic (std_msgs/Float64, W, latched, one value per publisher).
LOADS_TOPIC = "/electrical_power"
#: W, the communication uplink/downlink load (OceanWATERS' ``power_active_comms``).
COMMS_POWER_W = 9.6


class LoadSum:
    """The latest load of every publisher of :data:`LOADS_TOPIC`, and their sum (W).

    Not thread-safe: feed it and read it under one lock, or from one thread.
    """

    def __init__(self) -> None:
        self._loads: dict[str, float] = {}

    def update(self, publisher: str, power_w: float) -> None:
        """Set the load of ``publisher`` (its node name) to ``power_w`` W.

        Raises:
            PowerError: ``power_w`` is negative or not finite (the publisher's load is left
                as it was).
        """
        if not (math.isfinite(power_w) and power_w >= 0.0):
            msg = f"load of {publisher} = {power_w} W is not a finite number >= 0"
            raise PowerError(msg)
        self._loads[publisher] = float(power_w)

    @property
    def total_w(self) -> float:
        """W, the sum of the latest loads of every publisher (0 before any)."""
        return math.fsum(self._loads.values())
