"""The mission's calls to its stack's services (rospy wiring only): the simulation's clock and
where it stands, and the recorder's progress before the stack stops (which topics and how far:
:func:`ow_mission.mission.drain_periods`, :func:`~ow_mission.mission.topics_behind`).
"""

from __future__ import annotations

import time
from collections.abc import Mapping

import rospy
from std_srvs.srv import Trigger

from ow_mission.mission import topics_behind
from ow_msgs.srv import RecorderProgress
from ow_runtime.lockstep_client import LockstepError, simulation_status
from ow_runtime.names import STATUS_SERVICE

#: The recorder's progress service (ow_power record node, ``~progress``).
PROGRESS_SERVICE = "/record/progress"
#: s (wall) between two questions to the recorder.
POLL_S = 0.01


def wait_recorded(end_s: float, periods: Mapping[str, float], timeout_s: float) -> str:
    """Wait until the recorder has written every topic of ``periods`` up to ``end_s`` (s, sim),
    at most ``timeout_s`` of wall time.

    Returns:
        "" once it has; else what it lacks (or why it could not be asked).
    """
    deadline = time.monotonic() + timeout_s
    try:
        rospy.wait_for_service(PROGRESS_SERVICE, timeout=timeout_s)
        progress = rospy.ServiceProxy(PROGRESS_SERVICE, RecorderProgress)
        while True:
            reply = progress()
            behind = topics_behind(
                dict(zip(reply.topics, reply.latest_s, strict=True)), end_s, periods
            )
            if not behind:
                return ""
            if time.monotonic() > deadline:
                break
            time.sleep(POLL_S)
    except (rospy.ROSException, rospy.ServiceException) as exc:
        return f"{PROGRESS_SERVICE} failed: {exc}"
    lacking = ", ".join(f"{topic} only up to {s:.2f} s" for topic, s in behind.items())
    return (
        f"the bags may lack the end of the run: after {timeout_s:g} s (wall) the recorder had "
        f"{lacking} of {end_s:.2f} s"
    )


def sim_clock(action: str, between_steps: bool = False) -> str | None:
    """Call ``/sim/pause`` or ``/sim/resume``; None on success, else what went wrong (between
    steps only printed: the step's own checks report a simulation that does not run)."""
    try:
        reply = rospy.ServiceProxy(f"/sim/{action}", Trigger)()
        error = None if reply.success else f"/sim/{action} refused: {reply.message}"
    except (rospy.ROSException, rospy.ServiceException) as exc:
        error = f"/sim/{action} failed: {exc}"
    if error is not None and between_steps:
        print(f"[mission] {error}", flush=True)
    return error


def stands_at(timeout_s: float) -> tuple[float, float]:
    """s (sim), where the simulation stands when held or paused, and the stamp of its newest
    joint state (:class:`~ow_runtime.lockstep_client.LockstepError` when it cannot say)."""
    try:
        rospy.wait_for_service(STATUS_SERVICE, timeout=timeout_s)
    except rospy.ROSException as error:
        msg = f"{STATUS_SERVICE} failed: {error}"
        raise LockstepError(msg) from error
    reply = simulation_status()
    return float(reply.sim_time), float(reply.joint_state_stamp)
