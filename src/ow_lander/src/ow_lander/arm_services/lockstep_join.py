"""Joining the simulation's lockstep in the background, as the arm services do (rospy wiring
only; the client is :class:`~ow_runtime.lockstep_client.LockstepClient`)."""

from __future__ import annotations

import threading
from collections.abc import Callable

import rospy

from ow_runtime.lockstep_client import LockstepClient, LockstepError
from ow_runtime.names import REGISTER_SERVICE


class LockstepJoin:
    """Registers ``name`` with the simulation's lockstep on a thread of its own, once the
    simulation offers one (it may start later, or never), and calls ``on_joined`` with the
    client; a node's requests meanwhile wait for it (:meth:`wait`).

    Args:
        name: the client's name (the node's).
        hold: register holding the simulation.
        on_joined: called with the registered client, on the joining thread.
        log: who is joining, for the log lines ("arm services").
    """

    def __init__(
        self, name: str, hold: bool, on_joined: Callable[[LockstepClient], None], log: str
    ) -> None:
        self.name = name
        self._on_joined = on_joined
        self._log = log
        self._over = threading.Event()  # joined, or given up
        threading.Thread(target=self._join, args=(hold,), daemon=True).start()

    def _join(self, hold: bool) -> None:
        client = LockstepClient(self.name)
        try:
            client.register(hold=hold)
        except LockstepError as error:
            rospy.logwarn(f"{self._log}: no lockstep: {error}")
            self._over.set()
            return
        self._on_joined(client)
        self._over.set()
        rospy.on_shutdown(client.close)
        rospy.loginfo(f"{self._log}: in the simulation's lockstep (latency {client.latency} s)")

    def wait(self, timeout_s: float) -> None:
        """While the simulation offers a lockstep (its register service is up) and this is
        still joining it, wait until it has joined (``timeout_s`` of wall time at most). A
        request planned and executed outside it would not release the hold the simulation
        starts with for this client, and both would wait for each other (a mission whose
        stack was ready sooner once called its first step 0.3 s before the join)."""
        if self._over.is_set():
            return
        try:
            code, _, _ = rospy.get_master().lookupService(REGISTER_SERVICE)
        except OSError:
            return  # no master: nothing to wait for
        if code != 1:
            return  # no simulation offering a lockstep (yet): nothing to wait for
        if not self._over.wait(timeout_s):
            rospy.logwarn(f"{self._log}: not in the lockstep after {timeout_s} s; going on outside")
