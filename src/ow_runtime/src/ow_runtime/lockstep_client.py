"""A lockstep client of the simulation (rospy wiring only; the protocol is in
``ow_msgs/LockstepAck`` and docs/determinism.md): the arm services use it, and so can an
autonomy node of yours.

Once registered, the simulation never runs more than its lockstep latency (0.1 s of sim time by
default) past the newest joint state you acknowledged, and what you decide on the joint state of
stamp ``s`` takes effect at exactly ``s + latency``, however slowly your node or the machine
runs. docs/determinism.md shows a node of yours joining it (register after subscribing to
``/joint_states``, then :meth:`LockstepClient.ack` every joint state, with set-points or not).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Mapping
from typing import Any

import rospy

from ow_msgs.msg import LockstepAck
from ow_msgs.srv import LockstepRegister, LockstepStatus
from ow_runtime.names import ACK_TOPIC, REGISTER_SERVICE, STAMP_SLACK_S, STATUS_SERVICE
from ow_runtime.sim_time import wait_for_clock

#: acknowledgements are written in the caller's thread: none may be lost (the simulation would
#: wait for it); rospy's queue cost a thread switch and ~100 us of CPU per acknowledgement.
_ACK_QUEUE = None


class LockstepError(Exception):
    """The simulation does not offer lockstep, or refused the registration."""


class LockstepClient:
    """One lockstep client.

    Publishes: ``/sim/lockstep`` (ow_msgs/LockstepAck). Calls: ``/sim/lockstep_register``.

    Args:
        name: the client's name, unique among the simulation's clients.

    Attributes:
        latency: s of sim time from a joint state to the commands decided on it (the
            simulation's; None until registered).
        registered: whether the simulation has registered this client.
    """

    def __init__(self, name: str) -> None:
        self.name = name
        self.latency: float | None = None
        self.registered = False
        self._lock = threading.Lock()
        self._acked = self._sent = 0.0  # s (sim), newest processed / newest sent
        self._early = -1.0  # s (sim), newest joint state processed before registering
        self._hold_until: float | None = None
        self._publisher = rospy.Publisher(ACK_TOPIC, LockstepAck, queue_size=_ACK_QUEUE)

    def register(self, hold: bool = False, wait_s: float | None = None) -> float:
        """Join the simulation's lockstep; subscribe to what you decide on first.

        Args:
            hold: the simulation steps no further than now until :meth:`release`.
            wait_s: s of wall time to wait for the simulation (None: as long as it takes).

        Returns:
            s, the sim time of registration: acknowledge every joint state after it.

        Raises:
            LockstepError: no simulation offering lockstep within ``wait_s``, or it refused.
        """
        deadline = None if wait_s is None else time.monotonic() + wait_s
        try:
            rospy.wait_for_service(REGISTER_SERVICE, timeout=wait_s)
        except rospy.ROSException as error:
            msg = f"no {REGISTER_SERVICE} within {wait_s} s: is the simulation running?"
            raise LockstepError(msg) from error
        # An acknowledgement published before the simulation is connected would be lost.
        while self._publisher.get_num_connections() == 0 and not rospy.is_shutdown():
            if deadline is not None and time.monotonic() > deadline:
                msg = f"the simulation does not subscribe to {ACK_TOPIC} (waited {wait_s} s)"
                raise LockstepError(msg)
            time.sleep(0.01)
        try:
            reply = rospy.ServiceProxy(REGISTER_SERVICE, LockstepRegister)(
                client=self.name, enable=True, hold=hold
            )
        except rospy.ServiceException as error:
            msg = f"{REGISTER_SERVICE} failed: {error}"
            raise LockstepError(msg) from error
        if not reply.success:
            raise LockstepError(f"{REGISTER_SERVICE} refused {self.name}: {reply.message}")
        with self._lock:
            self._acked = self._sent = reply.sim_time
            self._hold_until = reply.sim_time if hold else None
            self.latency = reply.latency
            self.registered = True
            # Joint states processed before the reply (the simulation steps on meanwhile): no
            # later one would come to trigger their acknowledgement, and both would wait.
            if self._early > self._acked:
                self._acked = self._early
                self._send(None)
        return float(reply.sim_time)

    def ack(
        self, stamp: float, setpoints: Mapping[str, float] | None = None, force: bool = False
    ) -> None:
        """Everything up to the joint state of ``stamp`` (s, sim) is processed; ``setpoints``
        (rad by joint name) take effect at ``stamp + latency``. Acknowledgements before
        :meth:`register` are not sent (those during it are, when it completes); older stamps
        count as the newest.

        Without set-points an acknowledgement is sent only once it is half a latency newer than
        the last one sent (or with ``force``): each publication costs the node a thread switch,
        and the simulation needs one per half latency to keep stepping. Call it with ``force``
        when no further joint state may come to trigger one (e.g. on a backlog just dropped).
        """
        with self._lock:
            if not self.registered or self.latency is None:
                self._early = max(self._early, stamp)  # acknowledged on registering
                return
            self._acked = max(self._acked, stamp)
            if setpoints or force or self._acked >= self._sent + self.latency / 2 - STAMP_SLACK_S:
                self._send(setpoints)

    def hold(
        self, stamp: float, setpoints: Mapping[str, float] | None = None, after_s: float = 0.0
    ) -> float:
        """:meth:`ack` and hold the simulation ``after_s`` (s, sim) after the time these
        set-points take effect, until :meth:`release`; returns the time it holds at (s, sim)."""
        with self._lock:
            if not self.registered or self.latency is None:
                return stamp
            self._acked = max(self._acked, stamp)
            self._hold_until = self._acked + self.latency + after_s
            self._send(setpoints)
            return self._hold_until

    def release(self) -> None:
        """Let the simulation run on from a hold."""
        with self._lock:
            if self.registered and self._hold_until is not None:
                self._hold_until = None
                self._send(None)

    @property
    def holding(self) -> bool:
        """Whether this client holds the simulation."""
        with self._lock:
            return self._hold_until is not None

    def hold_at(self, time_s: float) -> None:
        """Hold the simulation at ``time_s`` (s, sim) until :meth:`release`, a later hold or
        :meth:`close`, as a client that follows no joint state (e.g. a fault schedule): its
        acknowledgement reaches up to the hold, so only the hold stops the simulation."""
        with self._lock:
            if not self.registered or self.latency is None:
                return
            self._acked = max(self._acked, time_s - self.latency)
            self._hold_until = time_s
            self._send(None)

    def held_stamp(self, timeout_s: float) -> float:
        """s (sim), the newest joint state's stamp once the simulation stands held by this
        client with its outputs (terrain too) written (:func:`wait_until_held`; LockstepError)."""
        return wait_until_held(self.name, timeout_s)

    def settle(self, timeout_s: float) -> None:
        """While holding: wait until the simulation stands at the hold and this node's clock
        has reached it (``timeout_s`` of wall time at most for each), so that what the node
        stamps now (e.g. an action's end, stamped by actionlib with the node's clock) carries
        the same time in every run."""
        if not self.holding:
            return
        try:
            stamp = wait_until_held(self.name, timeout_s)
        except LockstepError as error:
            rospy.logwarn(f"{self.name}: {error}")
            return
        wait_for_clock(stamp, timeout_s)

    def close(self) -> None:
        """Leave the lockstep (the simulation no longer waits for this client)."""
        with self._lock:
            if not self.registered:
                return
            self.registered = False
        try:
            rospy.ServiceProxy(REGISTER_SERVICE, LockstepRegister)(
                client=self.name, enable=False, hold=False
            )
        except (rospy.ServiceException, rospy.ROSException) as error:
            rospy.logwarn(f"{self.name}: leaving the lockstep failed: {error}")

    def _send(self, setpoints: Mapping[str, float] | None) -> None:
        """Publish the current state (call holding ``_lock``: the messages keep their order)."""
        self._sent = self._acked
        msg = LockstepAck(client=self.name)
        msg.header.stamp = rospy.Time.from_sec(self._acked)
        if self._hold_until is not None:
            msg.hold = True
            msg.hold_until = rospy.Time.from_sec(self._hold_until)
        for joint, position in (setpoints or {}).items():
            msg.name.append(joint)
            msg.position.append(float(position))
        self._publisher.publish(msg)


def wait_until_held(client: str, timeout_s: float) -> float:
    """Wait until the simulation stands still, held by lockstep client ``client`` (e.g. the arm
    services with ``lockstep_hold`` after an operation); return the stamp (s, sim) of the
    newest joint state it published, the last before the hold.

    Raises:
        LockstepError: the simulation offers no lockstep status, or is not held by ``client``
            within ``timeout_s`` of wall time.
    """
    deadline = time.monotonic() + timeout_s
    try:
        rospy.wait_for_service(STATUS_SERVICE, timeout=timeout_s)
        status = rospy.ServiceProxy(STATUS_SERVICE, LockstepStatus, persistent=True)
        while True:
            reply = status()
            if client in reply.holding:
                return float(reply.joint_state_stamp)
            if time.monotonic() > deadline:
                msg = (
                    f"the simulation was not held by {client} within {timeout_s} s "
                    f"(t={reply.sim_time:.3f} s, waiting for {reply.waiting_for or 'nobody'})"
                )
                raise LockstepError(msg)
            time.sleep(0.005)
    except (rospy.ROSException, rospy.ServiceException) as error:
        msg = f"{STATUS_SERVICE} failed: {error}"
        raise LockstepError(msg) from error


def simulation_status() -> Any:
    """The simulation's ``~lockstep_status`` now (ow_msgs/LockstepStatus response: its time,
    its newest joint state's and terrain's stamps, the clients; LockstepError)."""
    try:
        return rospy.ServiceProxy(STATUS_SERVICE, LockstepStatus)()
    except (rospy.ROSException, rospy.ServiceException) as error:
        msg = f"{STATUS_SERVICE} failed: {error}"
        raise LockstepError(msg) from error
