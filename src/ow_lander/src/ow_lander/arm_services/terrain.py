"""The terrain the arm services plan against (rospy wiring only)."""

from __future__ import annotations

import threading
import time

import rospy

from ow_description.conversions import height_map_from_msg
from ow_description.terrain import HeightMap
from ow_lander.errors import REQUEST_ERRORS
from ow_msgs.msg import HeightMap as HeightMapMsg
from ow_runtime.lockstep_client import LockstepError, simulation_status
from ow_runtime.names import STAMP_SLACK_S, TERRAIN_TOPIC

#: s (wall) a plan in the lockstep waits for the terrain the simulation last published.
TERRAIN_CATCH_UP_S = 10.0


class TerrainFeed:
    """The newest ``/sim/terrain``, and the simulation's terrain before each plan in the lockstep.

    Subscribes: ``/sim/terrain`` (ow_msgs/HeightMap, latched).
    Calls (with ``lockstep``): ``/sim/lockstep_status`` (its ``terrain_stamp``).

    Args:
        wait_s: s (wall) after start-up a plan waits for a first terrain (it may be on its way).
        fallback_ground_z: m, the flat ground planned against without any terrain.
        lockstep: before each plan, wait for the terrain the simulation last published: it
            publishes where it stops, so the one the next operation starts on may still be on its
            way when that operation is planned (a plan against the terrain before it once made a
            grind's lift-off differ between two equal runs).
    """

    def __init__(self, wait_s: float, fallback_ground_z: float, lockstep: bool) -> None:
        self._changed = threading.Condition(threading.Lock())
        self._deadline = time.monotonic() + wait_s
        self._terrain: HeightMap | None = None
        self._stamp = -1.0  # s (sim) of the newest terrain received
        self._fallback_z = fallback_ground_z
        self._fallback = HeightMap.flat(fallback_ground_z)
        self._lockstep = lockstep
        rospy.Subscriber(TERRAIN_TOPIC, HeightMapMsg, self._on_terrain, queue_size=1)

    def _on_terrain(self, msg: HeightMapMsg) -> None:
        try:
            terrain = height_map_from_msg(msg)
        except REQUEST_ERRORS as error:
            rospy.logerr("arm_services: ignoring /sim/terrain: %s", error)
            return
        with self._changed:
            self._terrain = terrain
            self._stamp = msg.header.stamp.to_sec()
            self._changed.notify_all()

    def current(self) -> tuple[HeightMap, str]:
        """The terrain to plan against, and a note when it is not the simulation's: the newest
        /sim/terrain (in the lockstep, once it is the one the simulation last published),
        waited for until ``wait_s`` after start-up, else the fallback (later plans do not
        wait: no simulation sends it)."""
        newest = -1.0
        if self._lockstep:
            try:
                newest = float(simulation_status().terrain_stamp)
            except LockstepError:
                newest = -1.0  # no simulation offering the lockstep: nothing to wait for
        with self._changed:
            wait_s = max(0.0, self._deadline - time.monotonic())
            self._changed.wait_for(lambda: self._terrain is not None, timeout=wait_s)
            if newest >= 0.0:
                self._changed.wait_for(
                    lambda: self._stamp >= newest - STAMP_SLACK_S, timeout=TERRAIN_CATCH_UP_S
                )
            terrain, stamp = self._terrain, self._stamp
        if terrain is None:
            note = (
                f"no /sim/terrain received: planned against flat ground at z={self._fallback_z} m"
            )
            return self._fallback, note
        if stamp < newest - STAMP_SLACK_S:
            return terrain, (
                f"planned against the terrain of t = {stamp:.3f} s: the simulation's of "
                f"t = {newest:.3f} s did not arrive within {TERRAIN_CATCH_UP_S:g} s"
            )
        return terrain, ""
