"""The simulation's locked-joint flags, stamp by stamp, for the arm's decisions in the lockstep
(rospy wiring only)."""

from __future__ import annotations

import threading
from collections import deque
from dataclasses import replace

import rospy

from ow_lander.execution.fault_reaction import HARDWARE, FaultReaction
from ow_msgs.msg import JointStatesFlag
from ow_runtime.names import EVERY_MESSAGE, FLAGS_JOINT_STATES, STAMP_SLACK_S


class LockFlags:
    """The joints the simulation flags as locked, at each joint state's stamp.

    The detector turns the same flags into the HARDWARE fault, but its status reaches the arm
    services whenever it does; in the lockstep the arm decides on the flags of each joint state
    instead, so a lock stops the arm at the same simulation time in every run.

    Subscribes: ``/flags/joint_states`` (ow_msgs/JointStatesFlag, every message, TCP_NODELAY),
        published by the simulation with every ``/joint_states``, with its stamp.
    """

    def __init__(self) -> None:
        self._changed = threading.Condition()
        # 100 s of sim time at 100 Hz: the lockstep keeps a decision a latency behind at most.
        self._flags: deque[tuple[float, frozenset[str]]] = deque(maxlen=10000)
        self._newest = -1.0  # s (sim), the newest stamp received
        rospy.Subscriber(
            FLAGS_JOINT_STATES,
            JointStatesFlag,
            self._on_flags,
            queue_size=EVERY_MESSAGE,
            tcp_nodelay=True,
        )

    def _on_flags(self, msg: JointStatesFlag) -> None:
        locked = frozenset(n for n, f in zip(msg.name, msg.flags, strict=True) if f)
        with self._changed:
            self._newest = msg.header.stamp.to_sec()
            self._flags.append((self._newest, locked))
            self._changed.notify_all()

    def locked_at(self, stamp: float, timeout_s: float) -> frozenset[str] | None:
        """The joints flagged locked with the joint state of ``stamp`` (s, sim), once that
        message has arrived (``timeout_s`` of wall time at most: None then). Older messages
        are dropped: call it with the stamps in order."""
        with self._changed:
            if not self._changed.wait_for(lambda: self._newest >= stamp - STAMP_SLACK_S, timeout_s):
                return None
            locked: frozenset[str] = frozenset()
            while self._flags and self._flags[0][0] <= stamp + STAMP_SLACK_S:
                locked = self._flags.popleft()[1]
            return locked

    def stop_reason(
        self, reaction: FaultReaction, stamp: float, watches_force: bool, timeout_s: float
    ) -> str | None:
        """Why an execution must stop at the joint state of ``stamp`` (s, sim): ``reaction``
        (the fault telemetry now) with the joints flagged locked at that stamp in place of the
        detector's HARDWARE bit; None when nothing says so (or the flags did not come within
        ``timeout_s`` of wall time)."""
        locked = self.locked_at(stamp, timeout_s)
        if locked is None:
            return None
        return without_locks(reaction).with_locked(locked).stop_reason(watches_force)


def without_locks(reaction: FaultReaction) -> FaultReaction:
    """``reaction`` without the detector's HARDWARE bit: in the lockstep the arm acts on the
    lock flags, stamp by stamp, not on when the detector's word arrives."""
    return replace(reaction, arm=reaction.arm & ~HARDWARE)
