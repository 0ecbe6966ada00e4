"""The execution monitor's stop requests and force/torque guard, and the wrench detector, on
synthetic joint-state streams (no ROS)."""

import math

import numpy as np
import pytest

from ow_description.description import STOWED
from ow_description.model import LanderModel
from ow_lander.config import ArmServicesConfig
from ow_lander.execution.ground_detection import WrenchDetector
from ow_lander.execution.monitor import ExecutionMonitor
from ow_lander.operations.planner import Operations
from ow_lander.planning.planner import ArmPlanner

CONFIG = ArmServicesConfig()
T_START = 100.0
RATE_HZ = 50.0


@pytest.fixture(scope="module")
def model():
    return LanderModel()


@pytest.fixture(scope="module")
def unstow(model):
    planner = ArmPlanner(model, CONFIG.planner)
    plan = Operations(planner).plan_unstow(model.q_from(STOWED), None)
    return plan.timed(CONFIG.timing, planner.velocity_limits)


def _joints(trajectory, row):
    return dict(zip(trajectory.joints, (float(v) for v in row), strict=True))


def _monitor(model, trajectory, wrench_limits=None):
    start = _joints(trajectory, trajectory.positions[0])
    return ExecutionMonitor(trajectory, T_START, CONFIG.execution, model, start, wrench_limits)


def _feed_until(monitor, t_end, on_sample=None):
    """Joint states on the trajectory every 1/RATE_HZ s up to ``t_end`` (s from the start);
    ``on_sample(stamp)`` before each decision. Returns (stamp, decision) of the first end."""
    trajectory = monitor.trajectory
    for k in range(round(t_end * RATE_HZ) + 1):
        stamp = T_START + k / RATE_HZ
        joints = _joints(trajectory, trajectory.sample(k / RATE_HZ))
        monitor.record_joint_state(stamp, joints)
        if on_sample is not None:
            on_sample(stamp)
        decision = monitor.decide(stamp, joints)
        if decision.result is not None:
            return stamp, decision
    return None


def test_stop_brakes_at_the_stop_stamp_then_holds_where_the_arm_rests(model, unstow):
    monitor = _monitor(model, unstow)
    half = round(unstow.duration / 2 * RATE_HZ) / RATE_HZ
    t_stop = T_START + half
    assert _feed_until(monitor, half) is None
    monitor.request_stop(t_stop)
    # The simulation ran on for 0.1 s before the node decided: the brake holds the stop stamp.
    row = unstow.sample(half + 0.1)
    decision = monitor.decide(t_stop + 0.1, _joints(unstow, row))
    expected = _joints(unstow, unstow.sample(half))
    assert decision.hold.keys() == expected.keys()
    assert np.allclose([decision.hold[j] for j in expected], list(expected.values()))
    assert decision.result is None
    # Still moving on the way it went (overshooting the brake hold): no new command.
    direction = np.sign(unstow.sample(half) - unstow.sample(half - 0.02))
    row = row + 0.002 * direction
    assert decision_is_empty(monitor.decide(t_stop + 0.12, _joints(unstow, row)))
    # Every moving joint has turned back: held right there, stopped.
    back = _joints(unstow, row - 0.0002 * direction)
    decision = monitor.decide(t_stop + 0.14, back)
    assert decision.hold == back
    result = decision.result
    assert result.stopped and not result.success
    assert result.message == f"stopped on request at t={half:.2f} s, at rest 0.14 s later"


def decision_is_empty(decision):
    return decision.hold is None and decision.result is None and decision.setpoints is None


def test_states_queued_from_before_the_stop_stamp_neither_brake_nor_command(model, unstow):
    """A node deciding late (states still queued when the stop comes) brakes on the stop's own
    joint state, as a prompt one does: the braking starts at the same state at any load."""
    monitor = _monitor(model, unstow)
    half = round(unstow.duration / 2 * RATE_HZ) / RATE_HZ
    t_stop = T_START + half
    assert _feed_until(monitor, half - 0.2) is None
    queued = [half - 0.2 + k / RATE_HZ for k in range(1, 11)]  # received, not yet decided
    for t in queued:
        monitor.record_joint_state(T_START + t, _joints(unstow, unstow.sample(t)))
    monitor.request_stop(t_stop)
    for t in queued[:-1]:
        assert decision_is_empty(monitor.decide(T_START + t, _joints(unstow, unstow.sample(t))))
    assert monitor.braking is None
    decision = monitor.decide(t_stop, _joints(unstow, unstow.sample(half)))
    assert decision.hold == pytest.approx(_joints(unstow, unstow.sample(half)))
    assert monitor.braking is not None and monitor.braking.last_stamp == t_stop


def test_a_joint_still_moving_keeps_the_arm_braking(model, unstow):
    monitor = _monitor(model, unstow)
    t_stop = T_START + 2.0
    _feed_until(monitor, 2.0)
    monitor.request_stop(t_stop)
    row = unstow.sample(2.0)
    direction = np.sign(row - unstow.sample(2.0 - 1 / RATE_HZ))
    monitor.decide(t_stop, _joints(unstow, row))
    moving = row + 0.001 * direction  # 0.05 rad/s on at 50 Hz
    assert monitor.decide(t_stop + 0.02, _joints(unstow, moving)).result is None
    assert monitor.decide(t_stop + 0.04, _joints(unstow, moving)).result.stopped  # at rest


def test_an_arm_that_never_rests_is_held_after_the_braking_limit(model, unstow):
    monitor = _monitor(model, unstow)
    _feed_until(monitor, 2.0)
    monitor.request_stop(T_START + 2.0)
    row = unstow.sample(2.0)
    direction = np.sign(row - unstow.sample(2.0 - 1 / RATE_HZ))
    assert monitor.decide(T_START + 2.0, _joints(unstow, row)).result is None
    for k in range(1, 60):
        moved = row + 0.01 * k * direction
        decision = monitor.decide(T_START + 2.0 + k / RATE_HZ, _joints(unstow, moved))
        if decision.result is not None:
            break
    assert decision.result.stopped
    assert k == RATE_HZ  # 1 s of braking


def test_a_second_stop_request_keeps_the_first_stamp(model, unstow):
    monitor = _monitor(model, unstow)
    monitor.request_stop(T_START + 1.0)
    monitor.request_stop(T_START + 2.0)
    assert monitor.stop_time == T_START + 1.0


def test_stop_before_any_joint_state_holds_where_the_arm_is(model, unstow):
    monitor = _monitor(model, unstow)
    monitor.request_stop(T_START - 1.0)
    here = _joints(unstow, unstow.positions[0])
    decision = monitor.decide(T_START, here)
    assert decision.hold == here
    assert monitor.decide(T_START + 0.02, here).result.stopped


NOT_EXCEEDED = "no force/torque threshold exceeded (largest changes "


@pytest.mark.parametrize(
    ("force", "torque", "fires", "message"),
    [
        ((0, 0, 9.9), (0, 0, 0), False, NOT_EXCEEDED + "9.9 N of 10.0 N, 0.00 N m of 2.0 N m)"),
        ((0, 0, 10.1), (0, 0, 0), True, "force 10.1 N exceeded force_threshold 10.0 N"),
        ((6, 8.1, 0), (0, 0, 0), True, "force 10.1 N exceeded force_threshold 10.0 N"),
        ((0, 0, 0), (0, 2.01, 0), True, "torque 2.01 N m exceeded torque_threshold 2.0 N m"),
        ((0, 0, 0), (0, 1.99, 0), False, NOT_EXCEEDED + "0.0 N of 10.0 N, 1.99 N m of 2.0 N m)"),
    ],
)
def test_wrench_detector_measures_from_the_tare(force, torque, fires, message):
    detector = WrenchDetector(10.0, 2.0)
    tare_f, tare_t = np.array([3.0, -1.0, 20.0]), np.array([0.5, 0.5, -0.5])
    assert not detector.update(tare_f, tare_t)
    assert detector.update(tare_f + force, tare_t + torque) is fires
    assert detector.describe() == message


def test_force_torque_guard_stops_a_joint_move_and_holds_at_the_breach(model, unstow):
    monitor = _monitor(model, unstow, wrench_limits=(10.0, 5.0))
    t_breach = T_START + 3.0

    def wrench(stamp):
        pressed = stamp >= t_breach
        monitor.wrist_force(stamp, np.array([0, 0, 12.0 if pressed else 0.5]), np.zeros(3))

    ended = _feed_until(monitor, unstow.duration, wrench)
    assert ended is not None
    stamp, decision = ended
    assert stamp == pytest.approx(t_breach)
    assert decision.hold == _joints(unstow, unstow.sample(3.0))
    result = decision.result
    assert result.success and not result.reports_ground
    assert result.message == "force 11.5 N exceeded force_threshold 10.0 N"
    assert result.wrench == pytest.approx((11.5, 0.0))
    assert result.hold == decision.hold
    kinds = {s.detector for s in monitor.signals}
    assert kinds == {"force", "torque"}
    assert [s.contact for s in monitor.signals if s.detector == "force"][-1]
    assert all(s.threshold == 10.0 for s in monitor.signals if s.detector == "force")


def test_guarded_joint_move_without_a_breach_succeeds(model, unstow):
    monitor = _monitor(model, unstow, wrench_limits=(10.0, 5.0))
    ended = _feed_until(
        monitor, unstow.duration + 1.0, lambda s: monitor.wrist_force(s, np.zeros(3), np.zeros(3))
    )
    assert ended is not None
    assert ended[1].result.success
    assert ended[1].result.message == "reached the final set-point"


def test_velocity_detector_samples_are_kept_for_publishing(model):
    planner = ArmPlanner(model, CONFIG.planner)
    from ow_description.description import DEFAULT_GROUND_Z, UNSTOWED
    from ow_description.terrain import HeightMap
    from ow_lander.execution.monitor import with_settle_pause

    plan = Operations(planner).plan_guarded_move(
        model.q_from(UNSTOWED), HeightMap.flat(DEFAULT_GROUND_Z), {"use_defaults": True}
    )
    trajectory = with_settle_pause(
        plan.timed(CONFIG.timing, planner.velocity_limits), CONFIG.execution
    )
    monitor = _monitor(model, trajectory)
    first, _ = trajectory.steady_span("guarded")
    for k in range(8):
        t = T_START + first + k * 0.02
        monitor.tip_sample(t, np.array([1.7, 0.0, 0.3 - 0.01 * k]))
    signals = monitor.signals
    assert len(signals) == 7
    assert all(s.detector == "velocity" for s in signals)
    assert signals[0].signal == pytest.approx(-0.5)
    assert math.isnan(signals[0].threshold) and not math.isnan(signals[-1].threshold)
