"""``rosrun ow_lander arm_services``: the paper's arm operation services (rospy wiring only)."""

from __future__ import annotations

import os
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import rospy
from geometry_msgs.msg import Point

from ow_description.errors import TrajectoryError
from ow_description.model import LanderModel
from ow_description.trajectory import Trajectory, TrajectoryStore, read_csv
from ow_lander import conversions as conv
from ow_lander.arm_services.action_servers import ArmActions
from ow_lander.arm_services.execution import ArmExecutor
from ow_lander.arm_services.guarded_move_action import GuardedMoveServer
from ow_lander.arm_services.terrain import TerrainFeed
from ow_lander.config import ArmServicesConfig
from ow_lander.errors import REQUEST_ERRORS, ConfigError
from ow_lander.operations.planner import Operations
from ow_lander.operations.registry import SERVICE_OPERATIONS
from ow_lander.planning.planner import ArmPlanner
from ow_msgs import srv
from ow_msgs.msg import Operation
from ow_runtime.names import ARM_OPERATION
from ow_runtime.node import init_node, spin

#: The planning services: name under /arm/ (the operation's name) and service class.
OPERATIONS: dict[str, Any] = {
    spec.name: getattr(srv, spec.service) for spec in SERVICE_OPERATIONS if spec.service
}
#: What a service reports as a failed request: the arm's and the description's errors, and a
#: request value no message conversion accepts.
_FAILED_REQUEST: tuple[type[Exception], ...] = (*REQUEST_ERRORS, ValueError)
#: The answer to a request or goal that arrives while another one runs (it is not queued).
BUSY = "busy: {owner} is running; request refused"

#: A service's work: ``body(name, parameters, response)`` fills the response (parameters: the
#: request's fields, to which it may add the effective ones).
Body = Callable[[str, dict[str, Any], Any], None]


class ArmServicesNode:
    """The arm services: plan from the current joint state, write trajectories, execute them.

    Services (ow_msgs): ``/arm/unstow`` (Unstow), ``/arm/stow`` (Stow), ``/arm/guarded_move``
        (GuardedMove), ``/arm/grind`` (Grind), ``/arm/dig_circular`` (DigCircular),
        ``/arm/dig_linear`` (DigLinear), ``/arm/deliver_sample`` (DeliverSample),
        ``/arm/publish_trajectory`` (PublishTrajectory). Busy policy: one operation at a time,
        shared with the actions (:mod:`ow_lander.arm_services.action_servers`); a request arriving
        while another request or an action goal is planning or executing is refused with
        ``success: false`` and a message "busy: <what> is running"; it is not queued. Faults
        (``ArmExecutor.faults``) refuse requests while their group's goal error or an arm
        execution error stands (:mod:`ow_lander.execution.fault_reaction`).
    Subscribes: ``/joint_states`` (sensor_msgs/JointState, by joint name): the start of every
        plan and the execution monitor; ``/sim/terrain`` (ow_msgs/HeightMap, latched): the
        terrain checked against (in the lockstep, the one the simulation last published:
        :class:`~ow_lander.arm_services.terrain.TerrainFeed`); ``/tf``, ``/tf_static``: the scoop
        tip for ground detection;
        ``/arm_end_effector_force_torque`` (owl_msgs/ArmEndEffectorForceTorque, N): the wrist
        force for the force ground detector (``execution/ground_detector: force``).
    Publishes: ``/arm/operation`` (ow_msgs/Operation, START and END of every call, effective
        parameters as JSON); ``/sim/joint_trajectory`` (trajectory_msgs/JointTrajectory, the
        default execution interface) or ``/<joint>_position_controller/command``
        (std_msgs/Float64, rad; ``execution/interface: position_controllers``) for the six arm
        joints; ``/guarded_move_result`` (ow_msgs/GuardedMoveResult, latched) once per guarded
        descent.
    Parameters (private, read once, see config/arm_services.yaml): ``trajectory_dir``,
        ``plan_and_execute``, ``fallback_ground_z`` (m), ``terrain_wait_s`` (s),
        ``actionlib_status_frequency`` (Hz), ``planner/*``, ``timing/*``, ``execution/*``.

    Execution (the joint states, tf and wrist force, trajectories, holds, ground results, the
    /sim/pause and /sim/resume calls) is wired by
    :class:`~ow_lander.arm_services.execution.ArmExecutor`.
    """

    def __init__(self, config: ArmServicesConfig) -> None:
        self.config = config
        self.model = LanderModel()
        self.planner = ArmPlanner(self.model, config.planner)
        self.operations = Operations(self.planner)
        # The dock's IK restarts now rather than in the first delivery that needs them.
        self.operations.prepare(self.model.q_from({}))
        directory = config.trajectory_dir or os.path.join(
            os.environ.get("ROS_HOME", os.path.expanduser("~/.ros")), "trajectories"
        )
        self.store = TrajectoryStore(Path(directory))
        self._owner_lock = threading.Lock()
        self.owner: str | None = None
        self._operation_id = 0
        self.executor = ArmExecutor(config.execution, self.model)
        self.operation_pub = rospy.Publisher(ARM_OPERATION, Operation, queue_size=20)
        self.terrain = TerrainFeed(
            config.terrain_wait_s, config.fallback_ground_z, config.execution.lockstep
        )
        services = [(name, cls, self._operate, True) for name, cls in OPERATIONS.items()]
        services.append(("publish_trajectory", srv.PublishTrajectory, self._publish, False))
        self.services = [
            rospy.Service(f"/arm/{name}", cls, self._handler(name, cls, body, prefix))
            for name, cls, body, prefix in services
        ]
        rospy.loginfo("arm_services: trajectories in %s", self.store.directory)

    def _handler(self, name: str, service: Any, body: Body, prefix: bool) -> Callable[[Any], Any]:
        """The handler of service ``name`` (class ``service``): the busy policy, the START and
        END markers, and any failure of ``body`` turned into ``success: false`` with a message
        "<name> failed: <why>" (``prefix``) or "<why>"; an unexpected exception is logged."""

        def handle(request: Any) -> Any:
            response = service._response_class()
            refused = self.executor.faults.refusal(name, self.config.execution.ground_detector)
            owner = self.claim(f"/arm/{name} service") if refused is None else None
            if refused is not None or owner is not None:
                response.success = False
                response.message = refused or BUSY.format(owner=owner)
                return response
            try:
                self._operation_id += 1
                parameters = conv.request_to_dict(request)
                self.marker(name, Operation.START, parameters)
                try:
                    body(name, parameters, response)
                except _FAILED_REQUEST as error:
                    response.success = False
                    response.message = f"{name} failed: {error}" if prefix else str(error)
                except Exception as error:
                    rospy.logerr("arm_services: %s crashed: %r", name, error)
                    response.success = False
                    response.message = f"{name} failed with an internal error: {error!r}"
                self.marker(name, Operation.END, parameters, response)
                return response
            finally:
                self.release()

        return handle

    def claim(self, owner: str) -> str | None:
        """Take the arm for ``owner`` (e.g. "TaskGrind goal"); when another one has it,
        nothing is taken and that one's name returned."""
        with self._owner_lock:
            if self.owner is not None:
                return self.owner
            self.owner = owner
            return None

    def release(self) -> None:
        """Give the arm back (after :meth:`claim`)."""
        with self._owner_lock:
            self.owner = None

    def marker(self, name: str, event: int, parameters: dict[str, Any], end: Any = None) -> None:
        """Publish an ``/arm/operation`` START or END marker (END: ``end`` has success and
        message)."""
        stamp = rospy.Time.now()
        msg = conv.operation_msg(stamp, self._operation_id, name, event, parameters, end)
        self.operation_pub.publish(msg)

    def _operate(self, name: str, parameters: dict[str, Any], response: Any) -> None:
        """Plan operation ``name``, write its trajectory, and execute it (``plan_and_execute``)."""
        notes = []
        if parameters.get("delete_prev_traj"):
            notes.append(f"deleted {self.store.delete_written()} previous trajectory files")
        started = time.perf_counter()
        trajectory, path = self.plan_to_file(name, parameters, notes)
        response.planning_time = time.perf_counter() - started
        response.trajectory_file = str(path)
        response.duration = trajectory.duration
        response.success = True
        message = f"planned {name}: {trajectory.duration:.1f} s, written to {path.name}"
        if self.config.plan_and_execute:
            result = self.executor.execute(trajectory)
            response.success = result.success
            message += f"; executed: {result.message}"
            if hasattr(response, "ground_found"):
                response.ground_found = result.ground_found
                response.ground_position = Point(*result.ground_position)
        response.message = "; ".join([message, *notes])

    def plan_to_file(
        self, name: str, parameters: dict[str, Any], notes: list[str]
    ) -> tuple[Trajectory, Path]:
        """Plan operation ``name`` from the present joint state and terrain, time it and write
        its trajectory file; the plan's effective parameters go into ``parameters``, its
        notes into ``notes``.

        Raises:
            OwLanderError, DescriptionError: no joint state, invalid request or no plan.
        """
        q = self.model.q_from(self.executor.current_joints())
        terrain, terrain_note = self.terrain.current()
        if terrain_note:
            notes.append(terrain_note)
        plan = self.operations.plan(name, q, terrain, dict(parameters))
        notes.extend(plan.notes)
        trajectory = plan.timed(self.config.timing, self.planner.velocity_limits)
        parameters.update(plan.parameters)
        return trajectory, self.store.save(trajectory)

    def _publish(self, name: str, parameters: dict[str, Any], response: Any) -> None:
        """Execute the trajectory file of the request (the newest one with ``use_latest``)."""
        if parameters["use_latest"]:
            path = self.store.latest()
        else:
            path = self.store.resolve(parameters["trajectory_filename"])
        result = self.executor.execute(read_csv(path))
        response.success = result.success
        response.message = result.message
        response.duration = result.duration
        response.ground_found = result.ground_found
        response.ground_position = Point(*result.ground_position)


def main() -> None:
    """Entry point of ``rosrun ow_lander arm_services``."""
    init_node("arm_services")
    try:
        config = ArmServicesConfig.from_dict(rospy.get_param("~", {}))
        node = ArmServicesNode(config)
        ArmActions(node)
        GuardedMoveServer(node)
    except (ConfigError, TrajectoryError) as error:
        rospy.logfatal("arm_services: %s", error)
        sys.exit(1)
    spin()
