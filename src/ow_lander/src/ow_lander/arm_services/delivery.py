"""How ``arm_services`` hands a trajectory to the simulation (rospy wiring only; a node module of
the arm_services node)."""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping

import numpy as np
import rospy
from trajectory_msgs.msg import JointTrajectory

from ow_description.trajectory import Trajectory
from ow_lander import conversions as conv
from ow_lander.arm_services.observer import ArmObserver
from ow_lander.config import ExecutionConfig
from ow_runtime.clock_client import SimClock, TrajectoryDeliveryError
from ow_runtime.names import TRAJECTORY_TOPIC


class TrajectoryDelivery:
    """Sends trajectories to the simulation's joint trajectory controller.

    Publishes: ``/sim/joint_trajectory`` (trajectory_msgs/JointTrajectory): trajectories, and
        a stop's braking hold (:meth:`hold`).
    Calls: ``/sim/pause``, ``/sim/resume`` (std_srvs/Trigger) around a delivery, through
        :attr:`sim_clock` (:class:`~ow_runtime.clock_client.SimClock`).

    Args:
        config: the ``execution/*`` parameters.
        observer: the joint states (the newest stamp, and when they fall quiet).
    """

    def __init__(self, config: ExecutionConfig, observer: ArmObserver) -> None:
        self.config = config
        self.observer = observer
        self.sim_clock = SimClock(config.service_wait_s)
        self.publisher = rospy.Publisher(TRAJECTORY_TOPIC, JointTrajectory, queue_size=10)

    def hold(self, positions: Mapping[str, float]) -> bool:
        """Hand the simulation a hold of ``positions`` (rad by joint name) as a one-point
        trajectory starting on arrival, and wait for its receipt (a stop's braking, sent while
        the clock is paused: it takes effect before the clock runs on, at any load). False when
        the simulation sends no receipts: publish the hold as set-points instead.

        Raises:
            TrajectoryDeliveryError: no receipt came, or the simulation ignored the hold.
        """
        if self.publisher.get_num_connections() == 0 or not self.sim_clock.sends_receipts():
            return False
        joints = tuple(positions)
        row = np.array([[positions[j] for j in joints]])
        hold = Trajectory(joints, np.zeros(1), row, np.zeros_like(row), ("hold",), "stop")
        token = self.sim_clock.new_token()
        self.publisher.publish(conv.trajectory_msg(hold, 0.0, token))
        self.sim_clock.wait_received(token)
        return True

    def send(self, trajectory: Trajectory, started: Callable[[float], None]) -> float:
        """Hand ``trajectory`` to the simulation; call ``started`` with when (sim time, s) it
        starts, before the clock runs on, and return that time.

        A simulation running many times faster than real time could pass the start time before
        the message arrives, so its clock is paused while the message is delivered (when it
        offers ``/sim/pause`` and ``/sim/resume``), and resumed only if it was running. A
        simulation that sends receipts starts the trajectory when it queues it, clock stopped,
        and its receipt says when: the start is then exact whatever the machine's load.
        Otherwise the start is ``start_delay_s`` after the newest joint state.

        ``started`` is called while the clock is still paused: whatever watches the execution
        is in place before the simulation runs it, however late this thread runs after the
        resume (one set up after it misses the states that go by until its thread runs).

        Raises:
            TrajectoryDeliveryError: the simulation does not subscribe to the trajectory topic,
                sent no receipt, or ignored the trajectory.
        """
        cfg = self.config
        deadline = time.monotonic() + cfg.service_wait_s
        while self.publisher.get_num_connections() == 0:  # else the message is lost
            if time.monotonic() > deadline:
                msg = (
                    "the simulation does not subscribe to /sim/joint_trajectory "
                    f"(waited {cfg.service_wait_s} s)"
                )
                raise TrajectoryDeliveryError(msg)
            time.sleep(0.01)
        paused_here = self.sim_clock.pause()
        paused = paused_here is not None
        try:
            if paused and self.sim_clock.sends_receipts():
                token = self.sim_clock.new_token()
                self.publisher.publish(conv.trajectory_msg(trajectory, 0.0, token))
                t_start = float(self.sim_clock.wait_received(token).to_sec())
            else:
                if paused:
                    self.observer.wait_quiet(cfg.delivery_wait_s)
                t_start = self.observer.newest_stamp() + cfg.start_delay_s
                self.publisher.publish(conv.trajectory_msg(trajectory, t_start))
                if paused:
                    time.sleep(cfg.delivery_wait_s)  # no receipts: time for the delivery
            started(t_start)
            return t_start
        finally:
            if paused_here:
                self.sim_clock.resume()
