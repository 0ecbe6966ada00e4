"""OceanWATERS' own ow_lander actions (ow_lander.msg) on the real stack, through actionlib's stock
SimpleActionClient: Pan and Tilt move one mast joint and end with OceanWATERS' texts, refusals
included; ActivateComms draws 9.6 W on /power for exactly its duration; GuardedMove finds the ground
(or reports that it did not), and a cancel or ArmStop ends it."""

from __future__ import annotations

import math
import threading
import time
from typing import Any

import actionlib
import numpy as np
import pytest
import rospy
from actionlib_msgs.msg import GoalStatus
from geometry_msgs.msg import Point
from sensor_msgs.msg import JointState

import owl_msgs.msg as owl
from ow_bringup.testing import subscribe, wait_for_server
from ow_description.description import DEFAULT_GROUND_Z
from ow_lander.msg import (
    ActivateCommsAction,
    ActivateCommsGoal,
    GuardedMoveAction,
    GuardedMoveActionFeedback,
    GuardedMoveGoal,
    PanAction,
    PanActionFeedback,
    PanGoal,
    TiltAction,
    TiltGoal,
)
from ow_msgs.msg import Power
from ow_msgs.srv import SetLoad
from ow_power.loads import SET_LOAD_SERVICE

#: s of sim time a server gets to appear, and a goal to end (the simulation runs at 5x).
SERVER_WAIT_S = 300.0
RESULT_WAIT_S = 600.0
#: rad, OceanWATERS' pan/tilt tolerance.
TOLERANCE = 0.05
#: m, how close a guarded move's contact point is to flat ground (in the lockstep).
GROUND_TOLERANCE_M = 0.005
#: W, the configured P0 of the power node (its default).
P0_W = 43.0


@pytest.fixture(scope="module")
def stack(ros_stack, start_lander):
    start_lander(
        sim={"real_time_factor": 5.0},
        arm={"execution": {"lockstep": True}},  # contact found at the same place at any load
        arm_services=["/arm/guarded_move"],
        sim_topics=[],
    )
    ros_stack.start_node(
        "ow_lander",
        "pan_tilt",
        wait_for_topics=["/Pan/status", "/Tilt/status", "/ActivateComms/status"],
    )
    ros_stack.start_node(
        "ow_power", "power", params={"auxiliary_power_w": P0_W}, wait_for_topics=["/power"]
    )
    return ros_stack


def client(name: str, action: type) -> actionlib.SimpleActionClient:
    c = actionlib.SimpleActionClient(name, action)
    wait_for_server(c, SERVER_WAIT_S)
    return c


def run(c: actionlib.SimpleActionClient, goal: Any) -> tuple[int, str, Any]:
    """(state, status text, result) of ``goal``."""
    c.send_goal(goal)
    assert c.wait_for_result(rospy.Duration(RESULT_WAIT_S)), "the goal did not end"
    return c.get_state(), c.get_goal_status_text(), c.get_result()


def mast() -> tuple[float, float]:
    msg = rospy.wait_for_message("/joint_states", JointState, timeout=10)
    position = dict(zip(msg.name, msg.position, strict=True))
    return position["j_ant_pan"], position["j_ant_tilt"]


class Stamps:
    """Header stamps (s, sim) of every message of a topic, from now on."""

    def __init__(self, topic: str, data_class: type) -> None:
        self.stamps: list[float] = []
        self._sub = subscribe(
            topic, data_class, lambda m: self.stamps.append(m.header.stamp.to_sec())
        )

    def stop(self) -> list[float]:
        self._sub.unregister()
        return self.stamps


# --------------------------------------------------------------------------------- Pan, Tilt
def test_pan_turns_only_the_pan_joint_and_reports_at_5_hz(stack):
    _, tilt_before = mast()
    feedback = Stamps("/Pan/feedback", PanActionFeedback)
    state, text, result = run(client("Pan", PanAction), PanGoal(pan=0.8))
    stamps = feedback.stop()
    assert (state, text) == (GoalStatus.SUCCEEDED, "Reached commanded pan value")
    assert result.pan_position == pytest.approx(0.8, abs=TOLERANCE)
    pan, tilt = mast()
    assert pan == pytest.approx(0.8, abs=TOLERANCE)
    assert tilt == pytest.approx(tilt_before, abs=0.01)
    # OceanWATERS checks every 0.2 s until both joints stand still (< 1e-4 rad/s).
    assert len(stamps) >= 3
    assert np.allclose(np.diff(stamps), 0.2, atol=0.011)


def test_tilt_turns_only_the_tilt_joint(stack):
    pan_before, _ = mast()
    state, text, result = run(client("Tilt", TiltAction), TiltGoal(tilt=-0.5))
    assert (state, text) == (GoalStatus.SUCCEEDED, "Reached commanded tilt value")
    assert result.tilt_position == pytest.approx(-0.5, abs=TOLERANCE)
    pan, tilt = mast()
    assert tilt == pytest.approx(-0.5, abs=TOLERANCE)
    assert pan == pytest.approx(pan_before, abs=0.01)


@pytest.mark.parametrize(
    ("name", "action", "goal", "text"),
    [
        ("Pan", PanAction, PanGoal(pan=4.0), "Requested pan 4.0 is not within allowed limits."),
        ("Pan", PanAction, PanGoal(pan=-3.25), "Requested pan -3.25 is not within allowed limits."),
        (
            "Pan",
            PanAction,
            PanGoal(pan=math.nan),
            "Requested pan nan is not within allowed limits.",
        ),
        (
            "Tilt",
            TiltAction,
            TiltGoal(tilt=1.6),
            "Requested tilt 1.6 is not within allowed limits.",
        ),
    ],
)
def test_goals_beyond_the_limits_are_aborted_with_oceanwaters_text(stack, name, action, goal, text):
    before = mast()
    state, status_text, result = run(client(name, action), goal)
    assert (state, status_text) == (GoalStatus.ABORTED, text)
    index = 0 if name == "Pan" else 1
    reported = result.pan_position if name == "Pan" else result.tilt_position
    assert reported == pytest.approx(before[index], abs=0.01)  # where the joint is
    assert mast() == pytest.approx(before, abs=0.01)


# ------------------------------------------------------------------------------ ActivateComms
class PowerLog:
    """(stamp s, auxiliary_power W) of every /power message, from now on."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.samples: list[tuple[float, float]] = []
        self._sub = subscribe("/power", Power, self._on)

    def _on(self, msg: Power) -> None:
        with self.lock:
            self.samples.append((msg.header.stamp.to_sec(), msg.auxiliary_power))

    def stop(self) -> np.ndarray:
        self._sub.unregister()
        with self.lock:
            return np.array(self.samples)


def test_activate_comms_draws_9_6_w_on_the_battery_for_its_duration(stack):
    comms = client("ActivateComms", ActivateCommsAction)
    log = PowerLog()
    rospy.sleep(1.0)
    state, text, _ = run(comms, ActivateCommsGoal(duration=4.0))
    rospy.sleep(1.0)
    samples = log.stop()
    assert (state, text) == (GoalStatus.SUCCEEDED, "Communication uplink/downlink succeeded.")
    t, auxiliary = samples[:, 0], samples[:, 1]
    assert set(np.round(auxiliary, 9)) == {P0_W, P0_W + 9.6}
    loaded = t[auxiliary > P0_W]
    assert auxiliary[0] == P0_W and auxiliary[-1] == P0_W  # drawn once, then removed
    assert np.all(auxiliary[(t >= loaded[0]) & (t <= loaded[-1])] > P0_W)
    # Exactly the samples of (start, start + 4 s], at any machine load: the node holds the
    # simulation where the load starts and ends.
    period = float(np.median(np.diff(t)))
    assert len(loaded) == round(4.0 / period)
    assert loaded[-1] - loaded[0] == pytest.approx(4.0 - period, abs=1e-6)
    extra_j = float(np.sum((auxiliary[1:] - P0_W) * np.diff(t)))
    assert extra_j == pytest.approx(9.6 * 4.0, rel=1e-6)


def test_the_power_node_refuses_a_load_naming_the_value_and_keeps_the_one_it_had(stack):
    set_load = rospy.ServiceProxy(SET_LOAD_SERVICE, SetLoad)
    now = rospy.Time.from_sec(rospy.get_time())
    reply = set_load(source="/tester", power_w=-2.0, now=True, since=now)
    assert not reply.success
    assert "load of /tester = -2.0 W is not a finite number >= 0" in reply.message
    reply = set_load(source="/tester", power_w=1.0, now=False, since=rospy.Time.from_sec(0.5))
    assert not reply.success
    assert "load of /tester since 0.500000 s: the power model has integrated up to" in reply.message
    msg = rospy.wait_for_message("/power", Power, timeout=10)
    assert msg.auxiliary_power == P0_W


@pytest.mark.parametrize(
    ("duration", "state", "text"),
    [
        (0.0, GoalStatus.SUCCEEDED, "Communication uplink/downlink succeeded."),
        (-2.0, GoalStatus.SUCCEEDED, "Communication uplink/downlink succeeded."),
        (math.inf, GoalStatus.ABORTED, "duration = inf s is not finite"),
    ],
)
def test_activate_comms_without_a_duration(stack, duration, state, text):
    started = rospy.get_time()
    assert run(client("ActivateComms", ActivateCommsAction), ActivateCommsGoal(duration))[:2] == (
        state,
        text,
    )
    assert rospy.get_time() - started < 2.0


# -------------------------------------------------------------------------------- GuardedMove
def guarded_goal(z: float, search: float, normal: tuple[float, float, float] = (0, 0, 1)):
    return GuardedMoveGoal(start=Point(1.7, 0.0, z), normal=Point(*normal), search_distance=search)


def test_guarded_move_that_stops_above_the_ground_reports_no_ground(stack):
    feedback = Stamps("/GuardedMove/feedback", GuardedMoveActionFeedback)
    goal = guarded_goal(DEFAULT_GROUND_Z + 0.2, search=0.1)
    state, text, result = run(client("GuardedMove", GuardedMoveAction), goal)
    stamps = feedback.stop()
    assert (state, text) == (GoalStatus.SUCCEEDED, "No ground detected")
    assert not result.success
    assert (result.final.x, result.final.y, result.final.z) == (0.0, 0.0, 0.0)
    assert len(stamps) > 10


def test_guarded_move_finds_the_ground(stack):
    goal = guarded_goal(DEFAULT_GROUND_Z + 0.2, search=0.5)
    state, text, result = run(client("GuardedMove", GuardedMoveAction), goal)
    assert (state, text) == (GoalStatus.SUCCEEDED, "Ground detected")
    assert result.success
    assert result.final.z == pytest.approx(DEFAULT_GROUND_Z, abs=GROUND_TOLERANCE_M)
    assert result.final.x == pytest.approx(1.7, abs=0.02)


def test_guarded_move_with_a_zero_normal_is_aborted_with_the_reason(stack):
    goal = guarded_goal(0.1, search=0.3, normal=(0.0, 0.0, 0.0))
    state, text, result = run(client("GuardedMove", GuardedMoveAction), goal)
    assert state == GoalStatus.ABORTED
    assert "direction=(0, 0, 0) is a zero vector" in text
    assert not result.success


@pytest.mark.parametrize(
    ("how", "state", "text"),
    [
        ("cancel", GoalStatus.PREEMPTED, "Action was preempted"),
        ("ArmStop", GoalStatus.ABORTED, "Stop was called; trajectory execution ceased"),
    ],
)
def test_a_guarded_move_is_stopped_by_a_cancel_or_arm_stop(stack, how, state, text):
    moves = client("GuardedMove", GuardedMoveAction)
    stop = client("ArmStop", owl.ArmStopAction)
    moving = threading.Event()
    moves.send_goal(guarded_goal(0.3, search=0.5), feedback_cb=lambda _: moving.set())
    deadline = time.monotonic() + 120.0
    while not moving.wait(0.05):
        assert time.monotonic() < deadline, "the guarded move never started"
    if how == "cancel":
        moves.cancel_goal()
    else:
        stop.send_goal(owl.ArmStopGoal())
    assert moves.wait_for_result(rospy.Duration(RESULT_WAIT_S))
    assert moves.get_state() == state
    assert moves.get_goal_status_text().startswith(text)
    assert not moves.get_result().success
