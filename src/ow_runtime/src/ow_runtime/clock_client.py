"""The simulation's clock services as the arm services use them (rospy wiring only)."""

from __future__ import annotations

import threading
import time
from typing import Any

import rospy
from std_msgs.msg import Header
from std_srvs.srv import Trigger

from ow_runtime.lockstep_client import LockstepError, simulation_status
from ow_runtime.names import ALREADY_PAUSED, REFUSED, SIM_RESUME


class TrajectoryDeliveryError(Exception):
    """A trajectory did not reach the simulation, or the simulation ignored it."""


class SimClock:
    """Pauses and resumes the simulation's clock around a trajectory's delivery; a clock
    stopped by someone else stays stopped.

    Calls: ``/sim/pause``, ``/sim/resume`` (std_srvs/Trigger), when the simulation offers them;
    whether it does is looked up once, within ``service_wait_s`` s of wall time.
    Subscribes: ``/sim/trajectory_received`` (std_msgs/Header: stamp = the sim time the
        trajectory starts at; frame_id = the trajectory's token, "refused:<token>" if the
        simulation ignored it): the simulation's
        receipt of a trajectory, so the clock resumes only once it has it, and the start is the
        simulation's own (no guess from the newest /joint_states, which may lag under load).
    """

    def __init__(self, service_wait_s: float) -> None:
        self.service_wait_s = service_wait_s
        self._offered: bool | None = None
        self._received = threading.Condition()
        self._receipts_by_token: dict[str, rospy.Time | None] = {}
        self._tokens = 0
        self._receipts_connected: bool | None = None
        self._receipts = rospy.Subscriber(
            "/sim/trajectory_received", Header, self._on_received, queue_size=10
        )

    def _on_received(self, msg: Header) -> None:
        with self._received:
            refused = msg.frame_id.startswith(REFUSED)
            token = msg.frame_id.removeprefix(REFUSED)
            if token:
                self._receipts_by_token[token] = None if refused else msg.stamp
                self._received.notify_all()

    def new_token(self) -> str:
        """A token for the next trajectory's header (frame_id), unique to this node."""
        self._tokens += 1
        return f"{rospy.get_name()}#{self._tokens}"

    def sends_receipts(self) -> bool:
        """True once the receipt subscription is connected. Right after start-up it may not be
        yet (the first trajectory can follow within a second): wait up to ``service_wait_s`` the
        first time; a simulation that never connects is then used without receipts."""
        if self._receipts_connected is None:
            deadline = time.monotonic() + self.service_wait_s
            while self._receipts.get_num_connections() == 0 and time.monotonic() < deadline:
                time.sleep(0.01)
            self._receipts_connected = self._receipts.get_num_connections() > 0
        return self._receipts_connected

    def wait_received(self, token: str) -> rospy.Time:
        """The start (sim time) the simulation gave the trajectory with ``token``, waited for up
        to ``service_wait_s`` of wall time.

        Raises:
            TrajectoryDeliveryError: no receipt came, or the simulation ignored the trajectory.
        """
        with self._received:
            if not self._received.wait_for(
                lambda: token in self._receipts_by_token, timeout=self.service_wait_s
            ):
                msg = f"the simulation sent no receipt of the trajectory in {self.service_wait_s} s"
                raise TrajectoryDeliveryError(msg)
            start = self._receipts_by_token.pop(token)
        if start is None:
            msg = "the simulation ignored the trajectory (its log says why)"
            raise TrajectoryDeliveryError(msg)
        return start

    def pause(self) -> bool | None:
        """Stop the simulation's clock (``/sim/pause``). True: this call stopped it (resume it
        with :meth:`resume` when done); False: it was stopped already (by a user, a test stepping
        it, or a mission between steps: leave it stopped); None: the simulation offers no
        pause, or the call failed (logged)."""
        response = self._call("pause")
        if response is None:
            return None
        return response.message != ALREADY_PAUSED

    def standing(self) -> tuple[float, float] | None:
        """Where the simulation stands once :meth:`pause` answered (it answers once the
        simulation has published everything up to there): its time and the stamp of the newest
        joint state it published (s, sim), from ``/sim/lockstep_status``; None when it offers
        none (logged)."""
        try:
            reply = simulation_status()
        except LockstepError as error:
            rospy.logwarn(f"arm_services: {error}")
            return None
        return float(reply.sim_time), float(reply.joint_state_stamp)

    def resume(self) -> None:
        """Restart the simulation's clock (``/sim/resume``), after a :meth:`pause` that
        returned True."""
        self._call("resume")

    def _call(self, action: str) -> Any:
        """Call ``/sim/<action>``; its response, or None when the simulation has none or the
        call failed (logged)."""
        if self._offered is None:
            self._offered = self._offers(("/sim/pause", SIM_RESUME))
        if not self._offered:
            return None
        try:
            response = rospy.ServiceProxy(f"/sim/{action}", Trigger)()
        except rospy.ServiceException as error:
            rospy.logwarn("arm_services: /sim/%s failed: %s", action, error)
            return None
        return response if response.success else None

    def _offers(self, services: tuple[str, ...]) -> bool:
        for name in services:
            try:
                rospy.wait_for_service(name, timeout=self.service_wait_s)
            except rospy.ROSException:
                rospy.logwarn("arm_services: no %s: trajectories start after a delay only", name)
                return False
        return True
