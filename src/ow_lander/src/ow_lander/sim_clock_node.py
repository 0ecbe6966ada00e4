"""The simulation's clock services as the arm services use them (rospy wiring only)."""

from __future__ import annotations

import threading
import time

import rospy
from std_msgs.msg import Header
from std_srvs.srv import Trigger


class SimClock:
    """Pauses and resumes the simulation's clock around a trajectory's delivery.

    Calls: ``/sim/pause``, ``/sim/resume`` (std_srvs/Trigger), when the simulation offers them;
    whether it does is looked up once, within ``service_wait_s`` s of wall time.
    Subscribes: ``/sim/trajectory_received`` (std_msgs/Header, stamp = the trajectory's start):
        the simulation's receipt of a trajectory, so the clock resumes only once it has it.
    """

    def __init__(self, service_wait_s: float) -> None:
        self.service_wait_s = service_wait_s
        self._offered: bool | None = None
        self._received = threading.Condition()
        self._last_received: rospy.Time | None = None
        self._receipts_connected: bool | None = None
        self._receipts = rospy.Subscriber(
            "/sim/trajectory_received", Header, self._on_received, queue_size=10
        )

    def _on_received(self, msg: Header) -> None:
        with self._received:
            self._last_received = msg.stamp
            self._received.notify_all()

    def wait_received(self, stamp: rospy.Time, fallback_s: float) -> None:
        """Wait (wall time) until the simulation confirms the trajectory starting at ``stamp``,
        up to ``service_wait_s``; a simulation that sends no receipts gets ``fallback_s``."""
        if not self._sends_receipts():
            time.sleep(fallback_s)
            return
        with self._received:
            if not self._received.wait_for(
                lambda: self._last_received == stamp, timeout=self.service_wait_s
            ):
                rospy.logwarn("arm_services: no receipt of the trajectory from the simulation")

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

    def _sends_receipts(self) -> bool:
        """True once the receipt subscription is connected. Right after start-up it may not be
        yet (the first trajectory can follow within a second): wait up to ``service_wait_s`` the
        first time; a simulation that never connects is then used without receipts."""
        if self._receipts_connected is None:
            deadline = time.monotonic() + self.service_wait_s
            while self._receipts.get_num_connections() == 0 and time.monotonic() < deadline:
                time.sleep(0.01)
            self._receipts_connected = self._receipts.get_num_connections() > 0
        return self._receipts_connected

    def _offers(self, services: tuple[str, ...]) -> bool:
        for name in services:
            try:
                rospy.wait_for_service(name, timeout=self.service_wait_s)
            except rospy.ROSException:
                rospy.logwarn("arm_services: no %s: trajectories start after a delay only", name)
                return False
        return True
