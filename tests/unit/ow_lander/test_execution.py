"""The execution monitor's decisions on synthetic joint-state streams (no ROS)."""

from dataclasses import replace

import numpy as np
import pytest

from ow_description.description import (
    ARM_JOINTS,
    DEFAULT_GROUND_Z,
    SCOOP_TIP_FRAME,
    STOWED,
    UNSTOWED,
)
from ow_description.model import LanderModel
from ow_description.terrain import HeightMap
from ow_description.trajectory import PathSegment, time_parameterize
from ow_lander.config import ArmServicesConfig, ExecutionConfig
from ow_lander.execution.monitor import (
    ExecutionMonitor,
    start_error,
    unknown_joints,
    with_settle_pause,
)
from ow_lander.operations.planner import Operations
from ow_lander.planning.planner import ArmPlanner

CONFIG = ArmServicesConfig()
#: s (sim), when the trajectories below start; joint states come at 50 Hz.
T_START = 100.0
RATE_HZ = 50.0


@pytest.fixture(scope="module")
def model():
    return LanderModel()


@pytest.fixture(scope="module")
def planned(model):
    """(unstow trajectory, guarded-move trajectory with its settle pause, guarded-move plan)."""
    planner = ArmPlanner(model, CONFIG.planner)
    ops = Operations(planner)
    unstow = ops.plan_unstow(model.q_from(STOWED), None)
    guarded = ops.plan_guarded_move(
        model.q_from(UNSTOWED), HeightMap.flat(DEFAULT_GROUND_Z), {"use_defaults": True}
    )
    limits = planner.velocity_limits
    return (
        unstow.timed(CONFIG.timing, limits),
        with_settle_pause(guarded.timed(CONFIG.timing, limits), CONFIG.execution),
        guarded,
    )


def _joints(trajectory, row):
    return dict(zip(trajectory.joints, (float(v) for v in row), strict=True))


def _monitor(model, trajectory, config=CONFIG.execution):
    return ExecutionMonitor(
        trajectory, T_START, config, model, _joints(trajectory, trajectory.positions[0])
    )


def _stream(monitor, arm_at, until, start=T_START - 0.2, feed=None):
    """Feed a joint state every 1/RATE_HZ s of sim time from ``start`` to ``until`` (both s);
    ``arm_at(t)`` gives the arm joints (rad, trajectory order) at ``t`` s from the start, and
    ``feed(monitor, stamp, joints)`` the detector's samples. Returns (stamp, decision) of the
    first decision that ends the execution, or None: at ``until``, or when contact is declared
    (the node decides on contact once the joint states up to its stamp are in)."""
    for k in range(round((until - start) * RATE_HZ) + 1):
        stamp = start + k / RATE_HZ
        joints = _joints(monitor.trajectory, arm_at(stamp - T_START))
        monitor.record_joint_state(stamp, joints)
        if feed is not None:
            feed(monitor, stamp, joints)
            if monitor.contact_time is not None:
                return None
        decision = monitor.decide(stamp, joints)
        if decision.result is not None:
            return stamp, decision
    return None


def test_following_the_trajectory_reaches_the_final_setpoint(model, planned):
    trajectory = planned[0]
    monitor = _monitor(model, trajectory)
    _, decision = _stream(monitor, trajectory.sample, T_START + trajectory.duration + 1.0)
    assert decision.result.success
    assert decision.result.message == "reached the final set-point"
    assert decision.hold is None and decision.setpoints is None
    assert decision.result.duration == pytest.approx(trajectory.duration, abs=1 / RATE_HZ)
    assert not decision.result.reports_ground


def test_a_lagging_joint_is_a_tracking_error_naming_it(model, planned):
    trajectory = planned[0]
    monitor = _monitor(model, trajectory)
    prox = trajectory.joints.index("j_prox_pitch")

    def lagging(t):
        row = trajectory.sample(t)
        if t > 5.0:  # the proximal pitch stops following
            row[prox] = trajectory.sample(5.0)[prox]
        return row

    stamp, decision = _stream(monitor, lagging, T_START + trajectory.duration)
    result = decision.result
    assert not result.success
    assert result.message.startswith("tracking error: j_prox_pitch is 0.30")
    assert "(limit 0.3 rad); the arm holds where it is" in result.message
    # Held where it is, by name.
    assert decision.hold == _joints(trajectory, lagging(stamp - T_START))
    assert 5.0 < result.duration < trajectory.duration


def test_an_arm_that_never_arrives_times_out(model, planned):
    trajectory = planned[0]
    monitor = _monitor(model, trajectory)
    yaw = trajectory.joints.index("j_shou_yaw")

    def short(t):
        row = trajectory.sample(t)
        row[yaw] += 0.05 * min(max(t, 0.0) / trajectory.duration, 1.0)  # ends 0.05 rad off
        return row

    limit = trajectory.duration * 1.5 + 10.0
    stamp, decision = _stream(monitor, short, T_START + limit + 1.0)
    result = decision.result
    assert not result.success
    assert result.message == (
        f"timeout: final set-point not reached within {limit:.1f} s "
        "(worst joint j_shou_yaw 0.050 rad away)"
    )
    assert result.duration > limit
    assert decision.hold == _joints(trajectory, short(stamp - T_START))


def test_joint_states_that_stop_arriving_hold_the_last_one(model, planned):
    trajectory = planned[0]
    monitor = _monitor(model, trajectory)
    _stream(monitor, trajectory.sample, T_START + 3.0)
    decision = monitor.stalled()
    assert not decision.result.success
    assert "no /joint_states for 5.0 s of wall time" in decision.result.message
    assert decision.hold == _joints(trajectory, trajectory.sample(3.0))


def _stopping_at(trajectory, t_ground, pushed_after=None):
    """The arm follows the trajectory until the ground stops it at ``t_ground`` s; from
    ``pushed_after`` s on, the (yielding) ground lets it go on again."""

    def arm_at(t):
        if pushed_after is not None and t >= pushed_after:
            return trajectory.sample(t - (pushed_after - t_ground))
        return trajectory.sample(min(t, t_ground))

    return arm_at


def _tip(model, joints):
    return model.position(model.q_from(joints), SCOOP_TIP_FRAME)


def test_velocity_detector_contact_holds_the_joints_of_the_contact_stamp(model, planned):
    trajectory = planned[1]
    steady = trajectory.steady_span("guarded")
    t_ground = steady[0] + 3.0
    monitor = _monitor(model, trajectory)
    tips = {}

    def feed(monitor, stamp, joints):
        tips[stamp] = _tip(model, joints)
        if monitor.wants_tip(stamp):
            monitor.tip_sample(stamp, tips[stamp])

    # The detector fires a few samples after the arm stopped; nothing is decided before.
    arm_at = _stopping_at(trajectory, t_ground, pushed_after=t_ground + 0.5)
    ended = _stream(monitor, arm_at, T_START + t_ground + 0.4, feed=feed)
    contact = monitor.contact_time
    assert ended is None and contact is not None
    assert T_START + t_ground < contact < T_START + t_ground + 0.4
    # The simulation runs on (the ground gives) before the node reacts: those joint states
    # arrive, and the decision comes on a later one.
    for k in range(1, 40):
        stamp = contact + 0.5 + k / RATE_HZ
        monitor.record_joint_state(stamp, _joints(trajectory, arm_at(stamp - T_START)))
    late = stamp
    decision = monitor.decide(late, _joints(trajectory, arm_at(late - T_START)))
    result = decision.result
    at_contact = _joints(trajectory, arm_at(contact - T_START))
    assert decision.hold == at_contact
    assert decision.hold != _joints(trajectory, arm_at(late - T_START))
    assert result.success and result.ground_found and result.reports_ground
    assert result.contact_time == contact
    assert np.allclose(result.ground_position, tips[contact])
    assert result.message == (f"ground found at z={tips[contact][2]:.4f} m (t={contact:.2f} s sim)")
    assert result.duration == pytest.approx(late - T_START)


def test_force_detector_contact_position_is_the_tip_at_the_contact_stamp(model, planned):
    trajectory = planned[1]
    config = replace(CONFIG.execution, ground_detector="force")
    steady = trajectory.steady_span("guarded")
    t_ground = steady[0] + 2.0
    monitor = _monitor(model, trajectory, config)
    tare = np.array([0.4, -0.1, 3.0])

    def feed(monitor, stamp, joints):
        assert not monitor.wants_tip(stamp)  # the velocity detector is not armed
        pressed = stamp - T_START >= t_ground
        force = tare + (np.array([0.0, 0.0, 12.0]) if pressed else np.zeros(3))
        monitor.wrist_force(stamp, force)

    arm_at = _stopping_at(trajectory, t_ground + 0.1, pushed_after=t_ground + 0.3)
    ended = _stream(monitor, arm_at, T_START + t_ground + 0.3, feed=feed)
    contact = monitor.contact_time
    assert ended is None
    assert contact == pytest.approx(T_START + t_ground, abs=1 / RATE_HZ)
    stamp = contact + 0.6
    monitor.record_joint_state(stamp, _joints(trajectory, arm_at(stamp - T_START)))
    decision = monitor.decide(stamp, _joints(trajectory, arm_at(stamp - T_START)))
    at_contact = _joints(trajectory, arm_at(contact - T_START))
    assert decision.hold == at_contact
    result = decision.result
    assert result.success and result.ground_found
    assert np.array_equal(result.ground_position, _tip(model, at_contact))
    assert f"ground found at z={result.ground_position[2]:.4f} m" in result.message


def test_no_contact_reports_the_distance_searched(model, planned):
    trajectory, plan = planned[1], planned[2]
    monitor = _monitor(model, trajectory)
    _, decision = _stream(monitor, trajectory.sample, T_START + trajectory.duration + 1.0)
    result = decision.result
    descent = next(s for s in plan.segments if s.label == "guarded").waypoints
    ends = [_tip(model, dict(zip(ARM_JOINTS, descent[i], strict=True))) for i in (0, -1)]
    searched = float(np.linalg.norm(ends[1] - ends[0]))
    assert searched > 0.3
    assert not result.success and not result.ground_found and result.reports_ground
    first, last = (T_START + t for t in trajectory.steady_span("guarded"))
    assert result.message == (
        f"no ground within {searched:.2f} m of the start of the descent "
        f"(no velocity reading between t={first:.2f} and t={last:.2f} s)"
    )
    assert np.array_equal(result.ground_position, np.zeros(3))
    assert result.contact_time is None


def test_a_guarded_action_without_contact_says_what_its_guard_read(model, planned):
    trajectory = planned[1]
    first, last = (T_START + t for t in trajectory.steady_span("guarded"))
    start = _joints(trajectory, trajectory.positions[0])
    limits = (10.0, 5.0)
    monitor = ExecutionMonitor(trajectory, T_START, CONFIG.execution, model, start, limits)

    def wrist(monitor, stamp, joints):  # the force creeps up 0.5 N/s: never 10 N
        monitor.wrist_force(stamp, np.array([0.0, 0.0, 0.5 * stamp]), np.array([0.3, 0, 0]))

    until = T_START + trajectory.duration + 1.0
    _, decision = _stream(monitor, trajectory.sample, until, feed=wrist)
    stamps = [T_START - 0.2 + k / RATE_HZ for k in range(round((until - T_START) * RATE_HZ) + 11)]
    read = [t for t in stamps if first <= t <= last]
    rise = 0.5 * (read[-1] - read[0])
    assert decision.result.message.endswith(
        f"the descent ({len(read)} wrench readings from t={read[0]:.2f} to t={read[-1]:.2f} s: "
        f"no force/torque threshold exceeded (largest changes {rise:.1f} N of 10.0 N, 0.00 N m "
        "of 5.0 N m))"
    )


def test_a_contact_read_seconds_after_the_joint_states_holds_at_its_own_stamp(model, planned):
    """The wrist readings may lag the joint states by seconds (their own connection): the joint
    state of the contact stamp is still there when its reading comes, however many came
    since (a fixed history of 500 once lost it: a breach reported as no ground found)."""
    trajectory = planned[1]
    first, last = (T_START + t for t in trajectory.steady_span("guarded"))
    start = _joints(trajectory, trajectory.positions[0])
    monitor = ExecutionMonitor(trajectory, T_START, CONFIG.execution, model, start, (10.0, 5.0))
    stamps = [T_START + k / 100.0 for k in range(round((last - T_START) * 100.0) + 1)]
    t_contact = next(stamp for stamp in stamps[::2] if stamp >= first + 1.0)
    for stamp in stamps:  # every joint state first, at 100 Hz: 20 s and more past the contact
        monitor.record_joint_state(stamp, _joints(trajectory, trajectory.sample(stamp - T_START)))
    assert stamps[-1] - t_contact > 10.0
    for stamp in stamps[::2]:  # then the wrist readings (50 Hz), pressed from the contact on
        pressed = 20.0 if stamp >= t_contact else 0.0
        if monitor.wrist_force(stamp, np.array([0.0, 0.0, pressed]), np.zeros(3)):
            break
    assert monitor.contact_time == pytest.approx(t_contact)
    at_contact = _joints(trajectory, trajectory.sample(monitor.contact_time - T_START))
    decision = monitor.decide(stamps[-1], _joints(trajectory, trajectory.sample(last - T_START)))
    result = decision.result
    assert result.success and result.ground_found, result.message
    assert decision.hold == pytest.approx(at_contact)
    tip = _tip(model, {**start, **at_contact})
    assert np.allclose(result.ground_position, tip)


def test_detectors_watch_only_the_steady_descent(model, planned):
    trajectory = planned[1]
    first, last = trajectory.steady_span("guarded")
    monitor = _monitor(model, trajectory)
    assert not monitor.wants_tip(T_START + first - 0.01)
    assert monitor.wants_tip(T_START + first)
    assert monitor.wants_tip(T_START + last)
    assert not monitor.wants_tip(T_START + last + 0.01)
    assert not monitor.wrist_force(T_START + first, np.zeros(3))  # not the force detector
    assert _monitor(model, planned[0]).guard is None


def test_decisions_after_the_descent_starts_wait_for_the_guard_stream(model, planned):
    trajectory = planned[1]
    first, last = trajectory.steady_span("guarded")
    monitor = _monitor(model, trajectory)  # velocity detector: the tip from tf
    assert monitor.guard_stream(T_START + first - 0.01) is None
    assert monitor.guard_stream(T_START + first) == "tip"
    assert monitor.guard_stream(T_START + last + 5.0) == "tip"  # "no ground" waits for it too
    monitor.guard.contact_time = T_START + last
    assert monitor.guard_stream(T_START + last + 0.01) is None  # contact: nothing to wait for
    assert _monitor(model, planned[0]).guard_stream(T_START + 1.0) is None  # no guard
    force = _monitor(model, trajectory, ExecutionConfig(ground_detector="force"))
    assert force.guard_stream(T_START + first) == "force"


def test_streaming_commands_the_setpoint_one_period_ahead(model, planned):
    trajectory = planned[0]
    config = replace(CONFIG.execution, interface="position_controllers", command_rate_hz=10.0)
    monitor = _monitor(model, trajectory, config)
    commanded = []
    for k in range(30):
        stamp = T_START + k / RATE_HZ
        joints = _joints(trajectory, trajectory.sample(stamp - T_START))
        decision = monitor.decide(stamp, joints)
        if decision.setpoints is not None:
            commanded.append((stamp, decision.setpoints))
    # At 10 Hz: every fifth 50 Hz joint state, the set-point 0.1 s ahead.
    assert [round(s - T_START, 6) for s, _ in commanded] == [0.0, 0.1, 0.2, 0.3, 0.4, 0.5]
    for stamp, setpoints in commanded:
        ahead = trajectory.sample(stamp - T_START + 0.1)
        assert setpoints == _joints(trajectory, ahead)


def test_the_start_is_refused_far_from_the_first_row_or_with_unknown_joints(model):
    trajectory = time_parameterize(
        [PathSegment("s", np.array([[0.0] * 6, [0.1] * 6]))],
        ARM_JOINTS,
        np.ones(6),
        np.ones(6),
        0.1,
    )
    here = dict.fromkeys(ARM_JOINTS, 0.0)
    assert start_error(trajectory, here, CONFIG.execution) is None
    assert unknown_joints(trajectory) is None
    far = start_error(trajectory, {**here, "j_hand_yaw": 0.5}, CONFIG.execution)
    assert not far.success
    assert far.message == (
        "the arm is 0.500 rad from the trajectory's first row (limit 0.3 rad); "
        "plan again from the current state"
    )
    other = replace(trajectory, joints=(*ARM_JOINTS[:5], "j_grinder"))
    refused = unknown_joints(other)
    assert refused.message == "trajectory names joints without a controller: ['j_grinder']"


def test_a_guarded_segment_is_preceded_by_the_settle_pause():
    segments = [
        PathSegment("approach", np.array([[0.0], [0.2]])),
        PathSegment("guarded", np.array([[0.2], [0.4]])),
    ]
    plain = time_parameterize(segments, ("a",), np.ones(1), np.ones(1), 0.1)
    settled = with_settle_pause(plain, ExecutionConfig(guarded_settle_s=2.0))
    assert settled.duration == pytest.approx(plain.duration + 2.0)
    start = plain.segment_span("guarded")[0]
    assert np.array_equal(settled.sample(start + 1.0), settled.sample(start))
    assert with_settle_pause(plain, ExecutionConfig(guarded_settle_s=0.0)) is plain
    no_guard = time_parameterize(segments[:1], ("a",), np.ones(1), np.ones(1), 0.1)
    assert with_settle_pause(no_guard, ExecutionConfig()) is no_guard
