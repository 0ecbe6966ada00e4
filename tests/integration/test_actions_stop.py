"""Cancelling an action and ArmStop: the arm stops within 0.2 s of simulation time of the
request reaching its server and holds where it stopped (drift < 1 mrad over 2 s). The request's
time is the stamp of the server's first status naming it (actionlib publishes its status as it
takes a goal or a cancel). The server pauses the simulation before it takes the request, so that
stamp is where the simulation stands, and the arm brakes from there.

The stack runs in the lockstep (as a mission does) and as fast as the simulation can: the stop
then takes the same simulation time at any speed and load. Before the pause came ahead of the
request, a loaded machine at real time once stopped 0.35 s after it, and 10x real time 0.31 s
(cancel) and 0.36 s (ArmStop)."""

from __future__ import annotations

import time

import numpy as np
import pytest
from actionlib_msgs.msg import GoalStatus, GoalStatusArray
from test_actions import JointLog, client, forget_clients, run

import owl_msgs.msg as owl
from ow_mission.testing import subscribe
from ow_msgs.srv import Unstow


@pytest.fixture(scope="module")
def stack(start_lander):
    forget_clients()
    sim = {"real_time_factor": 0.0}  # as fast as it can: a wall-time lag shows at its worst
    return start_lander(sim=sim, arm={"execution": {"lockstep": True}})


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


def _halfway(c, joints, start, target):
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:
        done = abs(joints.latest()[0] - start[0]) / abs(target[0] - start[0])
        if done > 0.5:
            return
        time.sleep(0.002)
    pytest.fail("the move never got half-way")


def _check_held(joints, t_stop):
    """(stop latency s sim: from the request (its server's time) until the arm stays within
    0.5 mrad of where it rests 2.5 s later, drift rad over the 2 s of sim time after that, s of
    samples after it).

    The latency bounds the drift too: an arm that crept by more than 0.5 mrad after stopping
    would settle late."""
    joints.wait_sim(2.5)
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
    c.send_goal(goal)
    _halfway(c, joints, start, target)
    c.cancel_goal()
    assert c.wait_for_end(30)
    assert c.get_state() == GoalStatus.PREEMPTED, c.get_goal_status_text()
    # The move's goal went into PREEMPTING when the server took the cancel.
    t_cancel = statuses.when(GoalStatus.PREEMPTING)
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
    client("ArmStop")  # connected before the move: the request itself is timed
    statuses = StatusTimes("ArmStop")
    c = client("ArmMoveJoints")
    c.send_goal(goal)
    _halfway(c, joints, start, target)
    known = statuses.goals()
    state, _, text = run("ArmStop", owl.ArmStopGoal(), timeout=30)
    assert state == GoalStatus.SUCCEEDED, text
    assert c.wait_for_end(30)
    assert c.get_state() == GoalStatus.PREEMPTED
    t_stop = statuses.when(GoalStatus.ACTIVE, known)  # the server took the ArmStop goal
    statuses.sub.unregister()
    latency, drift, _ = _check_held(joints, t_stop)
    print(f"ArmStop: stopped {latency:.3f} s sim after the request; drift {drift * 1e3:.3f} mrad")
    assert latency < 0.2
    assert drift < 1e-3
    state, _, text = run("ArmStop", owl.ArmStopGoal(), timeout=30)
    assert state == GoalStatus.ABORTED
    assert "nothing to stop" in text
