"""How ``arm_services`` carries out an execution's decisions (rospy wiring only; a node module
of the arm_services node): lockstep acknowledgements, or joint commands."""

from __future__ import annotations

import math

import rospy
from std_msgs.msg import Float64

from ow_description.description import ARM_JOINTS
from ow_lander import conversions as conv
from ow_lander.config import ExecutionConfig
from ow_lander.execution.monitor import Decision
from ow_runtime.lockstep_client import LockstepClient


class DecisionOutlet:
    """Sends the set-points and holds of :class:`~ow_lander.execution.monitor.Decision` s.

    Publishes: ``/<joint>_position_controller/command`` (std_msgs/Float64, rad) for the six
        arm joints, outside the simulation's lockstep (or for a stop's braking); in it, the
        decisions go out as the client's acknowledgements (``/sim/lockstep``, see
        :mod:`ow_runtime.lockstep_client`).

    Args:
        config: the ``execution/*`` parameters (``lockstep_hold``, ``lockstep_settle_s``).
    """

    def __init__(self, config: ExecutionConfig) -> None:
        self.config = config
        self.command_pubs = {
            j: rospy.Publisher(conv.command_topic(j), Float64, queue_size=10) for j in ARM_JOINTS
        }

    def apply(
        self, decision: Decision, stamp: float, lockstep: LockstepClient | None, now: bool
    ) -> None:
        """Carry out the decision on the joint state of ``stamp`` (s, sim): in the ``lockstep``,
        as its acknowledgement (set-points then hold, from ``stamp`` + latency; with
        ``lockstep_hold`` the simulation stops ``lockstep_settle_s`` later when the execution
        ends), else published at once. ``now``: published at once anyway (a stop's braking:
        the clock is paused while the stop is requested, so it brakes from the request, not a
        latency later; a stop is not part of a deterministic run)."""
        if lockstep is None or now:
            self.command(decision)
            decision = Decision(result=decision.result)
            if lockstep is None:
                return
        hold = decision.hold or {}
        if decision.in_place:  # where each joint is when it takes effect, not a latency ago
            hold = dict.fromkeys(hold, math.nan)
        commands = {**(decision.setpoints or {}), **hold}
        if decision.result is not None and self.config.lockstep_hold:
            lockstep.hold(stamp, commands, self.config.lockstep_settle_s)
        else:
            lockstep.ack(stamp, commands)

    def command(self, decision: Decision) -> None:
        """Publish a decision's set-points, then its hold."""
        for commands in (decision.setpoints, decision.hold):
            for joint, value in (commands or {}).items():
                self.command_pubs[joint].publish(Float64(value))
