"""A live DEM's failure during an execution, asked of the simulation when the execution ends
(rospy wiring only; the simulation's ``/sim/dem_digs_between``, docs/dem.md)."""

from __future__ import annotations

import rospy

from ow_msgs.srv import DemDigs
from ow_runtime.names import SIM_DEM_DIGS_SERVICE

#: The operations whose trajectories a live DEM digs (the scoop's; the grinder gets the fallback
#: model): only their executions ask the simulation, so no other execution ends later.
LIVE_DEM_OPERATIONS = frozenset({"dig_linear", "dig_circular"})


def live_dem_failure(start_s: float, end_s: float) -> str | None:
    """Why the live DEM failed during a dig the simulation ended between ``start_s`` and
    ``end_s`` (s, sim: an execution's first row and its end); None when none failed or the
    simulation runs no live DEM (it does not offer the service). The simulation has published
    everything up to ``end_s`` (the execution ended on its joint state of that stamp), so the
    answer is the same in every run."""
    try:
        reply = rospy.ServiceProxy(SIM_DEM_DIGS_SERVICE, DemDigs)(
            rospy.Time.from_sec(max(start_s, 0.0)), rospy.Time.from_sec(max(end_s, 0.0))
        )
    except (rospy.ServiceException, rospy.ROSException):
        return None  # no live DEM here
    failed = [dig.error for dig in reply.digs if dig.error]
    if not failed:
        return None
    return (
        f"the live DEM failed during the dig ({failed[0]}); the rest of the dig ran on the "
        "fallback terrain-force model"
    )
