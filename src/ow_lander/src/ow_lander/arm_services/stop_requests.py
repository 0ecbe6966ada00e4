"""How the arm actions take stop requests, ``ArmStop`` goals and cancels of the running goal
(rospy and actionlib wiring only; a node module of the arm_services node): the simulation is
paused before actionlib takes one, so its status (PREEMPTING, ACTIVE) is stamped where the
simulation stands, the time the arm brakes from."""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any

from actionlib.action_server import nop_cb

import owl_msgs.msg as owl
from ow_lander.actions.outcomes import ARM_STOPPED, NOTHING_TO_STOP
from ow_lander.arm_services.execution import ArmExecutor
from ow_runtime.action_server import ActionServer

#: actionlib's own handling of a goal or cancel message (``internal_*_callback``).
Take = Callable[[Any], None]
#: Wraps ``take`` for a message: (take, message) -> None.
Around = Callable[[Take, Any], None]


class PausingActionServer(ActionServer):
    """An action server (:class:`~ow_runtime.action_server.ActionServer`: every goal's end
    reaches actionlib's own clients) whose taking of each goal (``around_goal``) and cancel
    (``around_cancel``) message is wrapped: the wrapper may pause the simulation before
    actionlib takes the message and stamps the status it publishes. Not started (``start``)."""

    def __init__(
        self,
        ns: str,
        action: Any,
        goal_cb: Callable[[Any], None],
        cancel_cb: Callable[[Any], None] = nop_cb,
        around_goal: Around | None = None,
        around_cancel: Around | None = None,
    ) -> None:
        super().__init__(ns, action, goal_cb, cancel_cb, auto_start=False)
        self._around_goal = around_goal
        self._around_cancel = around_cancel

    def internal_goal_callback(self, goal: Any) -> None:
        if self._around_goal is None:
            super().internal_goal_callback(goal)
        else:
            self._around_goal(super().internal_goal_callback, goal)

    def internal_cancel_callback(self, goal_id: Any) -> None:
        if self._around_cancel is None:
            super().internal_cancel_callback(goal_id)
        else:
            self._around_cancel(super().internal_cancel_callback, goal_id)


class StopRequests:
    """``ArmStop`` (OceanWATERS: stops whatever arm execution runs, a goal's or a service's,
    and a goal's not yet started, succeeding with "Arm trajectory stopped"; aborts with "No arm
    trajectory to stop" when nothing runs) and the cancels of the arm actions' running goal,
    each taken with the simulation paused ahead
    (:class:`~ow_lander.arm_services.stop_clock.StopPause`) when an execution may stop.

    Args:
        executor: the arm's executions (their stop and its pause).
        running: the action and goal id running now, or None.
        flag_goal: flags the running action goal as stopped by ArmStop; whether one runs.
    """

    def __init__(
        self,
        executor: ArmExecutor,
        running: Callable[[], tuple[str, str] | None],
        flag_goal: Callable[[], bool],
    ) -> None:
        self.executor = executor
        self._running = running
        self._flag_goal = flag_goal
        self._taken = threading.local()  # a stop started while actionlib took a message
        self.server = PausingActionServer(
            "ArmStop", owl.ArmStopAction, self._on_stop, around_goal=self._around_stop
        )

    def started_stop(self) -> None:
        """Say, from the callback actionlib calls while taking a message, that it started a
        stop (which takes the pause made ahead of the message)."""
        self._taken.stop = True

    def around_cancel(self, action: str, take: Take, goal_id: Any) -> None:
        """Take a cancel of ``action``'s goals: pause first when it may cancel the running goal
        (its id, or every goal: id "")."""
        running = self._running()
        ahead = running is not None and running[0] == action and goal_id.id in ("", running[1])
        self._take(take, goal_id, ahead)

    def _around_stop(self, take: Take, goal: Any) -> None:
        self._take(take, goal, self.executor.executing())

    def _take(self, take: Take, message: Any, ahead: bool) -> None:
        if ahead:
            self.executor.stop_pause.pause_ahead()
        self._taken.stop = False
        try:
            take(message)
        finally:
            if ahead and not self._taken.stop:
                self.executor.stop_pause.release()

    def _on_stop(self, handle: Any) -> None:
        handle.set_accepted()
        self.started_stop()
        threading.Thread(target=self._stop, args=(handle,), daemon=True).start()

    def _stop(self, handle: Any) -> None:
        flagged = self._flag_goal()
        if self.executor.stop() or flagged:
            handle.set_succeeded(text=ARM_STOPPED)
        else:
            handle.set_aborted(text=NOTHING_TO_STOP)
