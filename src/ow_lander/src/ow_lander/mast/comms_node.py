"""OceanWATERS' ActivateComms action: the communication load on the battery for a while
(rospy wiring only; the antenna mast node serves it)."""

from __future__ import annotations

import math
import time
from typing import Any

import rospy
from std_msgs.msg import Float64

from ow_lander.msg import ActivateCommsAction, ActivateCommsResult
from ow_msgs.srv import SetLoad
from ow_power.loads import COMMS_POWER_W, LOADS_TOPIC, SET_LOAD_SERVICE
from ow_runtime.action_server import SimpleActionServer
from ow_runtime.latched import latched_publisher
from ow_runtime.lockstep_client import LockstepClient, LockstepError
from ow_runtime.names import STAMP_SLACK_S
from ow_runtime.sim_time import wait_for_clock

#: The status text of every ActivateComms goal that ran its duration (OceanWATERS').
SUCCEEDED_TEXT = "Communication uplink/downlink succeeded."
#: The status text of a goal whose simulation was reset under it.
CLOCK_BACK_TEXT = "the simulation clock was set back: the uplink/downlink ended early"
#: The node's name in the simulation's lockstep while an uplink runs.
LOCKSTEP_NAME = "activate_comms"
#: s of wall time the simulation and the power node get to answer.
ANSWER_WAIT_S = 10.0


class _ClockBackError(Exception):
    """The simulation's clock went back under a running goal (a reset)."""


class CommsServer:
    """OceanWATERS' ``ActivateComms`` (ow_lander/ActivateCommsAction): draws
    :data:`~ow_power.loads.COMMS_POWER_W` (9.6 W) from the battery for ``duration`` s of
    simulation time, then SUCCEEDED "Communication uplink/downlink succeeded.". Nothing else of a
    communication is simulated. As in OceanWATERS: no fault group, no check of the duration (0 or
    less ends at once, drawing nothing), a cancel does not shorten it, one goal at a time (a goal
    sent meanwhile starts when the running one ends). A duration that is not finite is aborted
    naming it; a clock set back (a simulation restarted) aborts the goal; the load is removed
    however the goal ends.

    The load is exact in sim time: the node holds the simulation (a lockstep client,
    docs/determinism.md) where the goal starts and where it ends, and sets the load on the power
    node's ``/power/set_load`` there, so the ``/power`` samples stamped in ``(start, end]`` carry
    it, ``duration`` s of them, at any machine load. Without a simulation offering lockstep or
    without the power node it falls back to OceanWATERS' way: the load published on
    ``/electrical_power`` for ``duration`` s of its clock.

    Calls:
        ``/power/set_load`` (ow_msgs/SetLoad), ``/sim/lockstep_register``.
    Publishes:
        ``/electrical_power`` (std_msgs/Float64, W, latched; only in the fallback): 9.6 while a
            goal runs and 0 otherwise (:mod:`ow_power.loads`; the power node adds it to P0).
    """

    def __init__(self) -> None:
        self._load: Any = None
        self._lockstep = LockstepClient(LOCKSTEP_NAME)
        self.server = SimpleActionServer("ActivateComms", ActivateCommsAction, self._on_goal)
        self.server.start()

    def _on_goal(self, goal: Any) -> None:
        duration = float(goal.duration)
        if not math.isfinite(duration):
            self.server.set_aborted(ActivateCommsResult(), f"duration = {duration} s is not finite")
            return
        try:
            if duration > 0.0 and not self._held_uplink(duration):
                self._timed_uplink(duration)
        except _ClockBackError:
            self.server.set_aborted(ActivateCommsResult(), CLOCK_BACK_TEXT)
            return
        except rospy.ROSInterruptException:
            return  # shutting down
        self.server.set_succeeded(ActivateCommsResult(), SUCCEEDED_TEXT)

    # --------------------------------------------------------------------- exact in sim time
    def _held_uplink(self, duration: float) -> bool:
        """Draw the load over ``duration`` s of sim time, holding the simulation at both ends;
        False (nothing drawn) when the simulation offers no lockstep or the power node does not
        answer."""
        try:
            rospy.wait_for_service(SET_LOAD_SERVICE, timeout=ANSWER_WAIT_S)
            held_at = self._lockstep.register(hold=True, wait_s=ANSWER_WAIT_S)
        except (rospy.ROSException, LockstepError) as error:
            rospy.logwarn(f"ActivateComms: the load is timed by this node's clock: {error}")
            return False
        set_load = rospy.ServiceProxy(SET_LOAD_SERVICE, SetLoad)
        try:
            start = self._lockstep.held_stamp(ANSWER_WAIT_S)
            if not self._set_load(set_load, COMMS_POWER_W, start):
                return False
            end: float | None = None
            try:
                # Held at the same time after the hold as the start: the newest joint state then
                # is as far from where it stands (joint states come every few steps).
                end = self._wait_held(start, held_at + duration)
            finally:
                # However the wait ended (None: a reset, a shutdown): from the next sample on.
                if not self._set_load(set_load, 0.0, end):
                    rospy.logerr("ActivateComms: the comms load could not be removed")
            rospy.loginfo(f"ActivateComms: {COMMS_POWER_W} W over ({start:.6f}, {end:.6f}] s")
            wait_for_clock(end, ANSWER_WAIT_S)  # the result is stamped where the load ended
            return True
        except LockstepError as error:
            rospy.logwarn(f"ActivateComms: the load is timed by this node's clock: {error}")
            self._set_load(set_load, 0.0, None)
            return False
        finally:
            self._lockstep.close()

    def _wait_held(self, start: float, end: float) -> float:
        """Hold the simulation at ``end`` (s, sim) and wait until it stands there; the newest
        joint state's stamp then."""
        self._lockstep.hold_at(end)
        while not rospy.is_shutdown():
            now = rospy.get_time()
            if now < start - STAMP_SLACK_S:
                raise _ClockBackError
            if now < end - 0.05:
                time.sleep(0.005)
                continue
            try:
                return self._lockstep.held_stamp(0.5)
            except LockstepError:
                continue  # not there yet, or a reset: look again
        raise rospy.ROSInterruptException("shutting down")

    def _set_load(self, set_load: Any, power_w: float, since: float | None) -> bool:
        try:
            reply = set_load(
                source=rospy.get_name(),
                power_w=power_w,
                now=since is None,
                since=rospy.Time.from_sec(since or 0.0),
            )
        except (rospy.ServiceException, rospy.ROSException) as error:
            rospy.logwarn(f"ActivateComms: {SET_LOAD_SERVICE} failed: {error}")
            return False
        if not reply.success:
            rospy.logwarn(f"ActivateComms: {SET_LOAD_SERVICE} refused {power_w} W: {reply.message}")
        return bool(reply.success)

    # --------------------------------------------------------------- OceanWATERS' way (fallback)
    def _timed_uplink(self, duration: float) -> None:
        if self._load is None:
            self._load = latched_publisher(LOADS_TOPIC, Float64, queue_size=10)
        self._load.publish(Float64(COMMS_POWER_W))
        try:
            rospy.sleep(duration)
        except rospy.ROSTimeMovedBackwardsException as error:
            raise _ClockBackError from error
        finally:
            self._load.publish(Float64(0.0))
