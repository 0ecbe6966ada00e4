"""``rosrun ow_lander arm_services``: the paper's arm operation services (rospy wiring only).

ROS API
    Services (ow_msgs): ``/arm/unstow`` (Unstow), ``/arm/stow`` (Stow), ``/arm/guarded_move``
        (GuardedMove), ``/arm/grind`` (Grind), ``/arm/dig_circular`` (DigCircular),
        ``/arm/dig_linear`` (DigLinear), ``/arm/deliver_sample`` (DeliverSample),
        ``/arm/publish_trajectory`` (PublishTrajectory).
    Subscribes: ``/joint_states`` (sensor_msgs/JointState, by joint name): the start of every
        plan and the execution monitor; ``/sim/terrain`` (ow_msgs/HeightMap, latched): the
        terrain checked against; ``/tf``, ``/tf_static``: the scoop tip for ground detection;
        ``/arm_end_effector_force_torque`` (geometry_msgs/WrenchStamped): the wrist force for
        the force ground detector (``execution/ground_detector: force``).
    Publishes: ``/arm/operation`` (ow_msgs/Operation, START and END of every call, effective
        parameters as JSON); ``/sim/joint_trajectory`` (trajectory_msgs/JointTrajectory, the
        default execution interface) or ``/<joint>_position_controller/command``
        (std_msgs/Float64, rad; ``execution/interface: position_controllers``) for the six arm
        joints; ``/guarded_move_result`` (ow_msgs/GuardedMoveResult) once per guarded descent.
    Parameters (private, read once, see config/arm_services.yaml): ``trajectory_dir``,
        ``plan_and_execute``, ``fallback_ground_z`` (m), ``planner/*``, ``timing/*``,
        ``execution/*``.

Busy policy: one operation at a time. A request arriving while another is planning or executing
is refused with ``success: false`` and a message starting with "busy"; it is not queued.
"""

from __future__ import annotations

import json
import os
import sys
import threading
import time
from collections import deque
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import rospy
import tf2_ros
from geometry_msgs.msg import Point, WrenchStamped
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64
from std_srvs.srv import Trigger
from tf2_msgs.msg import TFMessage
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from ow_lander.config import ArmServicesConfig, ExecutionConfig
from ow_lander.conversions import height_map_from_msg, joint_positions, jsonable, request_to_dict
from ow_lander.description import ALL_JOINTS, ARM_JOINTS, BASE_FRAME, SCOOP_TIP_FRAME
from ow_lander.errors import ConfigError, OwLanderError, PlanningError, TrajectoryError
from ow_lander.ground_detection import ForceDetector, GroundDetector
from ow_lander.model import LanderModel
from ow_lander.operations import Operations
from ow_lander.planning import ArmPlanner
from ow_lander.terrain import HeightMap
from ow_lander.trajectory import Trajectory, TrajectoryStore, read_csv
from ow_msgs.msg import GuardedMoveResult, Operation
from ow_msgs.msg import HeightMap as HeightMapMsg
from ow_msgs.srv import (
    DeliverSample,
    DeliverSampleResponse,
    DigCircular,
    DigCircularResponse,
    DigLinear,
    DigLinearResponse,
    Grind,
    GrindResponse,
    GuardedMove,
    GuardedMoveResponse,
    PublishTrajectory,
    PublishTrajectoryResponse,
    Stow,
    StowResponse,
    Unstow,
    UnstowResponse,
)


def command_topic(joint: str) -> str:
    """The position-controller command topic of ``joint`` (OceanWATERS names)."""
    short = joint.removeprefix("j_")
    if short == "grinder":
        short = "grinder_yaw"
    return f"/{short}_position_controller/command"


class ExecutionResult:
    """Outcome of streaming a trajectory."""

    def __init__(self, success: bool, message: str, duration: float = 0.0) -> None:
        self.success = success
        self.message = message
        self.duration = duration
        self.ground_found = False
        self.ground_position = np.zeros(3)


class GuardWatch:
    """The ground detector armed for one guarded descent, fed from tf on simulation time.

    Attributes:
        start: s (sim), first time of the descent (after the settle pause).
        end: s (sim), last time of the descent.
        kind: "velocity" (the paper's detector) or "force" (the wrist force/torque sensor).
        detector: the paper's detector.
        force_detector: the force detector.
        contact_time: s (sim) of the sample at which contact was declared, or None.
        joints: recent (stamp s, joint positions by name) of the descent, to hold the arm where
            it was at contact rather than where the running simulation has pushed it since.
    """

    def __init__(self, start: float, end: float, config: ExecutionConfig) -> None:
        self.start = start
        self.end = end
        self.kind = config.ground_detector
        self.detector = GroundDetector(relative_tolerance=config.ground_relative_tolerance)
        self.force_detector = ForceDetector(config.ground_force_threshold_n)
        self.contact_time: float | None = None
        self.joints: deque[tuple[float, dict[str, float]]] = deque(maxlen=500)

    @property
    def contact(self) -> np.ndarray | None:
        """m, scoop tip (base_link) where the chosen detector declared contact, or None."""
        detector = self.detector if self.kind == "velocity" else self.force_detector
        return detector.contact

    def joints_at_contact(self) -> dict[str, float] | None:
        """Joint positions of the last /joint_states at or before the contact, or None."""
        if self.contact_time is None:
            return None
        before = [values for stamp, values in self.joints if stamp <= self.contact_time]
        return before[-1] if before else None


class ArmServicesNode:
    """The arm services: plan from the current joint state, write trajectories, execute them."""

    def __init__(self, config: ArmServicesConfig) -> None:
        self.config = config
        self.model = LanderModel()
        self.planner = ArmPlanner(self.model, config.planner)
        self.operations = Operations(self.planner)
        directory = config.trajectory_dir or os.path.join(
            os.environ.get("ROS_HOME", os.path.expanduser("~/.ros")), "trajectories"
        )
        self.store = TrajectoryStore(Path(directory))
        self._busy = threading.Lock()
        self._state_lock = threading.Lock()
        self._state_changed = threading.Condition(self._state_lock)
        self._joints: dict[str, float] = {}
        self._joint_stamp = 0.0
        self._tf = tf2_ros.BufferCore(rospy.Duration(30.0))
        self._guard: GuardWatch | None = None
        self._sim_clock_services: bool | None = None
        self._terrain: HeightMap | None = None
        self._fallback = HeightMap.flat(config.fallback_ground_z)
        self._operation_id = 0
        self.operation_pub = rospy.Publisher("/arm/operation", Operation, queue_size=20)
        self.result_pub = rospy.Publisher(
            "/guarded_move_result", GuardedMoveResult, queue_size=10, latch=True
        )
        self.command_pubs = {
            j: rospy.Publisher(command_topic(j), Float64, queue_size=10) for j in ARM_JOINTS
        }
        self.trajectory_pub = rospy.Publisher(
            "/sim/joint_trajectory", JointTrajectory, queue_size=10
        )
        rospy.Subscriber("/joint_states", JointState, self._on_joint_states, queue_size=100)
        rospy.Subscriber("/tf", TFMessage, self._on_tf, queue_size=100)
        rospy.Subscriber("/tf_static", TFMessage, self._on_tf, callback_args=True, queue_size=10)
        rospy.Subscriber("/sim/terrain", HeightMapMsg, self._on_terrain, queue_size=1)
        rospy.Subscriber(
            "/arm_end_effector_force_torque", WrenchStamped, self._on_wrist_wrench, queue_size=50
        )
        services: list[tuple[str, Any, Callable[[Any], Any]]] = [
            ("unstow", Unstow, self._plan_service("unstow", UnstowResponse)),
            ("stow", Stow, self._plan_service("stow", StowResponse)),
            ("guarded_move", GuardedMove, self._plan_service("guarded_move", GuardedMoveResponse)),
            ("grind", Grind, self._plan_service("grind", GrindResponse)),
            ("dig_circular", DigCircular, self._plan_service("dig_circular", DigCircularResponse)),
            ("dig_linear", DigLinear, self._plan_service("dig_linear", DigLinearResponse)),
            (
                "deliver_sample",
                DeliverSample,
                self._plan_service("deliver_sample", DeliverSampleResponse),
            ),
            ("publish_trajectory", PublishTrajectory, self._publish_trajectory),
        ]
        self.services = [rospy.Service(f"/arm/{n}", cls, h) for n, cls, h in services]
        rospy.loginfo("arm_services: trajectories in %s", self.store.directory)

    # ------------------------------------------------------------------------- callbacks
    def _on_joint_states(self, msg: JointState) -> None:
        values = joint_positions(list(msg.name), msg.position)
        with self._state_changed:
            self._joints.update(values)
            self._joint_stamp = msg.header.stamp.to_sec()
            guard = self._guard
            if guard is not None and (
                guard.contact_time is None or self._joint_stamp <= guard.contact_time
            ):
                guard.joints.append((self._joint_stamp, dict(self._joints)))
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
        guard = self._guard
        if guard is None or guard.contact_time is not None or guard.kind != "velocity":
            return
        for stamp in sorted(stamps):
            t = stamp.to_sec()
            if not guard.start <= t <= guard.end:
                continue
            try:
                tip = self._tf.lookup_transform_core(BASE_FRAME, SCOOP_TIP_FRAME, stamp)
            except tf2_ros.TransformException:
                continue  # not every link's transform of this stamp has arrived yet
            p = tip.transform.translation
            if guard.detector.update(t, np.array([p.x, p.y, p.z])):
                guard.contact_time = t
                with self._state_changed:
                    self._state_changed.notify_all()
                return

    def _on_terrain(self, msg: HeightMapMsg) -> None:
        try:
            terrain = height_map_from_msg(msg)
        except OwLanderError as error:
            rospy.logerr("arm_services: ignoring /sim/terrain: %s", error)
            return
        with self._state_changed:
            self._terrain = terrain
            self._state_changed.notify_all()

    def _current_q(self) -> np.ndarray:
        """(9,) rad, the latest joint state; waits for the first one."""
        deadline = time.monotonic() + self.config.execution.joint_state_timeout_s
        while not rospy.is_shutdown():
            with self._state_lock:
                missing = [j for j in ARM_JOINTS if j not in self._joints]
                if not missing:
                    values = {j: v for j, v in self._joints.items() if j in ALL_JOINTS}
                    return self.model.q_from(values)
            if time.monotonic() > deadline:
                msg = f"no /joint_states with the arm joints ({', '.join(missing)}) received"
                raise PlanningError(msg)
            time.sleep(0.01)
        msg = "shutting down"
        raise PlanningError(msg)

    def _current_terrain(self) -> tuple[HeightMap, str]:
        """The latest /sim/terrain; right after start-up the latched message may still be on its
        way, so wait up to ``terrain_wait_s`` for it before planning against the fallback."""
        with self._state_changed:
            self._state_changed.wait_for(
                lambda: self._terrain is not None, timeout=self.config.terrain_wait_s
            )
            terrain = self._terrain
        if terrain is None:
            note = (
                f"no /sim/terrain received: planned against flat ground at "
                f"z={self.config.fallback_ground_z} m"
            )
            return self._fallback, note
        return terrain, ""

    # ----------------------------------------------------------------------- operations
    def _publish_marker(
        self, op_id: int, name: str, event: int, parameters: dict[str, Any], **end: Any
    ) -> None:
        msg = Operation()
        msg.header.stamp = rospy.Time.now()
        msg.header.frame_id = BASE_FRAME
        msg.id = op_id
        msg.name = name
        msg.event = event
        msg.parameters = json.dumps(jsonable(parameters), sort_keys=True)
        msg.success = bool(end.get("success", False))
        msg.message = str(end.get("message", ""))
        msg.trajectory_file = str(end.get("trajectory_file", ""))
        self.operation_pub.publish(msg)

    def _plan_service(self, name: str, response_cls: Any) -> Callable[[Any], Any]:
        def handler(request: Any) -> Any:
            return self._run_operation(name, request, response_cls)

        return handler

    def _run_operation(self, name: str, request: Any, response_cls: Any) -> Any:
        response = response_cls()
        req = request_to_dict(request)
        if not self._busy.acquire(blocking=False):
            response.success = False
            response.message = "busy: another arm operation is running; request refused"
            return response
        self._operation_id += 1
        op_id = self._operation_id
        try:
            self._publish_marker(op_id, name, Operation.START, req)
            parameters = dict(req)
            try:
                self._operate(name, req, response, parameters)
            except (OwLanderError, ValueError) as error:
                response.success = False
                response.message = f"{name} failed: {error}"
            except Exception as error:
                rospy.logerr("arm_services: %s crashed: %r", name, error)
                response.success = False
                response.message = f"{name} failed with an internal error: {error!r}"
            self._publish_marker(
                op_id,
                name,
                Operation.END,
                parameters,
                success=response.success,
                message=response.message,
                trajectory_file=response.trajectory_file,
            )
            return response
        finally:
            self._busy.release()

    def _operate(
        self, name: str, req: dict[str, Any], response: Any, parameters: dict[str, Any]
    ) -> None:
        notes = []
        if req.get("delete_prev_traj"):
            notes.append(f"deleted {self.store.delete_written()} previous trajectory files")
        q = self._current_q()
        terrain, terrain_note = self._current_terrain()
        if terrain_note:
            notes.append(terrain_note)
        started = time.perf_counter()
        plan = self.operations.plan(name, q, terrain, req)
        notes.extend(plan.notes)
        trajectory = plan.timed(self.config.timing, self.planner.velocity_limits)
        response.planning_time = time.perf_counter() - started
        parameters.update(plan.parameters)
        path = self.store.save(trajectory)
        response.trajectory_file = str(path)
        response.duration = trajectory.duration
        response.success = True
        message = f"planned {name}: {trajectory.duration:.1f} s, written to {path.name}"
        if self.config.plan_and_execute:
            result = self._execute(trajectory)
            response.success = result.success
            message += f"; executed: {result.message}"
            if hasattr(response, "ground_found"):
                response.ground_found = result.ground_found
                response.ground_position = Point(*result.ground_position)
        response.message = "; ".join([message, *notes])

    # ------------------------------------------------------------------------- execution
    def _publish_trajectory(self, request: Any) -> Any:
        response = PublishTrajectoryResponse()
        if not self._busy.acquire(blocking=False):
            response.success = False
            response.message = "busy: another arm operation is running; request refused"
            return response
        self._operation_id += 1
        op_id = self._operation_id
        req = request_to_dict(request)
        try:
            self._publish_marker(op_id, "publish_trajectory", Operation.START, req)
            try:
                path = (
                    self.store.latest()
                    if request.use_latest
                    else self.store.resolve(request.trajectory_filename)
                )
                result = self._execute(read_csv(path))
                response.success = result.success
                response.message = result.message
                response.duration = result.duration
                response.ground_found = result.ground_found
                response.ground_position = Point(*result.ground_position)
            except TrajectoryError as error:
                response.success = False
                response.message = str(error)
            except Exception as error:
                rospy.logerr("arm_services: publish_trajectory crashed: %r", error)
                response.success = False
                response.message = f"publish_trajectory failed with an internal error: {error!r}"
            self._publish_marker(
                op_id,
                "publish_trajectory",
                Operation.END,
                req,
                success=response.success,
                message=response.message,
            )
            return response
        finally:
            self._busy.release()

    def _on_wrist_wrench(self, msg: WrenchStamped) -> None:
        """During a guarded descent with the force detector, watch the wrist force."""
        guard = self._guard
        if guard is None or guard.contact_time is not None or guard.kind != "force":
            return
        t = msg.header.stamp.to_sec()
        if not guard.start <= t <= guard.end:
            return
        f = msg.wrench.force
        # The tip position at contact is filled in from the joint states of that stamp (see
        # _monitor); tf at 30 Hz may lag the 50 Hz wrench by more than the tolerance.
        if guard.force_detector.update(np.array([f.x, f.y, f.z])):
            guard.contact_time = t
            with self._state_changed:
                self._state_changed.notify_all()

    def _execute(self, trajectory: Trajectory) -> ExecutionResult:
        """Execute ``trajectory`` on the simulation and watch it on simulation time.

        The arm must start within ``max_tracking_error_rad`` of the first row. A guarded
        segment is preceded by a ``guarded_settle_s`` hold, and the ground detector runs on the
        scoop tip from tf during the descent; on contact the arm holds where it is.
        """
        cfg = self.config.execution
        unknown = [j for j in trajectory.joints if j not in self.command_pubs]
        if unknown:
            return ExecutionResult(
                False, f"trajectory names joints without a controller: {unknown}"
            )
        q0 = self._current_q()
        idx = [self.model.index(j) for j in trajectory.joints]
        start_error = float(np.max(np.abs(q0[idx] - trajectory.positions[0])))
        if start_error > cfg.max_tracking_error_rad:
            return ExecutionResult(
                False,
                f"the arm is {start_error:.3f} rad from the trajectory's first row "
                f"(limit {cfg.max_tracking_error_rad} rad); plan again from the current state",
            )
        guarded = trajectory.segment_span("guarded")
        if guarded is not None and cfg.guarded_settle_s > 0:
            trajectory = trajectory.with_pause(guarded[0], cfg.guarded_settle_s)
            guarded = (guarded[0] + cfg.guarded_settle_s, guarded[1] + cfg.guarded_settle_s)
        # The detector watches the *steady* descent (the paper): samples of the acceleration
        # ramp would set its threshold so close to zero velocity that ground which gives a
        # little is never detected, and the braking ramp at the end would look like contact.
        steady = trajectory.steady_span("guarded")
        if cfg.interface == "trajectory":
            t_start = self._send_trajectory(trajectory)
        else:
            with self._state_lock:
                t_start = self._joint_stamp + cfg.start_delay_s
        if guarded is not None and steady is not None:
            self._guard = GuardWatch(t_start + steady[0], t_start + steady[1], cfg)
        try:
            result = self._monitor(trajectory, idx, t_start)
        finally:
            guard, self._guard = self._guard, None
        if guarded is not None and result.success:
            result = self._guarded_result(trajectory, guarded, guard, result)
        return result

    def _monitor(self, trajectory: Trajectory, idx: list[int], t_start: float) -> ExecutionResult:
        """Follow the execution on each /joint_states message until it ends one way or another."""
        cfg = self.config.execution
        limit = trajectory.duration * cfg.timeout_factor + cfg.settle_timeout_s
        next_command = t_start
        last_stamp = -1.0
        while not rospy.is_shutdown():

            def news(last: float = last_stamp) -> bool:
                guard = self._guard
                contact = guard is not None and guard.contact_time is not None
                return self._joint_stamp != last or contact

            with self._state_changed:
                arrived = self._state_changed.wait_for(news, timeout=cfg.joint_state_timeout_s)
                stamp = self._joint_stamp
                values = {j: v for j, v in self._joints.items() if j in ALL_JOINTS}
            if not arrived:
                self._hold(None)
                return ExecutionResult(
                    False,
                    f"no /joint_states for {cfg.joint_state_timeout_s} s of wall time: "
                    "is the simulation running?",
                )
            last_stamp = stamp
            q = self.model.q_from(values)
            t = stamp - t_start
            guard = self._guard
            if guard is not None and guard.contact_time is not None:
                # The simulation may have run on for a while (it runs many times faster than
                # real time): go back to where the arm was at contact, not further into the
                # ground it yields.
                contact_time = guard.contact_time

                def caught_up(until: float = contact_time) -> bool:
                    return self._joint_stamp >= until

                with self._state_changed:  # the joint states up to the contact
                    self._state_changed.wait_for(caught_up, timeout=1.0)
                at_contact = guard.joints_at_contact()
                if at_contact is not None:
                    q_contact = self.model.q_from(at_contact)
                    if guard.kind == "force":
                        # Where the tip was at the force reading's stamp (tf may lag it).
                        guard.force_detector.contact = self.model.position(
                            q_contact, SCOOP_TIP_FRAME
                        )
                    self._hold(q_contact[idx])
                else:
                    self._hold(q[idx])
                return ExecutionResult(True, "ground found", t)
            if cfg.interface == "position_controllers" and stamp >= next_command:
                setpoint = trajectory.sample(max(t + 1.0 / cfg.command_rate_hz, 0.0))
                for joint, value in zip(trajectory.joints, setpoint, strict=True):
                    self.command_pubs[joint].publish(Float64(float(value)))
                next_command = stamp + 1.0 / cfg.command_rate_hz
            if t < 0.0:
                continue
            error = np.abs(q[idx] - trajectory.sample(t))
            worst = int(np.argmax(error))
            if error[worst] > cfg.max_tracking_error_rad:
                self._hold(q[idx])
                return ExecutionResult(
                    False,
                    f"tracking error: {trajectory.joints[worst]} is {error[worst]:.3f} rad from "
                    f"its set-point at t={t:.1f} s (limit {cfg.max_tracking_error_rad} rad); "
                    "the arm holds where it is",
                    t,
                )
            if t >= trajectory.duration and error[worst] <= cfg.goal_tolerance_rad:
                return ExecutionResult(True, "reached the final set-point", t)
            if t > limit:
                self._hold(q[idx])
                return ExecutionResult(
                    False,
                    f"timeout: final set-point not reached within {limit:.1f} s "
                    f"(worst joint {trajectory.joints[worst]} {error[worst]:.3f} rad away)",
                    t,
                )
        return ExecutionResult(False, "shutting down")

    def _guarded_result(
        self,
        trajectory: Trajectory,
        guarded: tuple[float, float],
        guard: GuardWatch | None,
        result: ExecutionResult,
    ) -> ExecutionResult:
        """Turn a finished guarded execution into found / not found, and publish it once."""
        if guard is not None and guard.contact_time is not None and guard.contact is not None:
            result.ground_found = True
            result.ground_position = guard.contact
            result.message = (
                f"ground found at z={result.ground_position[2]:.4f} m "
                f"(t={guard.contact_time:.2f} s sim)"
            )
            self._publish_ground(True, result.ground_position, guard.contact_time)
            return result
        base = self._current_q()
        ends = [
            self.model.position(
                self.model.q_from(dict(zip(trajectory.joints, row, strict=True)), base),
                SCOOP_TIP_FRAME,
            )
            for row in (trajectory.sample(guarded[0]), trajectory.sample(guarded[1]))
        ]
        searched = float(np.linalg.norm(ends[1] - ends[0]))
        self._publish_ground(False, np.zeros(3))
        return ExecutionResult(
            False, f"no ground within {searched:.2f} m of the start of the descent", result.duration
        )

    def _send_trajectory(self, trajectory: Trajectory) -> float:
        """Hand ``trajectory`` to the simulation to start ``start_delay_s`` from now (sim time);
        return that start time.

        A simulation running many times faster than real time could pass the start time before
        the message arrives, so its clock is paused while the message is delivered (when it
        offers ``/sim/pause`` and ``/sim/resume``)."""
        cfg = self.config.execution
        paused = self._sim_clock("pause")
        try:
            if paused:
                self._wait_quiet(cfg.delivery_wait_s)
            with self._state_lock:
                t_start = self._joint_stamp + cfg.start_delay_s
            self.trajectory_pub.publish(self._trajectory_msg(trajectory, t_start))
            if paused:
                time.sleep(cfg.delivery_wait_s)
        finally:
            if paused:
                self._sim_clock("resume")
        return t_start

    def _wait_quiet(self, quiet_s: float, limit_s: float = 1.0) -> None:
        """Wait until no new /joint_states has arrived for ``quiet_s`` (wall): the newest one then
        carries the paused simulation's time."""
        deadline = time.monotonic() + limit_s
        with self._state_changed:
            while time.monotonic() < deadline:
                stamp = self._joint_stamp
                self._state_changed.wait(timeout=quiet_s)
                if self._joint_stamp == stamp:
                    return

    def _sim_clock(self, action: str) -> bool:
        """Call ``/sim/<action>`` (pause or resume); False when the simulation has none.

        Whether it has them is looked up once (a simulator without them is used without)."""
        if self._sim_clock_services is None:
            try:
                for name in ("/sim/pause", "/sim/resume"):
                    rospy.wait_for_service(name, timeout=self.config.execution.service_wait_s)
                self._sim_clock_services = True
            except rospy.ROSException:
                rospy.logwarn("arm_services: no /sim/pause: trajectories start after a delay only")
                self._sim_clock_services = False
        if not self._sim_clock_services:
            return False
        try:
            return bool(rospy.ServiceProxy(f"/sim/{action}", Trigger)().success)
        except rospy.ServiceException as error:
            rospy.logwarn("arm_services: /sim/%s failed: %s", action, error)
            return False

    def _trajectory_msg(self, trajectory: Trajectory, t_start: float) -> JointTrajectory:
        msg = JointTrajectory()
        msg.header.stamp = rospy.Time.from_sec(t_start)
        msg.joint_names = list(trajectory.joints)
        for t, position, velocity in zip(
            trajectory.times, trajectory.positions, trajectory.velocities, strict=True
        ):
            point = JointTrajectoryPoint()
            point.positions = position.tolist()
            point.velocities = velocity.tolist()
            point.time_from_start = rospy.Duration.from_sec(float(t))
            msg.points.append(point)
        return msg

    def _hold(self, positions: np.ndarray | None) -> None:
        """Stop the arm: hold ``positions`` (rad, arm joints), or where it is when None."""
        if positions is None:
            positions = self.planner.arm(self._current_q())
        for joint, value in zip(ARM_JOINTS, positions, strict=True):
            self.command_pubs[joint].publish(Float64(float(value)))

    def _publish_ground(
        self, found: bool, position: np.ndarray, contact_time: float | None = None
    ) -> None:
        """Publish the result once; stamped with the contact's sim time (now when not found)."""
        msg = GuardedMoveResult()
        msg.header.stamp = rospy.Time.now() if contact_time is None else rospy.Time(contact_time)
        msg.header.frame_id = BASE_FRAME
        msg.success = found
        msg.position = Point(*map(float, position))
        msg.frame = BASE_FRAME
        self.result_pub.publish(msg)


def main() -> None:
    """Entry point of ``rosrun ow_lander arm_services``."""
    rospy.init_node("arm_services")
    try:
        config = ArmServicesConfig.from_dict(rospy.get_param("~", {}))
        ArmServicesNode(config)
    except (ConfigError, TrajectoryError) as error:
        rospy.logfatal("arm_services: %s", error)
        sys.exit(1)
    rospy.spin()
