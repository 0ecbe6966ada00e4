"""``rosrun ow_lander arm_services``: the paper's arm operation services (rospy wiring only).

ROS API
    Services (ow_msgs): ``/arm/unstow`` (Unstow), ``/arm/stow`` (Stow), ``/arm/guarded_move``
        (GuardedMove), ``/arm/grind`` (Grind), ``/arm/dig_circular`` (DigCircular),
        ``/arm/dig_linear`` (DigLinear), ``/arm/deliver_sample`` (DeliverSample),
        ``/arm/publish_trajectory`` (PublishTrajectory).
    Subscribes: ``/joint_states`` (sensor_msgs/JointState, by joint name): the start of every
        plan; ``/sim/terrain`` (ow_msgs/HeightMap, latched): the terrain checked against.
    Publishes: ``/arm/operation`` (ow_msgs/Operation, START and END of every call, effective
        parameters as JSON); ``/<joint>_position_controller/command`` (std_msgs/Float64, rad)
        for the six arm joints while executing; ``/guarded_move_result``
        (ow_msgs/GuardedMoveResult) after a guarded descent.
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
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import rospy
from geometry_msgs.msg import Point
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64

from ow_lander.config import ArmServicesConfig
from ow_lander.conversions import height_map_from_msg, joint_positions, jsonable, request_to_dict
from ow_lander.description import ALL_JOINTS, ARM_JOINTS, BASE_FRAME, SCOOP_TIP_FRAME
from ow_lander.errors import ConfigError, OwLanderError, PlanningError, TrajectoryError
from ow_lander.ground_detection import GroundDetector
from ow_lander.model import LanderModel
from ow_lander.operations import OperationPlan, Operations
from ow_lander.planning import ArmPlanner
from ow_lander.terrain import HeightMap
from ow_lander.trajectory import Trajectory, TrajectoryStore, read_csv, time_parameterize
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
        self._joints: dict[str, float] = {}
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
        rospy.Subscriber("/joint_states", JointState, self._on_joint_states, queue_size=10)
        rospy.Subscriber("/sim/terrain", HeightMapMsg, self._on_terrain, queue_size=1)
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
        with self._state_lock:
            self._joints.update(values)

    def _on_terrain(self, msg: HeightMapMsg) -> None:
        try:
            terrain = height_map_from_msg(msg)
        except OwLanderError as error:
            rospy.logerr("arm_services: ignoring /sim/terrain: %s", error)
            return
        with self._state_lock:
            self._terrain = terrain

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
        with self._state_lock:
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

    def _plan(self, name: str, q: np.ndarray, terrain: HeightMap, req: dict[str, Any]) -> Any:
        ops = self.operations
        planners: dict[str, Callable[[], OperationPlan]] = {
            "unstow": lambda: ops.plan_unstow(q, terrain),
            "stow": lambda: ops.plan_stow(q, terrain),
            "guarded_move": lambda: ops.plan_guarded_move(q, terrain, req),
            "grind": lambda: ops.plan_grind(q, terrain, req),
            "dig_circular": lambda: ops.plan_dig_circular(q, terrain, req),
            "dig_linear": lambda: ops.plan_dig_linear(q, terrain, req),
            "deliver_sample": lambda: ops.plan_deliver_sample(q, terrain, req),
        }
        return planners[name]()

    def _timed(self, plan: OperationPlan) -> Trajectory:
        timing = self.config.timing
        scales = {"guarded": timing.guarded_velocity_scale}
        dig_labels = {"descend", "pass_1", "shift", "pass_2", "dip_in", "cut", "lift_out", "sweep"}
        segments = []
        for segment in plan.segments:
            scale = scales.get(segment.label, timing.velocity_scale)
            if segment.label in dig_labels:
                scale = timing.dig_velocity_scale
            segments.append(type(segment)(segment.label, segment.waypoints, scale))
        accel = np.array([timing.acceleration_limits[j] for j in ARM_JOINTS])
        return time_parameterize(
            segments,
            ARM_JOINTS,
            self.planner.velocity_limits,
            accel,
            timing.sample_period_s,
            plan.operation,
        )

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
        plan = self._plan(name, q, terrain, req)
        trajectory = self._timed(plan)
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

    def _execute(self, trajectory: Trajectory) -> ExecutionResult:
        """Stream ``trajectory`` to the position controllers on simulation time."""
        cfg = self.config.execution
        unknown = [j for j in trajectory.joints if j not in self.command_pubs]
        if unknown:
            return ExecutionResult(
                False, f"trajectory names joints without a controller: {unknown}"
            )
        q0 = self._current_q()
        first = trajectory.positions[0]
        idx = [self.model.index(j) for j in trajectory.joints]
        start_error = float(np.max(np.abs(q0[idx] - first)))
        if start_error > cfg.max_tracking_error_rad:
            return ExecutionResult(
                False,
                f"the arm is {start_error:.3f} rad from the trajectory's first row "
                f"(limit {cfg.max_tracking_error_rad} rad); plan again from the current state",
            )
        detector = GroundDetector()
        guarded = trajectory.segment_span("guarded")
        rate = rospy.Rate(cfg.command_rate_hz)
        t_start = rospy.Time.now()
        settle_pause = 0.0
        pause_start: float | None = None
        limit = trajectory.duration * cfg.timeout_factor + cfg.settle_timeout_s
        stalled_since = time.monotonic()
        last_sim = t_start
        result = ExecutionResult(False, "")
        while not rospy.is_shutdown():
            now = rospy.Time.now()
            if now != last_sim:
                last_sim, stalled_since = now, time.monotonic()
            elif time.monotonic() - stalled_since > 5.0:
                return ExecutionResult(False, "simulation time is not advancing (no /clock?)")
            elapsed = (now - t_start).to_sec()
            t = elapsed - settle_pause
            settling = False
            if guarded and settle_pause == 0.0 and t >= guarded[0] and cfg.guarded_settle_s > 0:
                # Hold the start of the descent so the arm settles (OceanWATERS: 2 s).
                if pause_start is None:
                    pause_start = elapsed
                    detector.reset()
                if elapsed - pause_start < cfg.guarded_settle_s:
                    t, settling = guarded[0], True
                else:
                    settle_pause = cfg.guarded_settle_s
                    t = elapsed - settle_pause
            setpoint = trajectory.sample(min(max(t, 0.0), trajectory.duration))
            for joint, value in zip(trajectory.joints, setpoint, strict=True):
                self.command_pubs[joint].publish(Float64(float(value)))
            q = self._current_q()
            error = np.abs(q[idx] - setpoint)
            worst = int(np.argmax(error))
            if error[worst] > cfg.max_tracking_error_rad:
                return ExecutionResult(
                    False,
                    f"tracking error: {trajectory.joints[worst]} is {error[worst]:.3f} rad from "
                    f"its set-point at t={t:.1f} s (limit {cfg.max_tracking_error_rad} rad)",
                    elapsed,
                )
            if guarded and not settling and guarded[0] <= t <= guarded[1]:
                tip = self.model.position(q, SCOOP_TIP_FRAME)
                if detector.update(now.to_sec(), tip) and detector.contact is not None:
                    result.ground_found = True
                    result.ground_position = detector.contact
                    self._publish_ground(True, detector.contact)
                    hold = q[idx]
                    for joint, value in zip(trajectory.joints, hold, strict=True):
                        self.command_pubs[joint].publish(Float64(float(value)))
                    result.success = True
                    result.message = "ground found"
                    result.duration = elapsed
                    return result
            if t >= trajectory.duration and error[worst] <= cfg.goal_tolerance_rad:
                if guarded:
                    self._publish_ground(False, np.zeros(3))
                    result.message = "guarded move ended without finding the ground"
                else:
                    result.message = "reached the final set-point"
                result.success = True
                result.duration = elapsed
                return result
            if elapsed > limit + settle_pause:
                return ExecutionResult(
                    False,
                    f"timeout: final set-point not reached within {limit:.1f} s "
                    f"(worst joint {trajectory.joints[worst]} {error[worst]:.3f} rad away)",
                    elapsed,
                )
            try:
                rate.sleep()
            except rospy.ROSTimeMovedBackwardsException:
                t_start = rospy.Time.now()
        return ExecutionResult(False, "shutting down")

    def _publish_ground(self, found: bool, position: np.ndarray) -> None:
        msg = GuardedMoveResult()
        msg.header.stamp = rospy.Time.now()
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
