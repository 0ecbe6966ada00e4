"""A mission's fault schedule applied through the ``/faults`` server (rospy wiring only; the
timing is :class:`ow_mission.fault_schedule.ScheduleTimer`'s)."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterable
from typing import Any

import rospy
from dynamic_reconfigure import DynamicReconfigureCallbackException
from dynamic_reconfigure.client import Client
from rosgraph_msgs.msg import Clock

from ow_faults.protocol import APPLIED_TOPIC, CHANGES_TOPIC
from ow_mission.fault_schedule import AppliedFault, ScheduledFault, ScheduleTimer
from ow_msgs.msg import FaultChange, FaultChangeApplied
from ow_runtime.lockstep_client import LockstepClient, LockstepError, wait_until_held
from ow_runtime.names import CLOCK, FAULTS

#: s of wall time to wait for the ``/faults`` server when the runner starts.
FAULTS_SERVER_TIMEOUT_S = 10.0
#: s of wall time to wait for every follower of ``/faults/changes`` to apply a change.
FOLLOWERS_TIMEOUT_S = 10.0
#: The lockstep client that holds the simulation at each scheduled fault's time.
LOCKSTEP_NAME = "/mission_faults"
#: s of wall time between looks at the simulation while a hold is awaited.
_POLL_S = 0.01


class FaultScheduleRunner:
    """Sends each change of a mission's fault schedule to ``/faults`` at its simulation time,
    in the mission's process.

    In the lockstep (``lockstep``, the mission's default) the simulation is held at each
    entry's due time by the lockstep client ``/mission_faults`` (which follows no joint state:
    it only holds); the change is sent there, and the simulation goes on once every follower of
    ``/faults/changes`` (the nodes advertising ``/faults/applied``: simulation, monitors with
    the battery and the detector) has applied it. The change then holds from exactly the due
    time, whatever the machine's load (``applied_s`` = ``due_s``). Without the lockstep an entry
    is sent at the first ``/clock`` at or after its due time, the simulation running on
    meanwhile.

    Subscribes: ``/clock`` (rosgraph_msgs/Clock); ``/faults/changes`` (ow_msgs/FaultChange) and
        ``/faults/applied`` (ow_msgs/FaultChangeApplied): the followers' word.
    Services used: ``/faults/set_parameters`` (dynamic_reconfigure/Reconfigure), through
        dynamic_reconfigure's client. A change the server refuses is recorded with its message;
        the mission goes on. ``/sim/lockstep_register`` and ``/sim/lockstep_status``.
    Told by the mission: :meth:`step_started` at each step's start (s of sim time, the
        simulation standing still): an entry due then (``after_s: 0``) is applied before the
        step runs, and later ones of the step are held for.

    Args:
        schedule: the mission file's entries; none: no client, no subscription.
        publishers: the nodes publishing a topic, from the master (the followers are those of
            ``/faults/applied``: :meth:`ow_bringup.stack.RosMaster.publishers`).
        lockstep: hold the simulation at each entry (the simulation offers a lockstep).
    """

    def __init__(
        self,
        schedule: Iterable[ScheduledFault],
        publishers: Callable[[str], list[str]],
        lockstep: bool = True,
    ) -> None:
        self.timer = ScheduleTimer(schedule)
        self._publishers = publishers
        self.applied: list[AppliedFault] = []
        self._lock = threading.RLock()
        self._followed = threading.Condition()
        self._version = 0  # the newest /faults/changes version received
        self._acks: dict[str, int] = {}  # follower node -> newest version it applied
        self._clock = 0.0
        self._stop = threading.Event()
        self._client: Any = None
        self._lockstep: LockstepClient | None = None
        self._hold_s: float | None = None
        if not self.timer.schedule:
            return
        self._client = Client(FAULTS, timeout=FAULTS_SERVER_TIMEOUT_S)
        rospy.Subscriber(CHANGES_TOPIC, FaultChange, self._on_change, queue_size=None)
        rospy.Subscriber(APPLIED_TOPIC, FaultChangeApplied, self._on_applied, queue_size=None)
        rospy.Subscriber(CLOCK, Clock, self._on_clock, queue_size=1)
        if lockstep:
            self._lockstep = LockstepClient(LOCKSTEP_NAME)
            threading.Thread(target=self._hold_loop, name="faults", daemon=True).start()

    # ------------------------------------------------------------------------- callbacks
    def _on_clock(self, msg: Any) -> None:
        self._clock = msg.clock.to_sec()
        if self._lockstep is None:
            self.poll(self._clock)

    def _on_change(self, msg: FaultChange) -> None:
        with self._followed:
            self._version = max(self._version, msg.version)
            self._followed.notify_all()

    def _on_applied(self, msg: FaultChangeApplied) -> None:
        with self._followed:
            self._acks[msg.node] = max(self._acks.get(msg.node, -1), msg.version)
            self._followed.notify_all()

    # --------------------------------------------------------------------------- schedule
    def step_started(self, step: str, start_s: float) -> None:
        """Note a step's start (s, sim; the simulation stands there), apply what is due at it
        and hold the simulation for the step's later entries."""
        with self._lock:
            self.timer.step_started(step, start_s)
            self.poll(start_s)
            self._hold_next()

    def start(self, now_s: float) -> None:
        """Apply what is due at the simulation's start (``now_s``, s sim, standing still) and
        hold the simulation for the next entry."""
        with self._lock:
            self.poll(now_s)
            self._hold_next()

    def poll(self, now_s: float) -> None:
        """Apply every entry due at or before ``now_s`` (s, sim), earliest first."""
        with self._lock:
            for index, entry, due_s in self.timer.due(now_s):
                self.applied.append(self._apply(index, entry, due_s, now_s))

    def stop(self) -> None:
        """Stop holding the simulation (the mission ends)."""
        self._stop.set()
        with self._lock:
            if self._lockstep is not None:
                self._lockstep.close()

    def results(self) -> list[AppliedFault]:
        """Every entry: those applied or refused, in the order they came due, then those that
        never came due."""
        with self._lock:
            return [*self.applied, *self.timer.never_due()]

    # ----------------------------------------------------------------------------- holds
    def _hold_next(self) -> None:
        """Hold the simulation at the next entry's due time (holding ``_lock``), or let it go
        when no entry is known to come due."""
        client = self._lockstep
        if client is None:
            return
        due = self.timer.next_due_s()
        if due is None:
            if client.registered:
                client.close()
            self._hold_s = None
            return
        try:
            if not client.registered:
                client.register(wait_s=FAULTS_SERVER_TIMEOUT_S)
        except LockstepError as error:
            rospy.logerr(f"mission: faults are not held for: {error}")
            self._lockstep = None
            return
        client.hold_at(due)
        self._hold_s = due

    def _hold_loop(self) -> None:
        """Apply each entry where the simulation is held for it, then hold for the next."""
        while not self._stop.is_set():
            with self._lock:
                due = self._hold_s
            # Ask the simulation only near the hold: it stands at or before it.
            if due is None or self._clock < due - 0.05:
                self._stop.wait(_POLL_S)
                continue
            try:
                stamp = wait_until_held(LOCKSTEP_NAME, 0.5)
            except LockstepError:
                continue  # not there yet (the step ended first): look again
            with self._lock:
                if self._hold_s != due:
                    continue  # a step started meanwhile and moved the hold
                self.poll(max(stamp, due))
                self._hold_next()

    # ---------------------------------------------------------------------------- changes
    def _apply(self, index: int, entry: ScheduledFault, due_s: float, now_s: float) -> AppliedFault:
        record = AppliedFault(index, entry.describe(), dict(entry.changes), due_s=due_s)
        with self._followed:
            version = self._version
        try:
            self._client.update_configuration(dict(entry.changes))
        except (DynamicReconfigureCallbackException, rospy.ROSException) as exc:
            # The server's message is on the service exception the client raised from.
            record.error = str(exc.__context__ or exc)
            rospy.logerr(f"mission: fault {record.description} refused: {record.error}")
            return record
        record.applied_s = now_s if self._lockstep is not None else max(rospy.get_time(), now_s)
        late = self._wait_followers(version)
        if late:
            rospy.logwarn(
                f"mission: fault {record.description}: {', '.join(late)} did not apply it "
                f"within {FOLLOWERS_TIMEOUT_S} s"
            )
        rospy.loginfo(
            f"mission: fault {record.description} applied at t = {record.applied_s:.3f} s"
        )
        return record

    def _wait_followers(self, before: int) -> list[str]:
        """Wait until every follower has applied the first change after version ``before``
        (the server published it before it answered); the followers that have not."""
        try:
            followers = self._publishers(APPLIED_TOPIC)
        except Exception as error:  # the master is gone: the mission ends anyway
            return [f"the master ({error})"]
        deadline = time.monotonic() + FOLLOWERS_TIMEOUT_S

        def late() -> list[str]:
            version = self._version
            if version <= before:
                return [FAULTS]
            return [n for n in followers if self._acks.get(n, -1) < version]

        with self._followed:
            while late() and not self._stop.is_set():
                left = deadline - time.monotonic()
                if left <= 0:
                    break
                self._followed.wait(min(left, 0.1))
            return late()
