"""OceanWATERS' arm and task actions (owl_msgs) served by ``arm_services`` (rospy wiring only):
the same planning, execution, busy policy and trajectory files as the paper's services."""

from __future__ import annotations

import threading
from functools import partial
from types import SimpleNamespace
from typing import Any, Protocol

import numpy as np
import rospy

import owl_msgs.msg as owl
from ow_description.model import LanderModel
from ow_description.trajectory import Trajectory
from ow_lander import conversions as conv
from ow_lander.actions.owl import (
    ARM_ACTIONS,
    CARTESIAN_TOLERANCE,
    ActionRequest,
    action_values,
    arm_state,
    pose_error,
    to_request,
    validate_goal,
)
from ow_lander.arm_services.execution import ArmExecutor
from ow_lander.arm_services.stop_requests import PausingActionServer, StopRequests
from ow_lander.errors import REQUEST_ERRORS
from ow_lander.execution.monitor import ExecutionResult
from ow_lander.operations.planner import Operations
from ow_msgs.msg import Operation
from ow_runtime.feedback import StampedFeedback
from ow_runtime.status_timer import share_status_timer

#: s (sim), feedback period: 20 Hz of simulation time (from the joint-state stream).
FEEDBACK_PERIOD_S = 0.05
#: The refusal of a goal arriving while another goal or a service request runs.
BUSY = "busy: {owner} is running"


class ArmOwner(Protocol):
    """What the actions use of :class:`~ow_lander.arm_services.node.ArmServicesNode`."""

    model: LanderModel
    operations: Operations
    executor: ArmExecutor

    def claim(self, owner: str) -> str | None: ...

    def release(self) -> None: ...

    def marker(self, name: str, event: int, parameters: dict[str, Any], end: Any) -> None: ...

    def plan_to_file(self, name: str, parameters: dict[str, Any], notes: list[str]) -> Any: ...


class ArmActions:
    """The arm and task action servers (actionlib.ActionServer, one goal at a time).

    Actions (owl_msgs, plain names): ``ArmUnstow``, ``ArmStow``, ``ArmMoveJoint``,
        ``ArmMoveJoints``, ``ArmMoveJointsGuarded``, ``ArmMoveCartesian``,
        ``ArmMoveCartesianGuarded``, ``ArmFindSurface``, ``TaskGrind``, ``TaskScoopCircular``,
        ``TaskScoopLinear``, ``TaskDeliverSample``, ``TaskDiscardSample``, and ``ArmStop``
        (stops whatever arm execution runs, a goal's or a service's; aborts when none does).
    Goals: a goal with a bad field is rejected naming the field, its value and the limit; a
        goal arriving while another goal or a service request runs is rejected with
        "busy: <what> is running", or while a fault refuses it
        (:mod:`ow_lander.execution.fault_reaction`); a goal that cannot be planned, or that a fault
        stops, is aborted with the reason. Cancelling the running goal stops the arm where it is and
        holds it (PREEMPTED, the result filled with where it stopped).
    Feedback: every ``FEEDBACK_PERIOD_S`` of simulation time during execution (actions that
        have feedback fields): joint angles (rad, shoulder to scoop), ``l_scoop_tip`` pose in
        base_link (m, quaternion), wrist force (N) and torque (N m) magnitudes, distance (m).
    Publishes ``/arm/operation`` START/END markers as the services do.

    Args:
        node: the arm services (planning, execution, the busy owner, markers).
    """

    def __init__(self, node: ArmOwner) -> None:
        self.node = node
        self._lock = threading.Lock()
        self._running: tuple[str, str] | None = None  # the action and goal id running
        self._cancelled = threading.Event()
        self.stops = StopRequests(node.executor, self._running_goal)
        self.servers = []
        for name in ARM_ACTIONS:
            action, on_goal = getattr(owl, f"{name}Action"), partial(self._on_goal, name)
            around = partial(self.stops.around_cancel, name)
            server = PausingActionServer(name, action, on_goal, self._on_cancel, None, around)
            self.servers.append(server)
        self.servers.append(self.stops.server)
        for server in self.servers:
            server.start()
        self._status_timer = share_status_timer(self.servers)
        self._feedback = {s.ns: StampedFeedback(s, FEEDBACK_PERIOD_S) for s in self.servers}

    # ------------------------------------------------------------------------------- goals
    def _on_goal(self, name: str, handle: Any) -> None:
        goal = conv.goal_to_dict(handle.get_goal())
        try:
            validate_goal(name, goal)
            refused = self.node.executor.faults.refusal(name)
        except REQUEST_ERRORS as error:
            refused = str(error)
        owner = self.node.claim(f"{name} goal") if refused is None else None
        if refused is not None or owner is not None:
            text = f"{name}: {refused}" if refused else BUSY.format(owner=owner)
            rospy.loginfo(f"arm_services: {name} goal rejected: {text}")
            handle.set_rejected(text=text)
            return
        with self._lock:
            self._running = (name, handle.get_goal_id().id)
            self._cancelled.clear()
        handle.set_accepted()
        threading.Thread(target=self._run, args=(name, handle, goal), daemon=True).start()

    def _running_goal(self) -> tuple[str, str] | None:
        with self._lock:
            return self._running

    def _on_cancel(self, handle: Any) -> None:
        with self._lock:
            ours = self._running is not None and self._running[1] == handle.get_goal_id().id
            if ours:
                self._cancelled.set()
        if ours:
            self.stops.started_stop()
            # Not in this callback: actionlib holds the server's lock while it runs, which the
            # feedback (on the joint states the stop waits for) needs too.
            threading.Thread(target=self.node.executor.stop, daemon=True).start()

    # ----------------------------------------------------------------------------- running
    def _run(self, name: str, handle: Any, goal: dict[str, Any]) -> None:
        """Carry out a goal; the arm is released before the goal's end is announced, so that a
        client may send its next goal as soon as it learns the end of this one."""
        parameters = dict(goal)
        self.node.marker(name, Operation.START, parameters, None)
        end: tuple[Any, Any, str]
        try:
            end = self._carry_out(name, handle, goal, parameters)
        except REQUEST_ERRORS as error:
            end = (handle.set_aborted, self._result(name, None), f"{name} failed: {error}")
        except Exception as error:
            rospy.logerr("arm_services: %s goal crashed: %r", name, error)
            end = (handle.set_aborted, None, f"{name} failed with an internal error: {error!r}")
        finally:
            with self._lock:
                self._running = None
            self.node.release()
        self.node.executor.settle()  # in a mission: the end stamped where the arm is held
        announce, result, message = end
        success = announce == handle.set_succeeded
        ended = {handle.set_succeeded: "succeeded", handle.set_canceled: "cancelled"}
        rospy.loginfo(f"arm_services: {name} goal {ended.get(announce, 'aborted')}: {message}")
        self.node.marker(
            name, Operation.END, parameters, SimpleNamespace(success=success, message=message)
        )
        announce(result, message)

    def _carry_out(
        self, name: str, handle: Any, goal: dict[str, Any], parameters: dict[str, Any]
    ) -> tuple[Any, Any, str]:
        """Plan and execute the goal: how to end it (succeeded, aborted or preempted), with
        its result and text."""
        executor = self.node.executor
        start = arm_state(self.node.model, executor.current_joints(), *executor.wrench())
        request = to_request(
            name, goal, start.angles, start.X_base_tip, self.node.operations.motions.yaw
        )
        parameters.update(request.request)
        trajectory: Trajectory
        trajectory, path = self.node.plan_to_file(request.operation, parameters, request.notes)
        if self._cancelled.is_set():
            return handle.set_canceled, self._result(name, request), "cancelled before execution"
        feedback = partial(self._send_feedback, name, handle, request)
        result = executor.execute(trajectory, request.wrench_limits, feedback)
        success, message = self._outcome(name, request, result)
        message = "; ".join([f"{message} ({path.name})", *request.notes])
        values = self._result(name, request, result.hold, result.wrench)
        if result.stopped:
            return handle.set_canceled, values, message
        return (handle.set_succeeded if success else handle.set_aborted), values, message

    def _outcome(
        self, name: str, request: ActionRequest, result: ExecutionResult
    ) -> tuple[bool, str]:
        """Success and message of an execution, with the action's own checks."""
        if result.fault is not None:
            return False, result.message
        if name == "ArmFindSurface" and not result.ground_found and not result.stopped:
            return False, f"No surface was found: {result.message}"
        if not result.success:
            return False, result.message
        if request.target_pose is not None and result.hold is None:
            state = self._state()
            distance, angle = pose_error(request.target_pose, state.X_base_tip)
            if distance > CARTESIAN_TOLERANCE[0] or angle > CARTESIAN_TOLERANCE[1]:
                return False, (
                    f"the tool ended {distance:.4f} m and {angle:.4f} rad from the target "
                    f"(tolerance {CARTESIAN_TOLERANCE[0]} m, {CARTESIAN_TOLERANCE[1]} rad)"
                )
        return True, result.message

    def _state(self, hold: dict[str, float] | None = None) -> Any:
        executor = self.node.executor
        joints = {**executor.current_joints(), **(hold or {})}
        return arm_state(self.node.model, joints, *executor.wrench())

    def _result(
        self,
        name: str,
        request: ActionRequest | None,
        hold: dict[str, float] | None = None,
        wrench: tuple[float, float] | None = None,
    ) -> Any:
        """The result message of ``name`` filled with where the arm is now (or is held, when
        a stop or a guard ended the move) and, when a guard stopped it, the force and torque
        that did."""
        point = None if request is None else request.surface_point
        values = action_values(self._state(hold), point)
        if wrench is not None:
            values.update(final_force=wrench[0], final_torque=wrench[1])
        return conv.fill_fields(getattr(owl, f"{name}Result")(), values)

    def _send_feedback(
        self,
        name: str,
        handle: Any,
        request: ActionRequest,
        stamp: float,
        joints: dict[str, float],
        force: np.ndarray,
        torque: np.ndarray,
    ) -> None:
        """Publish feedback on a joint state, at most every ``FEEDBACK_PERIOD_S`` (sim)."""
        msg, feedback = getattr(owl, f"{name}Feedback")(), self._feedback[name]
        if msg.__slots__ and feedback.due(handle, stamp):
            state = arm_state(self.node.model, joints, force, torque)
            values = action_values(state, request.surface_point)
            feedback.publish(handle, conv.fill_fields(msg, values), stamp)
