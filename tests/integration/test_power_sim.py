"""The power node against the physics of the real simulation (issue 7 acceptance).

* Work and energy: a slow lift of the arm in ``ow_sim_bullet``; the mechanical energy the power
  node integrates equals the rise of the arm's potential energy (pinocchio, Europa gravity) plus
  what the joint dampers dissipated (``/sim/joint_damping``), the arm at rest at both ends.
* Holding a pose costs P0 times the duration and no mechanical energy.
* A guarded move's power rises when the scoop meets the ground (the paper's Figure 18).

Everything is on simulation time: windows are chosen by message stamps, never by the wall clock.
"""

import re
import threading
import time

import numpy as np
import pytest
import rospy
from sensor_msgs.msg import JointState
from std_msgs.msg import Header
from std_srvs.srv import Trigger
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from ow_bringup.testing import advertise, subscribe, wait_connected
from ow_description.description import DEFAULT_GROUND_Z, UNSTOWED
from ow_description.model import LanderModel
from ow_msgs.msg import GuardedMoveResult, Power
from ow_msgs.srv import GuardedMove, Unstow
from ow_power.energy import ArmEnergyModel
from ow_power.model import integrate_j

P0_W = 43.0
GROUND_Z = DEFAULT_GROUND_Z
#: rad, the arm reaching out low (scoop tip 22 cm above the ground) and lifted high (tip ~1.2 m
#: up): only the shoulder and proximal pitch joints move between them.
LOW = {**UNSTOWED, "j_shou_pitch": 1.0, "j_prox_pitch": -1.5707}
HIGH = {**UNSTOWED, "j_shou_pitch": 1.5707, "j_prox_pitch": -0.8}
LIFT_S = 10.0  # s (sim) for the lift: slow, so the dampers take a fraction of the work
PITCH_JOINTS = ("j_shou_pitch", "j_prox_pitch", "j_dist_pitch")
CONTACT_WINDOW_S = 0.3  # s (sim) after the reported contact in which the power is compared


@pytest.fixture(scope="module")
def stack(ros_stack, start_lander):
    ros_stack.start_node(
        "ow_power", "power", params={"auxiliary_power_w": P0_W}, wait_for_topics=["/power"]
    )
    start_lander(terrain=f"flat:{GROUND_Z}", arm_services=["/arm/unstow", "/arm/guarded_move"])
    return ros_stack


class Trace:
    """Every ``/joint_states``, ``/sim/joint_damping`` and ``/power`` message while recording,
    keyed by stamp (ns), so the three streams are joined sample by sample."""

    def __init__(self):
        self._lock = threading.Lock()
        self.joint_states: dict[int, JointState] = {}
        self.damping: dict[int, JointState] = {}
        self.power: dict[int, Power] = {}
        #: ns (sim): record at least up to this stamp (set it before the ``with`` block ends)
        self.record_until_ns = 0
        # Connected before the test goes on: the simulation runs on meanwhile.
        self._subs = [
            wait_connected(subscribe(topic, cls, self._store(store)))
            for topic, cls, store in (
                ("/joint_states", JointState, self.joint_states),
                ("/sim/joint_damping", JointState, self.damping),
                ("/power", Power, self.power),
            )
        ]

    def _store(self, into):
        def callback(msg):
            with self._lock:
                into[msg.header.stamp.to_nsec()] = msg

        return callback

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        # Record 1 s of sim time more than this process's clock says, and at least up to
        # ``record_until_ns``: under load the clock lags the simulation (it took a guarded
        # move's trace to end 20 ms after the contact it was about). Wait (bounded) until every
        # stream has caught up to it: the subscriber callbacks may lag too.
        end_ns = max((rospy.Time.now() + rospy.Duration(1.0)).to_nsec(), self.record_until_ns)
        deadline = time.monotonic() + 20.0
        while time.monotonic() < deadline and not self._reached(end_ns):
            time.sleep(0.01)
        for sub in self._subs:
            sub.unregister()

    def _reached(self, stamp_ns):
        with self._lock:
            streams = (self.joint_states, self.damping, self.power)
            return all(stream and max(stream) >= stamp_ns for stream in streams)

    def window(self, t0_s, t1_s):
        """Stamps (ns) within [t0, t1] that all three streams have, in order."""
        with self._lock:
            common = set(self.joint_states) & set(self.damping) & set(self.power)
        lo, hi = int(t0_s * 1e9), int(t1_s * 1e9)
        stamps = sorted(s for s in common if lo <= s <= hi)
        assert len(stamps) > 10, f"only {len(stamps)} joint samples between {t0_s} and {t1_s} s"
        # One sample per physics step: nothing lost, or the integrals below would be wrong.
        gaps = np.diff(stamps) * 1e-9
        assert np.allclose(gaps, 0.01), f"a stream lost samples: gaps up to {gaps.max():.3f} s"
        return stamps

    def arrays(self, stamps):
        """t (N,) s, names, position, velocity, effort, damping effort (N, n)."""
        names = list(self.joint_states[stamps[0]].name)

        def by_name(msg, field):
            index = {n: i for i, n in enumerate(msg.name)}
            values = getattr(msg, field)
            return [values[index[n]] for n in names]

        js = [self.joint_states[s] for s in stamps]
        return (
            np.array(stamps) * 1e-9,
            names,
            np.array([by_name(m, "position") for m in js]),
            np.array([by_name(m, "velocity") for m in js]),
            np.array([by_name(m, "effort") for m in js]),
            np.array([by_name(self.damping[s], "effort") for s in stamps]),
        )


@pytest.fixture(scope="module")
def send_trajectory(stack):
    """``send(duration_s, target) -> start_s``: a smooth (minimum-jerk) joint-space move from the
    current positions to ``target`` (rad by joint), with velocities (the sim interpolates cubic
    Hermite). The sim clock is paused while the message is delivered, so the move starts at the
    returned sim time exactly, however slow the delivery."""
    publisher = advertise("/sim/joint_trajectory", JointTrajectory, queue_size=1)
    deadline = time.monotonic() + 20.0
    while publisher.get_num_connections() == 0 and time.monotonic() < deadline:
        time.sleep(0.01)
    pause = stack.service("/sim/pause", Trigger)
    resume = stack.service("/sim/resume", Trigger)
    receipts: list[str] = []
    wait_connected(
        subscribe("/sim/trajectory_received", Header, lambda m: receipts.append(m.frame_id))
    )

    def send(duration_s, target, n_points=20):
        current = rospy.wait_for_message("/joint_states", JointState, timeout=10)
        position = dict(zip(current.name, current.position, strict=True))
        joints = [j for j in target if abs(target[j] - position[j]) > 1e-3]
        q0 = np.array([position[j] for j in joints])
        dq = np.array([target[j] for j in joints]) - q0
        assert pause().success
        try:
            start_s = rospy.Time.now().to_sec() + 0.1
            msg = JointTrajectory(joint_names=joints)
            msg.header.stamp = rospy.Time.from_sec(start_s)
            msg.header.frame_id = f"test_power_sim {len(receipts)}"
            for s in np.linspace(0.0, 1.0, n_points + 1):
                shape = 10 * s**3 - 15 * s**4 + 6 * s**5
                rate = (30 * s**2 - 60 * s**3 + 30 * s**4) / duration_s
                msg.points.append(
                    JointTrajectoryPoint(
                        positions=(q0 + shape * dq).tolist(),
                        velocities=(rate * dq).tolist(),
                        time_from_start=rospy.Duration.from_sec(s * duration_s),
                    )
                )
            publisher.publish(msg)
            deadline = time.monotonic() + 20.0  # queued by the paused simulation
            while msg.header.frame_id not in receipts:
                assert time.monotonic() < deadline, f"no receipt of {msg.header.frame_id}"
                time.sleep(0.01)
        finally:
            assert resume().success
        return start_s

    yield send
    publisher.unregister()


def _unstow(stack):
    response = stack.service("/arm/unstow", Unstow)(delete_prev_traj=False)
    assert response.success, response.message


def test_lift_work_equals_potential_rise_plus_damping_losses(stack, send_trajectory):
    """The power node's mechanical energy over a slow 10 s lift (shoulder and proximal pitch),
    from rest to rest, against pinocchio's potential-energy rise and the dampers' losses."""
    _unstow(stack)
    with Trace() as trace:
        # Reach out low and settle, then lift slowly and settle again.
        low_start = send_trajectory(4.0, LOW)
        rospy.sleep(low_start + 4.0 + 3.0 - rospy.Time.now().to_sec())
        lift_start = send_trajectory(LIFT_S, HIGH)
        lift_end = lift_start + LIFT_S
        rospy.sleep(lift_end + 3.0 - rospy.Time.now().to_sec())

    stamps = trace.window(lift_start - 0.2, lift_end + 3.0)
    t, names, position, velocity, effort, damper = trace.arrays(stamps)
    work_j = trace.power[stamps[-1]].mechanical_energy - trace.power[stamps[0]].mechanical_energy

    lander = LanderModel()  # Europa gravity, as the simulation
    q0, q1 = (lander.q_from(dict(zip(names, position[k], strict=True))) for k in (0, -1))
    potential_rise_j = lander.potential_energy(q1) - lander.potential_energy(q0)
    dissipated_j = -integrate_j(t, np.sum(damper * velocity, axis=1))  # -sum tau_d * w * dt
    arm = ArmEnergyModel()
    kinetic_j = [arm.kinetic_energy_j(names, position[k], velocity[k]) for k in (0, -1)]
    accounted_j = potential_rise_j + kinetic_j[1] - kinetic_j[0] + dissipated_j
    error = abs(work_j - accounted_j) / accounted_j
    print(
        f"\nlift: work {work_j:.4f} J = PE rise {potential_rise_j:.4f} J + damping "
        f"{dissipated_j:.4f} J + KE rise {kinetic_j[1] - kinetic_j[0]:.2e} J, error {error:.3%}"
    )
    assert potential_rise_j > 15.0  # the arm was lifted
    assert dissipated_j > 0.0
    assert max(kinetic_j) < 1e-4 * accounted_j  # at rest at both ends
    assert error < 0.05

    # The same balance through ow_power's ROS-free API, with the URDF damping c w^2 too: the
    # lift moves only heavy joints, where the simulation's damping torque is -c w.
    balance = arm.balance(t, names, position, velocity, effort, damping_effort=damper)
    assert balance.work_j == pytest.approx(work_j, rel=1e-6)  # the node's eq. 4, same stamps
    assert balance.potential_rise_j == pytest.approx(potential_rise_j, rel=1e-9)
    assert balance.dissipated_j == pytest.approx(dissipated_j, rel=1e-9)
    assert balance.relative_error < 0.05
    urdf = arm.balance(t, names, position, velocity, effort)
    assert urdf.dissipated_j == pytest.approx(dissipated_j, rel=0.01)
    assert urdf.relative_error < 0.05


def test_holding_a_pose_costs_p0_times_the_duration(stack):
    rospy.sleep(1.0)  # sim: whatever ran before has settled
    with Trace() as trace:
        rospy.sleep(5.0)
    stamps = trace.window(0.0, 1e12)
    first, last = trace.power[stamps[0]], trace.power[stamps[-1]]
    duration_s = (stamps[-1] - stamps[0]) * 1e-9
    energy_j = last.energy - first.energy
    mechanical_j = last.mechanical_energy - first.mechanical_energy
    peak_w = max(abs(trace.power[s].mechanical_power_abs) for s in stamps)
    print(
        f"\nhold: {duration_s:.2f} s, E {energy_j:.4f} J (P0 x duration "
        f"{P0_W * duration_s:.4f} J), E_mech {mechanical_j:.2e} J, peak sum|P| {peak_w:.2e} W"
    )
    assert duration_s > 4.0
    assert energy_j - mechanical_j == pytest.approx(P0_W * duration_s, rel=1e-9)
    assert energy_j == pytest.approx(P0_W * duration_s, rel=1e-4)
    assert peak_w < 0.01


def test_guarded_move_power_rises_at_ground_contact(stack):
    """The paper's Figure 18: steady power while the scoop descends, a rise when it meets the
    ground. How long the arm keeps pressing after the detector fires depends on how fast the
    arm services react (wall time, the simulation running meanwhile), so the rise is checked as
    a departure of sum |P| from its steady value around the contact, a change of the shoulder
    pitch's torque as the ground takes up load, and its power, which stops braking the descent,
    not as a mean that depends on that delay."""
    _unstow(stack)
    results = []
    started = rospy.Time.now()
    sub = subscribe(
        "/guarded_move_result",
        GuardedMoveResult,
        lambda msg: results.append(msg) if msg.header.stamp >= started else None,
    )
    with Trace() as trace:
        response = stack.service("/arm/guarded_move", GuardedMove)(
            use_defaults=False, x=1.7, y=0.0, z=0.05, direction_x=0.0, direction_y=0.0,
            direction_z=1.0, search_distance=0.5,
        )  # fmt: skip
        contact = re.search(r"\(t=([0-9.]+) s sim\)", response.message)
        assert contact, response.message
        t_contact = float(contact.group(1))
        trace.record_until_ns = int((t_contact + 0.6) * 1e9)  # the window below, and a margin
    sub.unregister()
    assert response.success, response.message
    assert response.ground_position.z == pytest.approx(GROUND_Z, abs=0.005)
    assert [r.success for r in results] == [True]
    # The result is stamped when it is published, at or after the contact.
    assert results[0].header.stamp.to_sec() >= t_contact - 1e-6

    stamps = trace.window(t_contact - 2.0, t_contact + 0.5)
    t = np.array(stamps) * 1e-9
    power_abs = np.array([trace.power[s].mechanical_power_abs for s in stamps])
    shoulder = np.array(
        [dict(zip(trace.power[s].name, trace.power[s].joint_power, strict=True)) for s in stamps]
    )
    shoulder = np.array([p["j_shou_pitch"] for p in shoulder])
    descent = (t >= t_contact - 1.5) & (t < t_contact - 0.2)
    # The scoop touches a few steps before the detector declares it (its velocity must drop).
    around = (t >= t_contact - 0.1) & (t < t_contact + CONTACT_WINDOW_S)
    after = (t >= t_contact) & (t < t_contact + CONTACT_WINDOW_S)
    descent_w = power_abs[descent].mean()
    efforts = np.array(
        [
            [dict(zip(m.name, m.effort, strict=True))[j] for j in PITCH_JOINTS]
            for m in (trace.joint_states[s] for s in stamps)
        ]
    )
    print(
        f"\nguarded move: contact at {t_contact:.2f} s; sum|P| descent {descent_w:.3f} W "
        f"(std {power_abs[descent].std():.3f}), around contact peak {power_abs[around].max():.3f}"
        f" W, mean after {power_abs[after].mean():.3f} W; shoulder pitch "
        f"{shoulder[descent].mean():.3f} W -> {shoulder[after].mean():.3f} W"
    )
    assert descent_w > 0.1
    assert power_abs[descent].std() < 0.05 * descent_w  # steady
    # At the contact the power leaves its steady value, by far more than its noise (up or down:
    # how far depends on when the arm services' hold arrives) ...
    assert np.abs(power_abs[around] - descent_w).max() > 20 * power_abs[descent].std()
    # ... because the ground takes up the load: the shoulder pitch's torque changes by a fifth or
    # more (rises while the arm presses on, falls once it holds and the ground carries the scoop).
    shoulder_effort = efforts[:, 0]
    steady = shoulder_effort[descent].mean()
    assert np.abs(shoulder_effort[around] - steady).max() > 0.2 * abs(steady)
    # The shoulder brakes the descending arm (negative power) and stops braking at the contact.
    assert shoulder[descent].mean() < -0.3
    assert shoulder[after].mean() > shoulder[descent].mean() + 0.25
