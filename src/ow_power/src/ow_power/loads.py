"""Electrical loads besides the arm's motors: how a node tells the power model what it draws, and
the sum the model adds to P0. No ROS.

Two ways in, both summed by :class:`LoadSum` per source:

- OceanWATERS' protocol (its ow_lander ``PowerInterface`` and ow_power_system): a node publishes
  the sum of its own loads, W, on :data:`LOADS_TOPIC` (std_msgs/Float64, latched) whenever that
  sum changes, 0 when it draws nothing. The value counts from the next joint state the power node
  processes after it arrives: when that is depends on the machine, as in OceanWATERS.
- The power node's :data:`SET_LOAD_SERVICE` (ow_msgs/SetLoad): a load from a given sim time on,
  set before the call returns. A node that holds the simulation (a lockstep client,
  docs/determinism.md) while it calls it gets the same samples loaded in every run: the mast's
  ``ActivateComms`` (``ow_lander.mast.comms_node``) does.

The power node adds the sum to P0 in every ``/power`` sample: ``auxiliary_power``,
``total_power``, ``electrical_power`` and their energies, hence the battery, carry it. A source
that goes away leaves its last value in the sum.

Loads known to the stack: :data:`COMMS_POWER_W`, drawn by the antenna mast node for OceanWATERS'
``ActivateComms`` action; the cameras' lights and captures (``ow_cameras.commands``).
"""

from __future__ import annotations

import math

from ow_power.errors import PowerError
from ow_runtime.names import STAMP_SLACK_S

#: OceanWATERS' name of the loads topic (std_msgs/Float64, W, latched, one value per publisher).
LOADS_TOPIC = "/electrical_power"
#: The power node's service setting a load from a given sim time on (ow_msgs/SetLoad).
SET_LOAD_SERVICE = "/power/set_load"
#: W, the communication uplink/downlink load (OceanWATERS' ``power_active_comms``).
COMMS_POWER_W = 9.6


class LoadSum:
    """The load of every source (a publisher of :data:`LOADS_TOPIC`, a caller of
    :data:`SET_LOAD_SERVICE`) over sim time, and their sum at a sample's stamp (W).

    Each source has a schedule of ``(since_s, W)`` changes: at stamp ``t`` its load is that of
    its newest change with ``since_s < t`` (0 before any; stamps within
    :data:`~ow_runtime.names.STAMP_SLACK_S` are one instant). Reading the sum at a stamp
    (:meth:`at`) marks the samples up to it as integrated: a change dated before them is refused,
    as it would rewrite energy already published.

    Not thread-safe: feed it and read it under one lock, or from one thread.
    """

    def __init__(self) -> None:
        self._changes: dict[str, list[tuple[float, float]]] = {}
        self._read_s = -math.inf  # s (sim), the newest stamp the sum was read at

    def update(self, source: str, power_w: float, since_s: float | None = None) -> None:
        """Set the load of ``source`` to ``power_w`` W for the samples stamped after
        ``since_s`` (s, sim; None: after the newest sample read, i.e. from the next one on).
        Changes of ``source`` dated after ``since_s`` are dropped (this one replaces them).

        Raises:
            PowerError: ``power_w`` is negative or not finite, or ``since_s`` is not finite or
                before a sample already read (the source's loads are left as they were).
        """
        if not (math.isfinite(power_w) and power_w >= 0.0):
            msg = f"load of {source} = {power_w} W is not a finite number >= 0"
            raise PowerError(msg)
        if since_s is None:
            since = self._read_s
        elif not math.isfinite(since_s):
            raise PowerError(f"load of {source} since {since_s} s: the time is not finite")
        elif since_s < self._read_s - STAMP_SLACK_S:
            msg = (
                f"load of {source} since {since_s:.6f} s: the power model has integrated up to "
                f"{self._read_s:.6f} s already"
            )
            raise PowerError(msg)
        else:
            since = max(float(since_s), self._read_s)
        kept = [change for change in self._changes.get(source, []) if change[0] < since]
        self._changes[source] = [*kept, (since, float(power_w))]

    def at(self, stamp_s: float) -> float:
        """W, the sum of every source's load at the sample of ``stamp_s`` (s, sim). A stamp older
        than the newest read (the simulation reset) starts the schedules afresh from each
        source's load then. Called for every joint state: nothing is copied."""
        if stamp_s < self._read_s:  # the clock went back: keep what each source draws now
            self._changes = {
                source: [(-math.inf, self._load(changes, self._read_s))]
                for source, changes in self._changes.items()
            }
        self._read_s = stamp_s
        before = stamp_s - STAMP_SLACK_S
        loads = []
        for changes in self._changes.values():  # each in time order (update keeps them so)
            while len(changes) > 1 and changes[1][0] < before:
                del changes[0]  # superseded before this stamp: never read again
            if changes[0][0] < before:
                loads.append(changes[0][1])
        return math.fsum(loads)

    @property
    def total_w(self) -> float:
        """W, the sum of every source's newest load (0 before any)."""
        return math.fsum(changes[-1][1] for changes in self._changes.values() if changes)

    @staticmethod
    def _load(changes: list[tuple[float, float]], stamp_s: float) -> float:
        load = 0.0
        for since, power_w in changes:
            if since < stamp_s - STAMP_SLACK_S:
                load = power_w
        return load
