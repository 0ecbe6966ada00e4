"""The execution side of ``arm_services`` (rospy wiring only; a node module of the arm_services
node): trajectories go to the simulation, its observations to an
:class:`~ow_lander.execution.ExecutionMonitor`, whose decisions are published."""

from __future__ import annotations

import threading
import time

import numpy as np
import rospy
import tf2_ros
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64
from tf2_msgs.msg import TFMessage
from trajectory_msgs.msg import JointTrajectory

from ow_lander import conversions as conv
from ow_lander.config import ExecutionConfig
from ow_lander.description import ALL_JOINTS, ARM_JOINTS, BASE_FRAME, SCOOP_TIP_FRAME
from ow_lander.errors import PlanningError
from ow_lander.execution import (
    Decision,
    ExecutionMonitor,
    ExecutionResult,
    start_error,
    unknown_joints,
    with_settle_pause,
)
from ow_lander.model import LanderModel
from ow_lander.sim_clock_node import SimClock
from ow_lander.trajectory import Trajectory
from ow_msgs.msg import GuardedMoveResult
from owl_msgs.msg import ArmEndEffectorForceTorque


class ArmExecutor:
    """Executes trajectories on the simulation, watched on simulation time.

    Subscribes: ``/joint_states`` (sensor_msgs/JointState, by joint name); ``/tf``,
        ``/tf_static``: the scoop tip for the velocity ground detector;
        ``/arm_end_effector_force_torque`` (owl_msgs/ArmEndEffectorForceTorque, N): the wrist
        force for the force ground detector.
    Publishes: ``/sim/joint_trajectory`` (trajectory_msgs/JointTrajectory, interface
        ``trajectory``) or ``/<joint>_position_controller/command`` (std_msgs/Float64, rad;
        interface ``position_controllers``, and every hold) for the six arm joints;
        ``/guarded_move_result`` (ow_msgs/GuardedMoveResult, latched) once per guarded descent.
    Calls: ``/sim/pause``, ``/sim/resume`` (std_srvs/Trigger) around delivering a trajectory.

    Args:
        config: the ``execution/*`` parameters.
        model: the lander, for the monitor's forward kinematics.
    """

    def __init__(self, config: ExecutionConfig, model: LanderModel) -> None:
        self.config = config
        self.model = model
        self._state_changed = threading.Condition(threading.Lock())
        self._joints: dict[str, float] = {}
        self._joint_stamp = 0.0
        self._tf = tf2_ros.BufferCore(rospy.Duration(30.0))
        self._monitor: ExecutionMonitor | None = None
        self._sim_clock = SimClock(config.service_wait_s)
        self.result_pub = rospy.Publisher(
            "/guarded_move_result", GuardedMoveResult, queue_size=10, latch=True
        )
        self.command_pubs = {
            j: rospy.Publisher(conv.command_topic(j), Float64, queue_size=10) for j in ARM_JOINTS
        }
        self.trajectory_pub = rospy.Publisher(
            "/sim/joint_trajectory", JointTrajectory, queue_size=10
        )
        rospy.Subscriber("/joint_states", JointState, self._on_joint_states, queue_size=100)
        rospy.Subscriber("/tf", TFMessage, self._on_tf, queue_size=100)
        rospy.Subscriber("/tf_static", TFMessage, self._on_tf, callback_args=True, queue_size=10)
        rospy.Subscriber(
            "/arm_end_effector_force_torque",
            ArmEndEffectorForceTorque,
            self._on_wrist,
            queue_size=50,
        )

    # -------------------------------------------------------------------------------- callbacks
    def _on_joint_states(self, msg: JointState) -> None:
        values = conv.joint_positions(list(msg.name), msg.position)
        with self._state_changed:
            self._joints.update(values)
            self._joint_stamp = msg.header.stamp.to_sec()
            if self._monitor is not None:
                self._monitor.record_joint_state(self._joint_stamp, self._joints)
            self._state_changed.notify_all()

    def _on_tf(self, msg: TFMessage, static: bool = False) -> None:
        """Feed tf2; during a guarded descent, sample the scoop tip at each tf stamp."""
        stamps = set()
        for transform in msg.transforms:
            if static:
                self._tf.set_transform_static(transform, "sim")
            else:
                self._tf.set_transform(transform, "sim")
                stamps.add(transform.header.stamp)
        for stamp in sorted(stamps):
            monitor = self._monitor
            if monitor is None or not monitor.wants_tip(stamp.to_sec()):
                continue
            try:
                tip = self._tf.lookup_transform_core(BASE_FRAME, SCOOP_TIP_FRAME, stamp)
            except tf2_ros.TransformException:
                continue  # not every link's transform of this stamp has arrived yet
            p = tip.transform.translation
            with self._state_changed:
                if monitor.tip_sample(stamp.to_sec(), np.array([p.x, p.y, p.z])):
                    self._state_changed.notify_all()
                    return

    def _on_wrist(self, msg: ArmEndEffectorForceTorque) -> None:
        f, t = msg.value.force, msg.header.stamp.to_sec()
        with self._state_changed:
            if self._monitor is not None and self._monitor.wrist_force(
                t, np.array([f.x, f.y, f.z])
            ):
                self._state_changed.notify_all()

    def current_joints(self) -> dict[str, float]:
        """rad by name, the latest joint state of the lander's joints; waits for the first one.

        Raises:
            PlanningError: none with every arm joint within ``joint_state_timeout_s``, or the
                node is shutting down.
        """
        deadline = time.monotonic() + self.config.joint_state_timeout_s
        while not rospy.is_shutdown():
            with self._state_changed:
                missing = [j for j in ARM_JOINTS if j not in self._joints]
                if not missing:
                    return {j: v for j, v in self._joints.items() if j in ALL_JOINTS}
            if time.monotonic() > deadline:
                msg = f"no /joint_states with the arm joints ({', '.join(missing)}) received"
                raise PlanningError(msg)
            time.sleep(0.01)
        msg = "shutting down"
        raise PlanningError(msg)

    # ------------------------------------------------------------------------------ execution
    def execute(self, trajectory: Trajectory) -> ExecutionResult:
        """Execute ``trajectory`` and watch it until it ends (see :mod:`ow_lander.execution`);
        publish a guarded descent's result once.

        Raises:
            PlanningError: no joint state to start from.
        """
        cfg = self.config
        refused = unknown_joints(trajectory) or start_error(trajectory, self.current_joints(), cfg)
        if refused is not None:
            return refused
        trajectory = with_settle_pause(trajectory, cfg)
        if cfg.interface == "trajectory":
            t_start = self._send_trajectory(trajectory)
        else:
            with self._state_changed:
                t_start = self._joint_stamp + cfg.start_delay_s
        with self._state_changed:
            monitor = ExecutionMonitor(trajectory, t_start, cfg, self.model, self._joints)
            self._monitor = monitor
        try:
            result = self._follow(monitor)
        finally:
            self._monitor = None
        if result.reports_ground:
            found = result.contact_time
            stamp = rospy.Time.now() if found is None else rospy.Time(found)
            self.result_pub.publish(conv.guarded_move_result_msg(result, stamp))
        return result

    def _follow(self, monitor: ExecutionMonitor) -> ExecutionResult:
        """Give the monitor the newest joint state whenever one arrives (or contact is
        declared) and carry out its decisions until it says the execution is over."""
        last = -1.0
        while not rospy.is_shutdown():

            def news(last: float = last) -> bool:
                return self._joint_stamp != last or monitor.contact_time is not None

            with self._state_changed:
                arrived = self._state_changed.wait_for(news, self.config.joint_state_timeout_s)
                stamp, joints = self._joint_stamp, dict(self._joints)
                contact = monitor.contact_time
            if arrived and contact is not None:
                # The simulation may have run on: the joint states up to the contact first.
                def caught_up(until: float = contact) -> bool:
                    return self._joint_stamp >= until

                with self._state_changed:
                    self._state_changed.wait_for(caught_up, timeout=1.0)
            with self._state_changed:
                decision = monitor.decide(stamp, joints) if arrived else monitor.stalled()
            last = stamp
            self._command(decision)
            if decision.result is not None:
                return decision.result
        return ExecutionResult(False, "shutting down")

    def _command(self, decision: Decision) -> None:
        """Publish a decision's set-points, then its hold."""
        for commands in (decision.setpoints, decision.hold):
            for joint, value in (commands or {}).items():
                self.command_pubs[joint].publish(Float64(value))

    def _send_trajectory(self, trajectory: Trajectory) -> float:
        """Hand ``trajectory`` to the simulation to start ``start_delay_s`` from now (sim time);
        return that start time.

        A simulation running many times faster than real time could pass the start time before
        the message arrives, so its clock is paused while the message is delivered (when it
        offers ``/sim/pause`` and ``/sim/resume``)."""
        cfg = self.config
        paused = self._sim_clock.call("pause")
        try:
            if paused:
                self._wait_quiet(cfg.delivery_wait_s)
            with self._state_changed:
                t_start = self._joint_stamp + cfg.start_delay_s
            self.trajectory_pub.publish(conv.trajectory_msg(trajectory, t_start))
            if paused:
                time.sleep(cfg.delivery_wait_s)
        finally:
            if paused:
                self._sim_clock.call("resume")
        return t_start

    def _wait_quiet(self, quiet_s: float, limit_s: float = 1.0) -> None:
        """Wait until no new /joint_states has arrived for ``quiet_s`` (wall): the newest one then
        carries the paused simulation's time."""
        deadline = time.monotonic() + limit_s
        with self._state_changed:
            stamp = None
            while time.monotonic() < deadline and stamp != self._joint_stamp:
                stamp = self._joint_stamp
                self._state_changed.wait(timeout=quiet_s)
