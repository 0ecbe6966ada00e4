"""OceanWATERS' deprecated GuardedMove action (ow_lander/GuardedMoveAction) served by
``arm_services`` on the paper's guarded move (rospy and actionlib wiring only; the goal's
translation and end are :mod:`ow_lander.actions.guarded_move`'s)."""

from __future__ import annotations

import threading
from pathlib import Path
from types import SimpleNamespace
from typing import Any, Protocol

import numpy as np
import rospy
from geometry_msgs.msg import Point

from ow_description.model import LanderModel
from ow_description.trajectory import Trajectory
from ow_lander.actions.guarded_move import (
    GUARDED_MOVE,
    OPERATION,
    PREEMPTED,
    GuardedMoveEnd,
    guarded_move_end,
    guarded_move_request,
)
from ow_lander.actions.owl import arm_state
from ow_lander.arm_services.execution import ArmExecutor
from ow_lander.config import ArmServicesConfig
from ow_lander.errors import REQUEST_ERRORS
from ow_lander.msg import GuardedMoveAction, GuardedMoveFeedback, GuardedMoveResult
from ow_msgs.msg import Operation
from ow_runtime.action_server import SimpleActionServer
from ow_runtime.feedback import StampedFeedback
from ow_runtime.status_timer import share_status_timer

#: s (sim), feedback period: 20 Hz of simulation time, as the owl_msgs arm actions.
FEEDBACK_PERIOD_S = 0.05
#: OceanWATERS' refusal of a goal while something else has the arm (here: "<what> goal" or
#: "/arm/<name> service").
CHECKED_OUT = "Arm is already checked out by the {owner}"


class ArmServices(Protocol):
    """What the action uses of :class:`~ow_lander.arm_services.node.ArmServicesNode`."""

    config: ArmServicesConfig
    model: LanderModel
    executor: ArmExecutor

    def claim(self, owner: str) -> str | None: ...

    def release(self) -> None: ...

    def marker(self, name: str, event: int, parameters: dict[str, Any], end: Any) -> None: ...

    def plan_to_file(
        self, name: str, parameters: dict[str, Any], notes: list[str]
    ) -> tuple[Trajectory, Path]: ...


class GuardedMoveServer:
    """The ``GuardedMove`` action server (ow_lander/GuardedMoveAction; OceanWATERS' TASK group).

    Goal: ``start`` m (base_link), ``normal`` (base_link), ``search_distance`` m: planned as
        ``/arm/guarded_move`` with (x, y, z) = start and direction = normal (scoop tip to start,
        then a straight search along -normal), executed and watched by its ground detector;
        ``/guarded_move_result`` and ``/arm/operation`` are published as for the service.
    Ends: SUCCEEDED "Ground detected" (result ``success`` true, ``final`` the scoop tip at
        contact, m, base_link) or "No ground detected" (false, zeros); ABORTED with the reason
        when the goal cannot be planned or a fault stops it, "Stop was called; trajectory
        execution ceased" when ArmStop stops it; PREEMPTED "Action was preempted: ..." when its
        client cancels it (the arm holds where it stopped).
    Refusals (ABORTED at once): while the TASK goal error stands with ``auto_clear_goal_errors``
        false, or an arm execution error stops motions (:mod:`ow_lander.execution.fault_reaction`);
        while a service request or another goal has the arm ("Arm is already checked out by the
        TaskGrind goal").
    Feedback: ``current``, the scoop tip (m, base_link), every ``FEEDBACK_PERIOD_S`` of sim time.

    Args:
        node: the arm services (planning, execution, the busy owner, markers).
    """

    def __init__(self, node: ArmServices) -> None:
        self.node = node
        self._lock = threading.Lock()
        self._executing = False  # this server's goal has the arm
        self._cancelled = threading.Event()
        self.server = SimpleActionServer(GUARDED_MOVE, GuardedMoveAction, self._on_goal)
        self.server.register_preempt_callback(self._on_cancel)
        self.server.start()
        self._feedback = StampedFeedback(self.server.action_server, FEEDBACK_PERIOD_S)
        # A status timer that outlives a clock set back (actionlib's own ends its thread).
        self._status_timer = share_status_timer([self.server.action_server])

    def _on_cancel(self) -> None:
        """A cancel of the running goal: stop the arm if the goal has it (not from this
        callback: the stop waits for joint states)."""
        with self._lock:
            self._cancelled.set()
            stop = self._executing
        if stop:
            threading.Thread(target=self.node.executor.stop, daemon=True).start()

    def _on_goal(self, goal: Any) -> None:
        self._cancelled.clear()
        detector = self.node.config.execution.ground_detector
        refused = self.node.executor.faults.now().refusal("task", detector == "force")
        owner = self.node.claim(f"{GUARDED_MOVE} goal") if refused is None else None
        if refused is not None or owner is not None:
            text = refused or CHECKED_OUT.format(owner=owner)
            rospy.loginfo(f"arm_services: {GUARDED_MOVE} goal refused: {text}")
            self._finish(GuardedMoveEnd("aborted", text))
            return
        start, normal = goal.start, goal.normal
        parameters = guarded_move_request(
            (start.x, start.y, start.z), (normal.x, normal.y, normal.z), goal.search_distance
        )
        self.node.marker(GUARDED_MOVE, Operation.START, parameters, None)
        try:
            with self._lock:
                self._executing = True
            end = self._carry_out(parameters)
        except REQUEST_ERRORS as error:
            end = GuardedMoveEnd("aborted", str(error))
        except Exception as error:
            rospy.logerr("arm_services: %s goal crashed: %r", GUARDED_MOVE, error)
            end = GuardedMoveEnd(
                "aborted", f"{GUARDED_MOVE} failed with an internal error: {error!r}"
            )
        finally:
            with self._lock:
                self._executing = False
            self.node.release()
        self.node.executor.settle()  # in a mission: the end stamped where the arm is held
        rospy.loginfo(f"arm_services: {GUARDED_MOVE} goal {end.status}: {end.text}")
        done = SimpleNamespace(success=end.status == "succeeded", message=end.text)
        self.node.marker(GUARDED_MOVE, Operation.END, parameters, done)
        self._finish(end)

    def _carry_out(self, parameters: dict[str, Any]) -> GuardedMoveEnd:
        """Plan the guarded move, write its trajectory file and execute it."""
        notes: list[str] = []
        trajectory, path = self.node.plan_to_file(OPERATION, parameters, notes)
        rospy.loginfo(f"arm_services: {GUARDED_MOVE} planned: {path.name}; {'; '.join(notes)}")
        if self._cancelled.is_set():
            return GuardedMoveEnd("preempted", f"{PREEMPTED}: cancelled before execution")
        result = self.node.executor.execute(trajectory, None, self._send_feedback)
        return guarded_move_end(result, self._cancelled.is_set())

    def _send_feedback(
        self, stamp: float, joints: dict[str, float], force: np.ndarray, torque: np.ndarray
    ) -> None:
        """Publish feedback on a joint state, at most every ``FEEDBACK_PERIOD_S`` (sim)."""
        handle = self.server.current_goal
        if self._feedback.due(handle, stamp):
            tip = arm_state(self.node.model, joints, force, torque).X_base_tip[:3, 3]
            feedback = GuardedMoveFeedback(current=Point(*tip))
            self._feedback.publish(handle, feedback, stamp)

    def _finish(self, end: GuardedMoveEnd) -> None:
        result = GuardedMoveResult(final=Point(*end.final), success=end.success)
        finish = {
            "succeeded": self.server.set_succeeded,
            "preempted": self.server.set_preempted,
            "aborted": self.server.set_aborted,
        }[end.status]
        finish(result, end.text)
