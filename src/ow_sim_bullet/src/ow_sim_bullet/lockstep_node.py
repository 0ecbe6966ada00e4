"""The simulation's lockstep interface (rospy wiring only; the protocol is
:mod:`ow_sim_bullet.lockstep`'s, the waiting :class:`~ow_sim_bullet.runner.SimRunner`'s)."""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

import rospy

from ow_msgs.msg import LockstepAck
from ow_msgs.srv import (
    LockstepRegister,
    LockstepRegisterResponse,
    LockstepStatus,
    LockstepStatusResponse,
)
from ow_runtime.names import EVERY_MESSAGE
from ow_sim_bullet.runner import SimRunner


class LockstepServer:
    """Lockstep clients join, leave and acknowledge here.

    Services: ``~lockstep_register`` (ow_msgs/LockstepRegister): join (``enable``) or leave;
        ``~lockstep_status`` (ow_msgs/LockstepStatus): the clients, and whom the next step
        waits for (e.g. to know that a client's hold has been reached).
    Subscribes: ``~lockstep`` (ow_msgs/LockstepAck): acknowledgements, every one in order.

    Args:
        runner: the simulation thread's runner (its :class:`~ow_sim_bullet.lockstep.Lockstep`).
        expected: clients waited for from the start: registered now, holding the simulation at
            the current time until they register themselves.
    """

    def __init__(self, runner: SimRunner, expected: Iterable[str] = ()) -> None:
        self.runner = runner
        for name in expected:
            runner.lockstep_register(name, enable=True, hold=True)
        rospy.Subscriber(  # no Nagle delay (40 ms) on a round trip
            "~lockstep", LockstepAck, self._on_ack, queue_size=EVERY_MESSAGE, tcp_nodelay=True
        )
        rospy.Service("~lockstep_register", LockstepRegister, self._on_register)
        rospy.Service("~lockstep_status", LockstepStatus, self._on_status)

    def _on_ack(self, msg: LockstepAck) -> None:
        hold = msg.hold_until.to_sec() if msg.hold else None
        if len(msg.name) != len(msg.position):
            rospy.logerr(
                f"sim: lockstep acknowledgement of {msg.client} has {len(msg.name)} names and "
                f"{len(msg.position)} positions: its commands are ignored"
            )
            commands = []
        else:
            commands = list(zip(msg.name, msg.position, strict=True))
        self.runner.lockstep_ack(msg.client, msg.header.stamp.to_sec(), hold, commands)

    def _on_register(self, request: Any) -> LockstepRegisterResponse:
        if not request.client:
            return LockstepRegisterResponse(False, "a lockstep client needs a name", 0.0, 0.0)
        # The caller's node: its subscriptions get the outputs first while it is waited for.
        node = getattr(request, "_connection_header", {}).get("callerid")
        now, done = self.runner.lockstep_register(
            request.client, request.enable, request.hold, node
        )
        rospy.loginfo(f"sim: lockstep: {done}")
        return LockstepRegisterResponse(True, done, now, self.runner.lockstep.latency_s)

    def _on_status(self, _: Any) -> LockstepStatusResponse:
        now, stamp, clients, blocked, holding, terrain = self.runner.lockstep_status()
        waiting_for, reason = blocked or ("", "")
        return LockstepStatusResponse(now, stamp, clients, waiting_for, reason, holding, terrain)
