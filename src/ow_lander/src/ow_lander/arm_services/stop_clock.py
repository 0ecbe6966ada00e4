"""The simulation's clock stopped for a stop request (rospy wiring only; a node module of the
arm_services node)."""

from __future__ import annotations

import threading

from ow_lander.arm_services.observer import ArmObserver
from ow_runtime.clock_client import SimClock


class StopPause:
    """Pauses the simulation for a stop (a cancelled goal, ``ArmStop``), so that the request is
    stamped, and the arm brakes, where the simulation stands, at any load.

    A pause waits until the node has what the simulation published up to where it stands (its
    clock reads that time, its newest joint state is the last one published): whatever the node
    stamps then (actionlib's status as it takes the request) carries that time, and the braking
    starts from that joint state. An action server pauses with :meth:`pause_ahead` before it
    takes a request; the stop then :meth:`take` s that pause (or pauses itself) and resumes the
    clock when its braking is delivered; a request that started no stop :meth:`release` s it.

    Args:
        sim_clock: ``/sim/pause``, ``/sim/resume`` and where the paused simulation stands.
        observer: the joint states and the node's clock.
        quiet_s: s (wall), with a simulation that cannot say where it stands: how long the
            joint states must fall quiet before the newest is taken as its.
    """

    def __init__(self, sim_clock: SimClock, observer: ArmObserver, quiet_s: float) -> None:
        self.sim_clock = sim_clock
        self.observer = observer
        self.quiet_s = quiet_s
        self._lock = threading.Lock()
        #: the answer of a pause taken ahead of a request and not yet taken by a stop
        self._ahead: list[bool | None] = []

    def pause_ahead(self) -> None:
        """Pause before a stop request is taken (once: a pause ahead already held stays)."""
        with self._lock:
            if not self._ahead:
                self._ahead.append(self._pause())

    def take(self) -> bool | None:
        """The pause for a stop: the one taken ahead, else a new one. True: this node stopped
        the clock (resume it once the braking is delivered); False: it was stopped already
        (leave it); None: the simulation offers no pause."""
        with self._lock:
            return self._ahead.pop() if self._ahead else self._pause()

    def release(self) -> None:
        """Resume the clock a pause ahead stopped when no stop took it."""
        with self._lock:
            paused_here = self._ahead.pop() if self._ahead else None
        if paused_here:
            self.sim_clock.resume()

    def _pause(self) -> bool | None:
        paused_here = self.sim_clock.pause()
        if paused_here is not None:
            standing = self.sim_clock.standing()
            if standing is None:
                self.observer.wait_quiet(self.quiet_s)
            else:
                self.observer.wait_standing(*standing)
        return paused_here
