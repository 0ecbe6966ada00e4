"""OceanWATERS' ActivateComms action: the communication load on the battery for a while
(rospy wiring only; the antenna mast node serves it)."""

from __future__ import annotations

import math
from typing import Any

import rospy
from std_msgs.msg import Float64

from ow_lander.msg import ActivateCommsAction, ActivateCommsResult
from ow_power.loads import COMMS_POWER_W, LOADS_TOPIC
from ow_runtime.action_server import SimpleActionServer
from ow_runtime.latched import latched_publisher

#: The status text of every ActivateComms goal that ran its duration (OceanWATERS').
SUCCEEDED_TEXT = "Communication uplink/downlink succeeded."


class CommsServer:
    """OceanWATERS' ``ActivateComms`` (ow_lander/ActivateCommsAction): draws
    :data:`~ow_power.loads.COMMS_POWER_W` (9.6 W) from the battery for ``duration`` s of
    simulation time, then SUCCEEDED "Communication uplink/downlink succeeded.". Nothing else of a
    communication is simulated. As in OceanWATERS: no fault group, no check of the duration (0 or
    less ends at once), a cancel does not shorten it, one goal at a time (a goal sent meanwhile
    starts when the running one ends). A duration that is not finite is aborted naming it; a
    clock set back (a simulation restarted) aborts the goal; the load is removed however the
    goal ends.

    Publishes:
        ``/electrical_power`` (std_msgs/Float64, W, latched): this node's load, 9.6 while a goal
            runs and 0 otherwise (:mod:`ow_power.loads`; the power node adds it to P0).
    """

    def __init__(self) -> None:
        self._load = latched_publisher(LOADS_TOPIC, Float64, queue_size=10)
        self._load.publish(Float64(0.0))
        self.server = SimpleActionServer("ActivateComms", ActivateCommsAction, self._on_goal)
        self.server.start()

    def _on_goal(self, goal: Any) -> None:
        duration = float(goal.duration)
        if not math.isfinite(duration):
            self.server.set_aborted(ActivateCommsResult(), f"duration = {duration} s is not finite")
            return
        self._load.publish(Float64(COMMS_POWER_W))
        try:
            rospy.sleep(max(duration, 0.0))
        except rospy.ROSTimeMovedBackwardsException:
            text = "the simulation clock was set back: the uplink/downlink ended early"
            self.server.set_aborted(ActivateCommsResult(), text)
            return
        except rospy.ROSInterruptException:
            return  # shutting down
        finally:
            self._load.publish(Float64(0.0))
        self.server.set_succeeded(ActivateCommsResult(), SUCCEEDED_TEXT)
