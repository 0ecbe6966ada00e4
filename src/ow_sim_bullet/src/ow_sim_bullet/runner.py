"""The simulation thread: steps the simulation (paced to the wall clock, or paused) and runs the
commands other threads hand it between steps. Only this thread touches the simulation; other
threads enqueue commands or wait for their results. No ROS here."""

from __future__ import annotations

import math
import threading
import time
from collections import deque
from collections.abc import Callable
from typing import Any, TypeVar

from ow_description.terrain import HeightMap
from ow_sim_bullet.errors import CommandError, SimError
from ow_sim_bullet.lockstep import Lockstep
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
        log: error log (dropped lockstep clients, bad acknowledgements, ignored commands).

    Attributes:
        lockstep: the synchronous clients (:mod:`ow_sim_bullet.lockstep`; latency and the wall
            time after which a silent client is dropped from the simulation's configuration),
            guarded by this runner: change them through :meth:`lockstep_register` and
            :meth:`lockstep_ack`.
    """

    def __init__(
        self,
        sim: BulletSim,
        outputs: SimOutputs,
        real_time_factor: float,
        start_paused: bool,
        is_shutdown: Callable[[], bool],
        log: Callable[[str], None] = print,
    ) -> None:
        self.sim = sim
        self.outputs = outputs
        self._is_shutdown = is_shutdown
        self._pacer = Pacer(real_time_factor)
        self._wake = threading.Condition(threading.Lock())
        #: s of sim time where the simulation last stood with what it stands at written, the
        #: terrain included (:meth:`_stand`); :meth:`lockstep_status` reports holders from then.
        self._stood_at = -1.0
        self._queue: deque[Callable[[], None]] = deque()
        self._paused = start_paused
        self._shutdown = False
        self._started = False  # the initial state has been published
        self.lockstep = Lockstep(sim.config.lockstep_latency_s)
        self.lockstep_timeout_s = sim.config.lockstep_timeout_s
        self._log = log

    # ------------------------------------------------------------------ other threads
    def enqueue(self, command: Callable[[], None]) -> None:
        """Run ``command`` on the simulation thread before its next step."""
        with self._wake:
            self._queue.append(command)
            self._wake.notify()

    def command_setpoint(
        self,
        joint: str,
        position: float,
        warn: Callable[[str], None],
        applied: Callable[[float | None], None] | None = None,
    ) -> None:
        """Set one joint's set-point (rad) before the next step (:meth:`BulletSim.set_setpoint`).

        Args:
            joint: joint name.
            position: rad; beyond the joint's URDF limits it is clipped onto the limit.
            warn: called on the simulation thread with why the command was ignored (unknown
                joint, non-finite position) or how it was clipped.
            applied: called on the simulation thread, before any later command, with the sim
                time (s) from which the set-point holds, or None when it was ignored.
        """

        def command() -> None:
            try:
                clipped = self.sim.set_setpoint(joint, position)
            except CommandError as error:
                warn(str(error))
                if applied is not None:
                    applied(None)
                return
            if clipped is not None:
                warn(clipped.describe())
            if applied is not None:
                applied(self.sim.time)

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

    def lockstep_register(
        self, name: str, enable: bool, hold: bool, node: str | None = None
    ) -> tuple[float, str]:
        """Register ``name`` as a lockstep client at the current sim time (``enable``), or
        unregister it; returns (sim time s, what was done). ``node``: the node (caller id) it
        runs in: while the simulation waits for its acknowledgement, the outputs are written
        to that node's subscriptions first (None: to everyone)."""
        with self._wake:
            now = self.sim.time
            if enable:
                self.lockstep.register(name, now, hold, time.monotonic(), node)
                done = f"{name} registered at t={now:.6f} s" + (", holding" if hold else "")
            elif self.lockstep.unregister(name):
                done = f"{name} unregistered at t={now:.6f} s"
            else:
                done = f"{name} was not registered"
            self._wake.notify()
        return now, done

    def lockstep_ack(
        self,
        name: str,
        stamp: float,
        hold_until: float | None,
        commands: list[tuple[str, float]],
    ) -> None:
        """A client's acknowledgement (:meth:`Lockstep.ack`); a problem with it is logged."""
        with self._wake:
            problem = self.lockstep.ack(name, stamp, hold_until, commands, time.monotonic())
            self._wake.notify()
        if problem is not None:
            self._log(f"sim: {problem}")

    def lockstep_status(
        self,
    ) -> tuple[float, float, list[str], tuple[str, str] | None, list[str], float]:
        """(sim time s, stamp s of the newest joint state published, the registered clients,
        :meth:`Lockstep.blocking` now, :meth:`Lockstep.holding` now, stamp s of the newest
        terrain published)."""
        with self._wake:
            now, stamp, lockstep = self.sim.time, self.outputs.joint_stamp, self.lockstep
            # A hold shows once the simulation stands with its outputs written: a client that
            # plans on the terrain it stands on reads the terrain's stamp after that.
            stood = self._stood_at == now
            return (
                now,
                stamp,
                list(lockstep.clients),
                lockstep.blocking(now),
                lockstep.holding(now) if stood else [],
                self.outputs.terrain_stamp,
            )

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
            self._wake.notify()
        return was

    def pause_standing(self) -> bool:
        """:meth:`pause`, returning once the simulation thread stands: the step under way is
        finished and everything up to the time it stands at is written (``/clock`` at that
        time, the newest joint state). A node that then waits for what it stands at (its
        ``~lockstep_status``) has all the simulation published before the pause, at any load.

        Raises:
            SimError: the simulation thread did not answer (stalled, or shutting down).
        """
        was = self.pause()
        self.call(lambda: None)  # run by the thread after it stood (see run)
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
            self._started = True  # the steps' outputs follow
            for _ in range(steps):
                if not self._await_clients(stop_at_hold=True):
                    break  # a lockstep client holds the simulation here
                self._advance()
            self._stand()
            return self.sim.time

        return self.call(take_steps, CALL_TIMEOUT_S + STEP_TIMEOUT_S * steps)

    def replace_terrain(self, heightmap: HeightMap, terrain: str = "") -> None:
        """Replace the terrain and publish it (and the regolith budget: the new terrain's layer
        column may differ); ``terrain``, its specification, selects that column.

        Raises:
            SimError: the simulation thread did not answer.
        """

        def install() -> None:
            self.sim.set_terrain(heightmap, terrain)
            self.outputs.publish_terrain()
            self.outputs.publish_budget_if_changed()

        self.call(install)

    def stop(self) -> None:
        """Make :meth:`run` return (after the command or step under way)."""
        with self._wake:
            self._shutdown = True
            self._wake.notify()

    # ------------------------------------------------------------------ simulation thread
    def run(self) -> None:
        """Publish the initial state (when first running), then step and run commands until
        :meth:`stop` or a shutdown; paused, only run commands (and republish the terrain when
        due)."""
        sim, outputs, pacer = self.sim, self.outputs, self._pacer
        pacer.restart(sim.time)
        while not self._is_shutdown():
            if self._paused and self._started:  # it stands: what it stands at goes out first
                self._stand()
            with self._wake:
                while not self._shutdown and not self._queue and self._paused:
                    if self._started and self._stood_at != sim.time:
                        # Paused since the check above: it stands with what it stands at not
                        # yet out, which goes out before any wait (below).
                        break
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
                self._stand()
                pacer.restart(sim.time)
                continue
            if not self._started:
                self._publish_initial()
            if not self._await_clients(stop_at_hold=False, return_on_command=True):
                pacer.restart(sim.time)
                continue
            self._advance()
            wait = pacer.wait(sim.time)
            if wait > 0:
                outputs.flush()
                time.sleep(wait)

    def _publish_initial(self) -> None:
        """Publish the state the simulation starts from, once, when it first runs: a simulation
        started paused publishes it when resumed, so the nodes (and bags) that connected while
        it was paused all receive it."""
        self._started = True
        self.outputs.publish(force=True)
        self.outputs.flush()

    def _await_clients(self, stop_at_hold: bool, return_on_command: bool = False) -> bool:
        """Wait until the lockstep clients let the simulation step from its current time; True
        when it may. False, without waiting, when a client holds it (``stop_at_hold``) and, with
        ``return_on_command``, as soon as a command is queued, the clock paused or the runner
        stopped (the caller runs them and asks again). Everything published is written first:
        the clients decide on it. A client silent for ``lockstep_timeout_s`` is dropped."""
        now = self.sim.time
        with self._wake:
            if return_on_command and self._paused:
                return False  # not one step after a pause
            blocked = self.lockstep.blocking(now)
        if blocked is None:
            return True
        if blocked[1] == "hold":
            self._stand()
        else:  # what the awaited clients decide on goes out now; the rest with the next batch
            self.outputs.publish_standing(terrain=False)
            with self._wake:
                awaited = self.lockstep.awaited_nodes(now)
            self.outputs.flush(only=awaited)
        with self._wake:
            while not self._is_shutdown() and not self._shutdown:
                if return_on_command and self._paused:
                    return False  # paused while held: a client leaving then must not step it
                blocked = self.lockstep.blocking(now)
                if blocked is None:
                    return True
                if blocked[1] == "hold":  # e.g. after an acknowledgement: the clock is out, the
                    self.outputs.publish_standing()  # terrain's publisher queues
                    self.outputs.flush()  # what only the awaited nodes had
                    self._stood_at = now  # under _wake
                if stop_at_hold and blocked[1] == "hold":
                    return False
                if return_on_command and self._queue:
                    return False
                for name in self.lockstep.silent(now, time.monotonic(), self.lockstep_timeout_s):
                    self.lockstep.unregister(name)
                    self._log(
                        f"sim: lockstep client {name} acknowledged nothing for "
                        f"{self.lockstep_timeout_s:g} s of wall time (waiting at t={now:.3f} s): "
                        "dropped from the lockstep"
                    )
                if not self._wake.wait(timeout=_POLL_S):  # nothing for a while: everything
                    self.outputs.flush()  # to everyone (a client deciding on another node's)
                self.outputs.publish_terrain_if_due()
        return False

    def _stand(self, terrain: bool = True) -> None:
        """Write what the simulation stands at (/clock; with ``terrain``, a changed terrain),
        and with the terrain note that it stands here with its outputs out (call without
        holding ``_wake``)."""
        self.outputs.publish_standing(terrain=terrain)
        self.outputs.flush()
        if terrain:
            with self._wake:
                self._stood_at = self.sim.time

    def _advance(self) -> None:
        """One physics step and its outputs; first the lockstep clients' commands due then."""
        with self._wake:
            due = self.lockstep.due(self.sim.time)
        for joint, position in due:
            try:
                if math.isnan(position):  # hold the joint where it is now
                    position = self.sim.position(joint)
                clipped = self.sim.set_setpoint(joint, position)
            except CommandError as error:
                self._log(f"sim: lockstep command ignored: {error}")
                continue
            if clipped is not None:
                self._log(f"sim: lockstep command {clipped.describe()}")
        self.sim.step()
        self.outputs.after_step(lockstep=bool(self.lockstep.clients))
