"""Cancelling an action and ArmStop: the arm stops within 0.2 s of simulation time of the
request reaching its server and holds where it stopped (drift < 1 mrad over 2 s). The request's
time is the stamp of the server's first status naming it (actionlib publishes its status as it
takes a goal or a cancel). The server pauses the simulation before it takes the request, so that
stamp is where the simulation stands, and the arm brakes from there.

The stack runs in the lockstep, held where each operation has settled (as a mission does), and
as fast as the simulation can; the test joins the lockstep and holds the simulation half-way
through the move while it sends the request (:class:`HalfwayHold`). The stop is then the same
run after run at any load (0.170 s, 0.504-0.506 and 0.448 mrad, idle and beside eight busy
loops). Before the pause came ahead of the request, a loaded machine at real time once stopped
0.35 s after it, and 10x real time 0.31 s (cancel) and 0.36 s (ArmStop)."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest
from actionlib_msgs.msg import GoalStatus, GoalStatusArray
from sensor_msgs.msg import JointState
from test_actions import JointLog, client, forget_clients, run

import owl_msgs.msg as owl
from ow_bringup.testing import subscribe
from ow_description.description import ARM_JOINTS
from ow_lander.actions.outcomes import NOTHING_TO_STOP, STOP_DURING_EXECUTION
from ow_msgs.srv import Unstow
from ow_runtime.lockstep_client import LockstepClient


@pytest.fixture(scope="module")
def stack(start_lander):
    forget_clients()
    sim = {"real_time_factor": 0.0}  # as fast as it can: a wall-time lag shows at its worst
    # Held where each operation has settled, as in a mission: each move starts from the same
    # state whenever the test sends it (3 s: the checks look 2.5 s past a stop).
    execution = {"lockstep": True, "lockstep_hold": True, "lockstep_settle_s": 3.0}
    return start_lander(sim=sim, arm={"execution": execution})


@pytest.fixture(scope="module")
def joints(stack):
    log = JointLog()
    deadline = time.monotonic() + 10
    while not log.samples and time.monotonic() < deadline:
        time.sleep(0.05)
    yield log
    log.sub.unregister()


class StatusTimes:
    """The sim time (s, the server's status stamp) each goal of an action is first seen in each
    status, from the server's ``status`` topic."""

    def __init__(self, action: str) -> None:
        self.first: dict[tuple[str, int], float] = {}
        self.sub = subscribe(f"/{action}/status", GoalStatusArray, self._on)

    def _on(self, msg: GoalStatusArray) -> None:
        for status in msg.status_list:
            self.first.setdefault((status.goal_id.id, status.status), msg.header.stamp.to_sec())

    def when(self, status: int, known: set[str] | None = None) -> float:
        """The first stamp of a goal in ``status``, of a goal not in ``known`` if given."""
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline:
            stamps = [
                t
                for (goal, state), t in list(self.first.items())
                if state == status and (known is None or goal not in known)
            ]
            if stamps:
                return min(stamps)
            time.sleep(0.01)
        pytest.fail(f"no goal seen in status {status} on {self.sub.name}")

    def goals(self) -> set[str]:
        return {goal for goal, _ in list(self.first)}


def _long_move(joints):
    """A goal turning the shoulder yaw by 0.6 rad (about 5 s)."""
    target = joints.latest().copy()
    target[0] += 0.6 if target[0] < 0 else -0.6
    return owl.ArmMoveJointsGoal(False, target.tolist()), target


class HalfwayHold:
    """The test in the lockstep: it acknowledges every joint state until the shoulder yaw has
    turned half-way from ``start`` to ``target`` (rad), and none from then on until
    :meth:`release`. The simulation then stands a lockstep latency past the last state before
    half-way while the test sends its request, at any load: a test watching a free-running
    simulation sent it anywhere from half-way to the end of the move under load."""

    def __init__(self, start: float, target: float) -> None:
        self.start, self.target = start, target
        self.reached = threading.Event()
        self._released = False
        self._newest = 0.0
        self._lock = threading.Lock()
        self.client = LockstepClient("actions_stop_test")
        self.sub = subscribe("/joint_states", JointState, self._on, tcp_nodelay=True)
        self.client.register()

    def _on(self, msg: JointState) -> None:
        stamp = msg.header.stamp.to_sec()
        yaw = dict(zip(msg.name, msg.position, strict=False))[ARM_JOINTS[0]]
        with self._lock:
            self._newest = stamp
            if abs(yaw - self.start) > 0.5 * abs(self.target - self.start):
                self.reached.set()
            if self._released or not self.reached.is_set():
                self.client.ack(stamp, force=True)

    def wait(self) -> None:
        """Wait until the move is half-way (the simulation then stands)."""
        if not self.reached.wait(120):
            pytest.fail("the move never got half-way")

    def release(self) -> None:
        """Acknowledge every joint state from now on: the simulation runs on."""
        with self._lock:
            self._released = True
            self.client.ack(self._newest, force=True)

    def close(self) -> None:
        self.release()
        self.client.close()
        self.sub.unregister()


def _check_held(joints, t_stop):
    """(stop latency s sim: from the request (its server's time) until the arm stays within
    0.5 mrad of where it rests 2.5 s later, drift rad over the 2 s of sim time after that, s of
    samples after it).

    The latency bounds the drift too: an arm that crept by more than 0.5 mrad after stopping
    would settle late."""
    deadline = time.monotonic() + 60
    while joints.samples[-1][0] < t_stop + 2.5 and time.monotonic() < deadline:
        time.sleep(0.01)
    final = joints.latest()
    after = [(t, q) for t, q in joints.samples if t >= t_stop]
    far = [t for t, q in after if np.max(np.abs(q - final)) > 5e-4]
    settled = far[-1] if far else t_stop
    held = [q for t, q in after if settled < t <= settled + 2.0]  # from the first one at rest
    drift = max(float(np.max(np.abs(q - held[0]))) for q in held)
    return settled - t_stop, drift, after[-1][0] - settled


def test_cancel_halfway_holds_the_arm(stack, joints):
    stack.service("/arm/unstow", Unstow)(delete_prev_traj=False)
    start = joints.latest().copy()
    goal, target = _long_move(joints)
    c = client("ArmMoveJoints")
    statuses = StatusTimes("ArmMoveJoints")
    hold = HalfwayHold(start[0], target[0])
    try:
        c.send_goal(goal)
        hold.wait()
        c.cancel_goal()
        # The move's goal went into PREEMPTING when the server took the cancel.
        t_cancel = statuses.when(GoalStatus.PREEMPTING)
        hold.release()
        assert c.wait_for_end(30)
    finally:
        hold.close()
    assert c.get_state() == GoalStatus.PREEMPTED, c.get_goal_status_text()
    statuses.sub.unregister()
    latency, drift, span = _check_held(joints, t_cancel)
    print(f"cancel: stopped {latency:.3f} s sim after the request; drift {drift * 1e3:.3f} mrad")
    assert latency < 0.2
    assert span >= 2.0
    assert drift < 1e-3
    assert np.allclose(c.get_result().final_angles, joints.latest(), atol=2e-3)
    assert 0.2 < abs(joints.latest()[0] - start[0]) < 0.5


def test_arm_stop_stops_a_goal_and_aborts_when_idle(stack, joints):
    stack.service("/arm/unstow", Unstow)(delete_prev_traj=False)
    start = joints.latest().copy()
    goal, target = _long_move(joints)
    stop = client("ArmStop")  # connected before the move: the request itself is timed
    statuses = StatusTimes("ArmStop")
    c = client("ArmMoveJoints")
    hold = HalfwayHold(start[0], target[0])
    try:
        c.send_goal(goal)
        hold.wait()
        known = statuses.goals()
        stop.send_goal(owl.ArmStopGoal())
        t_stop = statuses.when(GoalStatus.ACTIVE, known)  # the server took the ArmStop goal
        hold.release()
        assert stop.wait_for_end(30)
    finally:
        hold.close()
    assert stop.get_state() == GoalStatus.SUCCEEDED, stop.get_goal_status_text()
    assert c.wait_for_end(30)
    # OceanWATERS aborts the goal ArmStop ended.
    assert (c.get_state(), c.get_goal_status_text()) == (GoalStatus.ABORTED, STOP_DURING_EXECUTION)
    statuses.sub.unregister()
    latency, drift, _ = _check_held(joints, t_stop)
    print(f"ArmStop: stopped {latency:.3f} s sim after the request; drift {drift * 1e3:.3f} mrad")
    assert latency < 0.2
    assert drift < 1e-3
    state, _, text = run("ArmStop", owl.ArmStopGoal(), timeout=30)
    assert (state, text) == (GoalStatus.ABORTED, NOTHING_TO_STOP)
