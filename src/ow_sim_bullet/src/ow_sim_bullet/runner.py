"""The simulation thread: steps the simulation (paced to the wall clock, or paused) and runs the
commands other threads hand it between steps. Only this thread touches the simulation; other
threads enqueue commands or wait for their results. No ROS here."""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable
from typing import Any, TypeVar

from ow_lander.terrain import HeightMap
from ow_sim_bullet.errors import CommandError, SimError
from ow_sim_bullet.outputs import SimOutputs
from ow_sim_bullet.scheduling import Pacer
from ow_sim_bullet.sim_core import BulletSim
from ow_sim_bullet.trajectory import JointTrajectory

T = TypeVar("T")

#: s of wall time a caller waits for the simulation thread before giving up.
CALL_TIMEOUT_S = 60.0
#: s of wall time per step added to that wait for a request of many steps.
STEP_TIMEOUT_S = 0.01
#: s of wall time between checks for a shutdown while paused or waiting.
_POLL_S = 0.1


class SimRunner:
    """Runs one simulation and its outputs on the thread that calls :meth:`run`.

    Args:
        sim: the simulation.
        outputs: its outputs, published after every step.
        real_time_factor: sim s per wall s; 0: as fast as possible.
        start_paused: wait for :meth:`resume` (or :meth:`step_paused`) before stepping.
        is_shutdown: whether the process is shutting down (the loop and waits end).
    """

    def __init__(
        self,
        sim: BulletSim,
        outputs: SimOutputs,
        real_time_factor: float,
        start_paused: bool,
        is_shutdown: Callable[[], bool],
    ) -> None:
        self.sim = sim
        self.outputs = outputs
        self._is_shutdown = is_shutdown
        self._pacer = Pacer(real_time_factor)
        self._wake = threading.Condition(threading.Lock())
        self._queue: deque[Callable[[], None]] = deque()
        self._paused = start_paused
        self._shutdown = False

    # ------------------------------------------------------------------ other threads
    def enqueue(self, command: Callable[[], None]) -> None:
        """Run ``command`` on the simulation thread before its next step."""
        with self._wake:
            self._queue.append(command)
            self._wake.notify()

    def command_setpoint(self, joint: str, position: float, warn: Callable[[str], None]) -> None:
        """Set one joint's set-point (rad) before the next step (:meth:`BulletSim.set_setpoint`).

        Args:
            joint: joint name.
            position: rad; beyond the joint's URDF limits it is clipped onto the limit.
            warn: called on the simulation thread with why the command was ignored (unknown
                joint, non-finite position) or how it was clipped.
        """

        def command() -> None:
            try:
                clipped = self.sim.set_setpoint(joint, position)
            except CommandError as error:
                warn(str(error))
                return
            if clipped is not None:
                warn(clipped.describe())

        self.enqueue(command)

    def command_trajectory(
        self,
        build: Callable[[float, tuple[str, ...]], JointTrajectory],
        warn: Callable[[str], None],
        queued: Callable[[float | None], None] | None = None,
    ) -> None:
        """Follow a trajectory from the next step (:meth:`BulletSim.set_trajectory`).

        Args:
            build: makes the trajectory from the sim time (s) and the simulation's joint names
                (e.g. ``TrajectoryRequest.build``); raises CommandError for a bad one.
            warn: called on the simulation thread with why the trajectory was ignored, or with
                each joint whose points beyond its URDF limits are followed on the limit.
            queued: called on the simulation thread, before any later command, with the
                trajectory's start (s, sim time), or None when it was ignored.
        """

        def command() -> None:
            try:
                trajectory = build(self.sim.time, self.sim.names)
                clipped = self.sim.set_trajectory(trajectory)
            except CommandError as error:
                warn(f"trajectory ignored: {error}")
                if queued is not None:
                    queued(None)
                return
            for clip in clipped:
                warn(f"trajectory {clip.describe()}")
            if queued is not None:
                queued(trajectory.start_time)

        self.enqueue(command)

    def call(self, command: Callable[[], T], timeout_s: float = CALL_TIMEOUT_S) -> T:
        """Run ``command`` on the simulation thread and return its result (or raise its error).

        Raises:
            SimError: the simulation thread did not answer within ``timeout_s`` s of wall time
                (stalled, or shutting down).
        """
        done = threading.Event()
        result: dict[str, Any] = {}

        def run() -> None:
            try:
                result["value"] = command()
            except Exception as error:
                result["error"] = error
            finally:
                done.set()

        self.enqueue(run)
        deadline = time.monotonic() + timeout_s
        while not done.wait(_POLL_S):
            if self._is_shutdown() or self._shutdown or time.monotonic() > deadline:
                msg = "the simulation thread did not answer (shutting down or stalled)"
                raise SimError(msg)
        if "error" in result:
            raise result["error"]
        return result["value"]

    def pause(self) -> bool:
        """Stop stepping; returns whether it was paused already."""
        with self._wake:
            was, self._paused = self._paused, True
        return was

    def resume(self) -> bool:
        """Start stepping again; returns whether it was paused."""
        with self._wake:
            was, self._paused = self._paused, False
            self._wake.notify()
        return was

    def step_paused(self, steps: int) -> float:
        """Advance the paused simulation by ``steps`` physics steps, outputs written.

        Returns:
            s, the sim time after them.

        Raises:
            CommandError: ``steps`` is 0 or the simulation is running.
            SimError: the simulation thread did not answer.
        """
        if steps <= 0:
            msg = "steps must be > 0"
            raise CommandError(msg)
        with self._wake:
            if not self._paused:
                msg = "the simulation is running; call ~pause first"
                raise CommandError(msg)

        def take_steps() -> float:
            for _ in range(steps):
                self._advance()
            self.outputs.flush()
            return self.sim.time

        return self.call(take_steps, CALL_TIMEOUT_S + STEP_TIMEOUT_S * steps)

    def replace_terrain(self, heightmap: HeightMap) -> None:
        """Replace the terrain and publish it.

        Raises:
            SimError: the simulation thread did not answer.
        """

        def install() -> None:
            self.sim.set_terrain(heightmap)
            self.outputs.publish_terrain()

        self.call(install)

    def stop(self) -> None:
        """Make :meth:`run` return (after the command or step under way)."""
        with self._wake:
            self._shutdown = True
            self._wake.notify()

    # ------------------------------------------------------------------ simulation thread
    def run(self) -> None:
        """Publish the initial state, then step and run commands until :meth:`stop` or a
        shutdown; paused, only run commands (and republish the terrain when due)."""
        sim, outputs, pacer = self.sim, self.outputs, self._pacer
        pacer.restart(sim.time)
        outputs.publish(force=True)
        outputs.flush()
        while not self._is_shutdown():
            with self._wake:
                while not self._shutdown and not self._queue and self._paused:
                    self._wake.wait(timeout=_POLL_S)
                    outputs.publish_terrain_if_due()
                if self._shutdown:
                    return
                commands = list(self._queue)
                self._queue.clear()
                paused = self._paused
            for command in commands:
                command()
            if paused:
                outputs.flush()
                pacer.restart(sim.time)
                continue
            self._advance()
            wait = pacer.wait(sim.time)
            if wait > 0:
                outputs.flush()
                time.sleep(wait)

    def _advance(self) -> None:
        """One physics step and its outputs."""
        self.sim.step()
        self.outputs.after_step()
