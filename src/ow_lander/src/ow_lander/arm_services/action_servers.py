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
from ow_lander.actions.outcomes import (
    SETUP_FAILED,
    STOP_BEFORE_EXECUTION,
    Outcome,
    SurfaceApproach,
    execution_outcome,
)
from ow_lander.actions.owl import (
    ARM_ACTIONS,
    ActionRequest,
    action_values,
    arm_state,
    controller_constraints,
    to_request,
    validate_goal,
)
from ow_lander.arm_services.execution import ArmExecutor
from ow_lander.arm_services.stop_requests import PausingActionServer, StopRequests
from ow_lander.errors import REQUEST_ERRORS, GoalError
from ow_lander.execution.monitor import ExecutionResult
from ow_lander.operations.planner import Operations
from ow_msgs.msg import Operation
from ow_runtime.feedback import StampedFeedback
from ow_runtime.status_timer import share_status_timer

#: s (sim), feedback period: 20 Hz of simulation time (from the joint-state stream).
FEEDBACK_PERIOD_S = 0.05
#: The refusal of a goal arriving while another goal or a service request runs.
#: A goal's end while the arm is taken (OceanWATERS' text, its servers checking the arm out).
BUSY = "Arm is already checked out by the {owner}"


def busy_text(owner: str) -> str:
    """:data:`BUSY` for ``owner`` as :meth:`ArmServicesNode.claim` names it ("TaskGrind goal"
    is OceanWATERS' "TaskGrind action server"; "/arm/grind service" stays)."""
    if owner.endswith(" goal"):
        owner = owner.removesuffix(" goal") + " action server"
    return BUSY.format(owner=owner)


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
    Goals (OceanWATERS' semantics, :mod:`ow_lander.actions.owl`): a goal arriving while another
        goal or a service request runs is aborted at once with "Arm is already checked out by
        the <what>", as is one a fault refuses (:mod:`ow_lander.execution.fault_reaction`;
        OceanWATERS' "Action group, ARM, is faulted. ..."); a goal with a bad field
        (OceanWATERS' checks and texts, and NaNs), that cannot be planned, or that a fault stops,
        is aborted with the reason; how an executed goal ends and its text are OceanWATERS'
        (:mod:`ow_lander.actions.outcomes`). ArmStop ends the running goal ABORTED ("Stop was
        called; ..."); cancelling it stops the arm where it is and holds it (PREEMPTED, the
        result filled with where it stopped).
    Feedback: every ``FEEDBACK_PERIOD_S`` of simulation time during execution (actions that
        have feedback fields): joint angles (rad, shoulder to scoop), ``l_scoop_tip`` pose in
        base_link (m, quaternion), wrist force (N) and torque (N m) magnitudes, distance (m;
        ArmFindSurface: distance, force and torque 0 until its approach begins).
    Publishes ``/arm/operation`` START/END markers as the services do.

    Args:
        node: the arm services (planning, execution, the busy owner, markers).
    """

    def __init__(self, node: ArmOwner) -> None:
        self.node = node
        self._lock = threading.Lock()
        self._running: tuple[str, str] | None = None  # the action and goal id running
        self._cancelled = threading.Event()
        self._stop_called = threading.Event()  # ArmStop was called during the running goal
        self._stop_sent = threading.Event()  # and the goal's execution was told to stop
        self.stops = StopRequests(node.executor, self._running_goal, self._flag_stop)
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
            refused = self.node.executor.faults.refusal(name)
        except REQUEST_ERRORS as error:
            refused = str(error)
        owner = self.node.claim(f"{name} goal") if refused is None else None
        if refused is not None or owner is not None:
            # OceanWATERS' servers accept every goal and abort one they cannot run.
            text = refused if refused else busy_text(owner or "")
            rospy.loginfo(f"arm_services: {name} goal aborted at once: {text}")
            handle.set_accepted()
            handle.set_aborted(self._early_result(name), text)
            return
        with self._lock:
            self._running = (name, handle.get_goal_id().id)
            self._cancelled.clear()
            self._stop_called.clear()
            self._stop_sent.clear()
        handle.set_accepted()
        threading.Thread(target=self._run, args=(name, handle, goal), daemon=True).start()

    def _running_goal(self) -> tuple[str, str] | None:
        with self._lock:
            return self._running

    def _flag_stop(self) -> bool:
        """ArmStop: flag the running goal (if any) to end as stopped; whether one runs. An
        execution running now is stopped by ArmStop itself; one not yet started is not
        started, or, if it starts meanwhile, stopped at its first joint state."""
        with self._lock:
            if self._running is None:
                return False
            self._stop_called.set()
            if self.node.executor.executing():
                self._stop_sent.set()
            return True

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
        notes: list[str] = []
        try:
            end = self._carry_out(name, handle, goal, parameters, notes)
        except GoalError as error:
            end = (handle.set_aborted, self._early_result(name), str(error))
        except REQUEST_ERRORS as error:
            text = f"{name} failed: {error}"
            if name == "ArmFindSurface":
                text += SETUP_FAILED
            end = (handle.set_aborted, self._early_result(name), text)
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
        details = "; ".join([message, *notes])
        rospy.loginfo(f"arm_services: {name} goal {ended.get(announce, 'aborted')}: {details}")
        self.node.marker(
            name, Operation.END, parameters, SimpleNamespace(success=success, message=details)
        )
        announce(result, message)

    def _carry_out(
        self,
        name: str,
        handle: Any,
        goal: dict[str, Any],
        parameters: dict[str, Any],
        notes: list[str],
    ) -> tuple[Any, Any, str]:
        """Check, plan and execute the goal: how to end it (succeeded, aborted or preempted),
        with its result and status text; ``notes`` gets the trajectory file and the plan's
        remarks (for the log and the END marker).

        Raises:
            GoalError: a bad goal field.
            OwLanderError: no plan.
        """
        executor = self.node.executor
        validate_goal(name, goal)
        start = arm_state(self.node.model, executor.current_joints(), *executor.wrench())
        request = to_request(name, goal, start.angles, start.X_base_tip)
        parameters.update(request.request)
        trajectory: Trajectory
        trajectory, path = self.node.plan_to_file(request.operation, parameters, request.notes)
        notes.extend([path.name, *request.notes])
        if self._stop_called.is_set():
            return handle.set_aborted, self._result(name, request), STOP_BEFORE_EXECUTION
        if self._cancelled.is_set():
            return handle.set_canceled, self._result(name, request), "cancelled before execution"
        finding = name == "ArmFindSurface"
        approach = SurfaceApproach(request) if finding else None
        if request.breaches_at_once and not finding:
            # OceanWATERS' guard trips at its first check: the arm does not move.
            result = ExecutionResult(True, "not moved: a threshold trips at once")
        else:
            feedback = partial(self._send_feedback, name, handle, request, approach)
            limits = None if request.breaches_at_once else request.wrench_limits
            constraints = controller_constraints(executor.config)
            result = executor.execute(trajectory, limits, feedback, constraints)
        state = self._state(result.hold)
        began = approach is None or approach.begun
        outcome = execution_outcome(name, request, result, state, self._stop_called.is_set(), began)
        values = self._result(name, request, result.hold, result.wrench, outcome.before_approach)
        if result.message not in outcome.text:
            notes.append(result.message)
        return self._announcer(handle, outcome), values, outcome.text

    @staticmethod
    def _announcer(handle: Any, outcome: Outcome) -> Any:
        """The goal handle's method that ends the goal as ``outcome`` says."""
        if outcome.status == "succeeded":
            return handle.set_succeeded
        return handle.set_canceled if outcome.status == "preempted" else handle.set_aborted

    def _state(self, hold: dict[str, float] | None = None) -> Any:
        executor = self.node.executor
        joints = {**executor.current_joints(), **(hold or {})}
        return arm_state(self.node.model, joints, *executor.wrench())

    def _early_result(self, name: str) -> Any:
        """The result of a goal that ended before anything moved: where the arm is, or the
        empty result when that is not known (no joint state yet: the goal still ends)."""
        try:
            return self._result(name, None, before_approach=True)
        except Exception as error:  # the end must go out whatever failed here
            rospy.logwarn(f"arm_services: {name} result left empty: {error}")
            return getattr(owl, f"{name}Result")()

    def _result(
        self,
        name: str,
        request: ActionRequest | None,
        hold: dict[str, float] | None = None,
        wrench: tuple[float, float] | None = None,
        before_approach: bool = False,
    ) -> Any:
        """The result message of ``name`` filled with where the arm is now (or is held, when
        a stop or a guard ended the move) and, when a guard stopped it, the force and torque
        that did (ArmFindSurface ended ``before_approach``: distance, force and torque 0, as
        OceanWATERS reports them)."""
        point = None if request is None else request.surface_point
        values = action_values(self._state(hold), point)
        if wrench is not None:
            values.update(final_force=wrench[0], final_torque=wrench[1])
        if name == "ArmFindSurface" and before_approach:
            values.update(final_distance=0.0, final_force=0.0, final_torque=0.0)
        return conv.fill_fields(getattr(owl, f"{name}Result")(), values)

    def _send_feedback(
        self,
        name: str,
        handle: Any,
        request: ActionRequest,
        approach: SurfaceApproach | None,
        stamp: float,
        joints: dict[str, float],
        force: np.ndarray,
        torque: np.ndarray,
    ) -> None:
        """On every joint state of the execution: stop it if ArmStop was called before it
        began (the stop found nothing executing yet); publish feedback at most every
        ``FEEDBACK_PERIOD_S`` (sim)."""
        if self._stop_called.is_set() and not self._stop_sent.is_set():
            self._stop_sent.set()
            threading.Thread(target=self.node.executor.stop, daemon=True).start()
        state = None
        if approach is not None:
            state = arm_state(self.node.model, joints, force, torque)
            approach.update(state.X_base_tip)
        msg, feedback = getattr(owl, f"{name}Feedback")(), self._feedback[name]
        if msg.__slots__ and feedback.due(handle, stamp):
            state = state or arm_state(self.node.model, joints, force, torque)
            values = action_values(state, request.surface_point)
            if approach is not None and not approach.begun:
                values.update(distance=0.0, force=0.0, torque=0.0)
            feedback.publish(handle, conv.fill_fields(msg, values), stamp)
