"""Stamped load samples (``/power``, ~100 Hz) to the battery's fixed-period mean loads (1 Hz).

The battery is stepped on the stamps of the samples, not on a timer, so a run gives the same
updates however fast the simulation runs or however late the messages arrive. A sample's power
holds over the interval that ends at its stamp, as in the power node's eq. 4, so the energy the
battery is charged with equals the ``/power`` energy over the same intervals. Periods start at
the first stamp; an interval that spans a period's end is split at it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from ow_power.errors import PowerError


@dataclass(frozen=True)
class LoadPeriod:
    """One completed period.

    Attributes:
        end_s: s, simulation time at the end of the period (the stamp of its update).
        duration_s: s, the period.
        mean_load_w: W, mean power over the period (its energy over its duration).
    """

    end_s: float
    duration_s: float
    mean_load_w: float


class LoadFeed:
    """Splits a stream of ``(stamp, power)`` samples into periods of equal length.

    Args:
        period_s: s of simulation time per period, > 0.
        max_gap_s: s, longest interval between samples that counts; after a longer gap, or a
            stamp earlier than the last, the feed restarts at the new stamp and the partial
            period is dropped (:attr:`restarts` counts these).

    Raises:
        PowerError: a period or gap not above 0 or not finite.
    """

    def __init__(self, period_s: float, max_gap_s: float) -> None:
        for name, value in (("period_s", period_s), ("max_gap_s", max_gap_s)):
            if not (math.isfinite(value) and value > 0.0):
                msg = f"{name} = {value!r} s must be finite and above 0 s"
                raise PowerError(msg)
        self.period_s = float(period_s)
        self.max_gap_s = float(max_gap_s)
        #: Times the feed restarted after a gap or a stamp going back.
        self.restarts = 0
        self._started = False
        self._start_s = 0.0
        self._last_s = 0.0
        self._periods = 0
        self._energy_j = 0.0

    def add(self, stamp_s: float, power_w: float) -> list[LoadPeriod]:
        """Take one sample; return the periods it completes (usually none or one).

        Args:
            stamp_s: s, the sample's simulation time.
            power_w: W, the load over the interval ending at ``stamp_s``.

        Raises:
            PowerError: a stamp or power that is not finite.
        """
        if not (math.isfinite(stamp_s) and math.isfinite(power_w)):
            msg = f"sample ({stamp_s!r} s, {power_w!r} W) is not finite"
            raise PowerError(msg)
        if not self._started:
            self._restart(stamp_s)
            return []
        gap = stamp_s - self._last_s
        if gap < 0.0 or gap > self.max_gap_s:
            self.restarts += 1
            self._restart(stamp_s)
            return []
        done: list[LoadPeriod] = []
        end = self._period_end()
        while stamp_s >= end:
            self._energy_j += power_w * (end - self._last_s)
            done.append(LoadPeriod(end, self.period_s, self._energy_j / self.period_s))
            self._energy_j = 0.0
            self._last_s = end
            self._periods += 1
            end = self._period_end()
        self._energy_j += power_w * (stamp_s - self._last_s)
        self._last_s = stamp_s
        return done

    def _period_end(self) -> float:
        # From the start each time, so that many periods do not accumulate rounding.
        return self._start_s + (self._periods + 1) * self.period_s

    def _restart(self, stamp_s: float) -> None:
        self._started = True
        self._start_s = stamp_s
        self._last_s = stamp_s
        self._periods = 0
        self._energy_j = 0.0
