"""ROS wiring of OceanWATERS' joint telemetry (see :mod:`ow_lander.telemetry.joints`)."""

from __future__ import annotations

import sys
import time
import warnings

import rospy
import rospy.impl.simtime
from geometry_msgs.msg import Point, Pose, Quaternion
from sensor_msgs.msg import JointState
from std_msgs.msg import Header

from ow_lander.errors import ConfigError
from ow_lander.telemetry.config import TelemetryConfig
from ow_lander.telemetry.joints import (
    ARM_POSE_FRAME,
    RateGate,
    TelemetryBuilder,
    TelemetryError,
)
from ow_runtime.names import (
    ARM_JOINT_ACCELERATIONS,
    ARM_JOINT_POSITIONS,
    ARM_JOINT_TORQUES,
    ARM_JOINT_VELOCITIES,
    ARM_POSE,
    JOINT_STATES,
    PAN_TILT_POSITION,
)
from ow_runtime.node import init_node, quiet_at_shutdown, spin
from owl_msgs.msg import (
    ArmJointAccelerations,
    ArmJointPositions,
    ArmJointTorques,
    ArmJointVelocities,
    ArmPose,
    PanTiltPosition,
)

#: Joint states the subscriber holds: the simulation writes several per socket write (4 when
#: running fast, a whole ~step request's when stepped), and rospy drops the oldest of one read
#: beyond the queue size.
JOINT_STATE_QUEUE = 1000
#: Publishers write in the callback (queue_size None), as the simulation does: no message is
#: dropped for a subscriber that lags, which slows this node (and through /joint_states the
#: simulation) instead. A queue hands each message to a writer thread per connection, which
#: cost twice the CPU per joint state (634 vs 282 us with /clock, docs/telemetry.md).
PUBLISH_QUEUE = None


class TelemetryNode:
    """The ``telemetry`` node: OceanWATERS' joint telemetry, one message of each topic for every
    ``/joint_states`` message (or at ``~rate_hz`` of simulation time), stamped with its stamp
    (owl_msgs; orders in docs/telemetry.md).

    Subscriptions:
        /joint_states (sensor_msgs/JointState): read by joint name; every lander joint needed.

    Publications:
        /arm_joint_positions (owl_msgs/ArmJointPositions): float64[7] rad.
        /arm_joint_velocities (owl_msgs/ArmJointVelocities): float64[7] rad/s.
        /arm_joint_accelerations (owl_msgs/ArmJointAccelerations): float64[7] rad/s^2, finite
            difference of the velocities between consecutive joint states.
        /arm_joint_torques (owl_msgs/ArmJointTorques): float64[7] N m, the joint efforts.
            (The four arrays in the order j_dist_pitch, j_grinder, j_hand_yaw, j_prox_pitch,
            j_scoop_yaw, j_shou_pitch, j_shou_yaw; frame_id empty.)
        /pan_tilt_position (owl_msgs/PanTiltPosition): float64[2] rad, j_ant_pan, j_ant_tilt.
        /arm_pose (owl_msgs/ArmPose): pose of l_scoop in base_link (m, unit quaternion),
            frame_id base_link.

    Parameters: ``~rate_hz`` (Hz of sim time, 0 = every joint state; config/telemetry.yaml,
    :class:`~ow_lander.telemetry.config.TelemetryConfig`). No clock (it does not subscribe to
    /clock).
    At shutdown the node logs the process CPU time it used per joint state.
    """

    def __init__(self, config: TelemetryConfig) -> None:
        self.builder = TelemetryBuilder()
        self.gate = RateGate(config.rate_hz)
        self.count = 0
        #: s of CPU time spent in the callback (building, serialising, publishing).
        self.callback_cpu = 0.0
        self._cpu_start: float | None = None

        def publisher(topic: str, cls: type) -> rospy.Publisher:
            with warnings.catch_warnings():  # rospy warns of queue_size None
                warnings.simplefilter("ignore", SyntaxWarning)
                return rospy.Publisher(topic, cls, queue_size=PUBLISH_QUEUE, tcp_nodelay=True)

        self._positions = publisher(ARM_JOINT_POSITIONS, ArmJointPositions)
        self._velocities = publisher(ARM_JOINT_VELOCITIES, ArmJointVelocities)
        self._accelerations = publisher(ARM_JOINT_ACCELERATIONS, ArmJointAccelerations)
        self._torques = publisher(ARM_JOINT_TORQUES, ArmJointTorques)
        self._pan_tilt = publisher(PAN_TILT_POSITION, PanTiltPosition)
        self._pose = publisher(ARM_POSE, ArmPose)
        rospy.Subscriber(
            JOINT_STATES,
            JointState,
            self._on_joint_state,
            queue_size=JOINT_STATE_QUEUE,
            tcp_nodelay=True,
        )

    @quiet_at_shutdown
    def _on_joint_state(self, msg: JointState) -> None:
        start = time.thread_time()
        if self._cpu_start is None:
            self._cpu_start = time.process_time()
        stamp = msg.header.stamp
        stamp_s = stamp.to_sec()
        # The kinematics only for the states published (every state counts for accelerations).
        due = self.gate.due(stamp_s)
        try:
            if not due:
                self.builder.skip(stamp_s, msg.name, msg.position, msg.velocity, msg.effort)
                return
            t = self.builder.update(stamp_s, msg.name, msg.position, msg.velocity, msg.effort)
        except TelemetryError as error:
            # Without a clock rospy's time stands still: each distinct message is logged once.
            rospy.logwarn_throttle_identical(5.0, f"telemetry: joint state skipped: {error}")
            return
        if not self.gate.passes(stamp_s):
            return
        header = Header(stamp=stamp)
        self._positions.publish(ArmJointPositions(header, t.positions))
        self._velocities.publish(ArmJointVelocities(header, t.velocities))
        self._accelerations.publish(ArmJointAccelerations(header, t.accelerations))
        self._torques.publish(ArmJointTorques(header, t.torques))
        self._pan_tilt.publish(PanTiltPosition(header, t.pan_tilt))
        x, y, z = t.scoop_position
        qx, qy, qz, qw = t.scoop_orientation
        pose = Pose(Point(x, y, z), Quaternion(qx, qy, qz, qw))
        self._pose.publish(ArmPose(Header(stamp=stamp, frame_id=ARM_POSE_FRAME), pose))
        self.count += 1
        self.callback_cpu += time.thread_time() - start

    def cpu_per_message_us(self) -> float:
        """us of process CPU time per joint state since the first one (all threads: receiving,
        building, serialising, writing)."""
        if self._cpu_start is None or self.count == 0:
            return 0.0
        return (time.process_time() - self._cpu_start) / self.count * 1e6


def main() -> None:
    """Entry point of ``rosrun ow_lander telemetry``."""
    init_node("telemetry")
    # Every message is stamped with its joint state's stamp: this node needs no clock, and with
    # /use_sim_time rospy would receive /clock (as often as /joint_states) for nothing.
    clock = getattr(rospy.impl.simtime, "_clock_sub", None)
    if clock is not None:
        clock.unregister()
    try:
        config = TelemetryConfig.from_dict(rospy.get_param("~", {}))
    except ConfigError as error:
        rospy.logfatal(f"telemetry: {error}")
        sys.exit(1)
    node = TelemetryNode(config)

    def report() -> None:
        rospy.loginfo(
            "telemetry: %d joint states, %.0f us of process CPU each (%.0f us in the callback)",
            node.count,
            node.cpu_per_message_us(),
            node.callback_cpu / max(node.count, 1) * 1e6,
        )

    rospy.on_shutdown(report)
    rospy.loginfo("telemetry: publishing OceanWATERS' joint telemetry from /joint_states")
    spin()
