"""The simulation's clock services as the arm services use them (rospy wiring only)."""

from __future__ import annotations

import rospy
from std_srvs.srv import Trigger


class SimClock:
    """Pauses and resumes the simulation's clock around a trajectory's delivery.

    Calls: ``/sim/pause``, ``/sim/resume`` (std_srvs/Trigger), when the simulation offers them;
    whether it does is looked up once, within ``service_wait_s`` s of wall time.
    """

    def __init__(self, service_wait_s: float) -> None:
        self.service_wait_s = service_wait_s
        self._offered: bool | None = None

    def call(self, action: str) -> bool:
        """Call ``/sim/<action>`` (pause or resume); False when the simulation has none or the
        call failed (logged)."""
        if self._offered is None:
            self._offered = self._offers(("/sim/pause", "/sim/resume"))
        if not self._offered:
            return False
        try:
            return bool(rospy.ServiceProxy(f"/sim/{action}", Trigger)().success)
        except rospy.ServiceException as error:
            rospy.logwarn("arm_services: /sim/%s failed: %s", action, error)
            return False

    def _offers(self, services: tuple[str, ...]) -> bool:
        for name in services:
            try:
                rospy.wait_for_service(name, timeout=self.service_wait_s)
            except rospy.ROSException:
                rospy.logwarn("arm_services: no %s: trajectories start after a delay only", name)
                return False
        return True
