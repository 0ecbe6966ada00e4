"""When the simulation node's outputs are due, and how the simulation keeps pace with the wall
clock. No ROS here: times are plain seconds, the wall clock is injected."""

from __future__ import annotations

import time
from collections.abc import Callable

#: s of sim time: ticks closer than this to a step count as reached (float rounding of steps).
_TICK_SLACK = 1e-9
#: s of wall time behind the pace after which the simulation stops trying to catch up.
_GIVE_UP_BEHIND_S = 0.5


class Periodic:
    """Fires at a fixed rate of sim time, on the first step at or after each tick.

    Args:
        rate_hz: Hz of sim time (> 0).
    """

    def __init__(self, rate_hz: float) -> None:
        self.period = 1.0 / rate_hz
        self.next_tick = 0.0

    def due(self, now: float) -> bool:
        """Whether a tick was reached at sim time ``now`` (s); if so, the next one is set (ticks
        missed in between are skipped)."""
        if now + _TICK_SLACK < self.next_tick:
            return False
        ticks = int((now + _TICK_SLACK) / self.period) + 1
        self.next_tick = ticks * self.period
        return True


class Pacer:
    """Keeps sim time at ``real_time_factor`` times wall time.

    Args:
        real_time_factor: sim s per wall s; 0 or less: as fast as possible.
        clock: wall clock in s (monotonic).
    """

    def __init__(
        self, real_time_factor: float, clock: Callable[[], float] = time.monotonic
    ) -> None:
        self.real_time_factor = real_time_factor
        self._clock = clock
        self._wall = clock()
        self._sim = 0.0

    def restart(self, sim_time: float) -> None:
        """Pace from now on from sim time ``sim_time`` (s), e.g. after a pause."""
        self._wall, self._sim = self._clock(), sim_time

    def wait(self, sim_time: float) -> float:
        """s of wall time to wait before the step after sim time ``sim_time`` (0: go on).

        More than half a second behind, the pace restarts from now: a simulation too slow to
        keep up does not try to catch up later.
        """
        rtf = self.real_time_factor
        if rtf <= 0:
            return 0.0
        ahead = (sim_time - self._sim) / rtf - (self._clock() - self._wall)
        if ahead > 0:
            return ahead
        if ahead < -_GIVE_UP_BEHIND_S:
            self.restart(sim_time)
        return 0.0


class Throttle:
    """Something republished when its version changes, at most every ``period`` s of ``clock``.

    Args:
        period: s of ``clock``.
        clock: s; the simulation's own time for what it records (the carved terrain): then
            what is published, and when, is a function of the run, not of the machine's load.
    """

    def __init__(self, period: float, clock: Callable[[], float]) -> None:
        self.period = period
        self._clock = clock
        self._version: int | None = None
        self._wall = -float("inf")

    def done(self, version: int) -> None:
        """``version`` was published now."""
        self._version, self._wall = version, self._clock()

    def changed(self, version: int) -> bool:
        """Whether ``version`` is not the one published last (whatever the period)."""
        return version != self._version

    def due(self, version: int) -> bool:
        """Whether ``version`` should be published now."""
        if version == self._version:
            return False
        return self._clock() - self._wall >= self.period
