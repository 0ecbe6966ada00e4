"""ROS wiring of the simulation's command topics (joint set-points, trajectories), each with a
receipt: a node that commands a paused simulation knows when its command was taken, so it can
step the simulation after it without a wall-clock wait."""

from __future__ import annotations

from functools import partial

import rospy
from std_msgs.msg import Float64, Header
from trajectory_msgs.msg import JointTrajectory as JointTrajectoryMsg

from ow_runtime.names import EVERY_MESSAGE, REFUSED
from ow_sim_bullet import conversions
from ow_sim_bullet.config import CONTROLLER_NAMES
from ow_sim_bullet.errors import CommandError
from ow_sim_bullet.runner import SimRunner

#: receipts a publisher holds for a slow subscriber (a mission sends a few hundred commands).
_RECEIPT_QUEUE = 1000


class SimCommands:
    """The command topics of the ``sim`` node.

    Subscriptions:
        /<controller>_position_controller/command (std_msgs/Float64): rad, set-point of one joint
            (controllers shou_yaw, shou_pitch, prox_pitch, dist_pitch, hand_yaw, scoop_yaw,
            grinder_yaw, ant_pan, ant_tilt); cancels that joint's trajectory.
        ~joint_trajectory (trajectory_msgs/JointTrajectory): interpolated by the sim from its
            stamp (0: on arrival).

    Publications (std_msgs/Header, each sent before any later command is taken):
        ~setpoint_received: a set-point taken: stamp = the sim time it holds from, frame_id =
            its joint; "refused:<joint>", stamp 0, if ignored (not finite).
        ~trajectory_received: a trajectory queued: stamp = its start, frame_id = its header's
            frame_id echoed; "refused:" prefixed, stamp 0, if ignored.
    """

    def __init__(self, runner: SimRunner) -> None:
        self.runner = runner
        for joint, controller in CONTROLLER_NAMES.items():
            topic = f"/{controller}_position_controller/command"
            rospy.Subscriber(
                topic, Float64, partial(self._on_setpoint, joint), queue_size=EVERY_MESSAGE
            )
        rospy.Subscriber(
            "~joint_trajectory", JointTrajectoryMsg, self._on_trajectory, queue_size=EVERY_MESSAGE
        )
        self._setpoint_receipts = rospy.Publisher(
            "~setpoint_received", Header, queue_size=_RECEIPT_QUEUE
        )
        self._trajectory_receipts = rospy.Publisher(
            "~trajectory_received", Header, queue_size=_RECEIPT_QUEUE
        )

    def _on_setpoint(self, joint: str, msg: Float64) -> None:
        def receipt(start: float | None) -> None:  # on the simulation thread
            _send(self._setpoint_receipts, joint, start)

        self.runner.command_setpoint(joint, msg.data, _warn, receipt)

    def _on_trajectory(self, msg: JointTrajectoryMsg) -> None:
        def receipt(start: float | None) -> None:  # before any later pause/resume/step
            _send(self._trajectory_receipts, msg.header.frame_id, start)

        try:
            request = conversions.TrajectoryRequest.from_msg(msg)
        except CommandError as error:
            rospy.logerr(f"sim: trajectory ignored: {error}")
            return receipt(None)
        self.runner.command_trajectory(request.build, _warn, receipt)


def _send(publisher: rospy.Publisher, token: str, start: float | None) -> None:
    """A receipt: ``token`` and the sim time ``start`` (s) it holds from, or refused (the
    prefix the receipts' reader, :mod:`ow_runtime.clock_client`, looks for)."""
    if start is None:
        token, start = REFUSED + token, 0.0
    stamp = rospy.Time(*conversions.stamp_parts(start))
    publisher.publish(Header(stamp=stamp, frame_id=token))


def _warn(text: str) -> None:
    """A warning, repeated at most once a second (a topic can repeat a command at any rate)."""
    rospy.logwarn_throttle_identical(1.0, f"sim: {text}")
