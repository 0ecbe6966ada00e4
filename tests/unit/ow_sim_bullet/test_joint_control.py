"""The joint controllers on their own, with pinocchio as the plant: no pybullet.

The plant integrates the joints with pinocchio's forward dynamics (ABA) under the controllers'
effort and damping torques; the controllers predict exactly that motion (their implicit step), so
the loop is what the simulation runs without the terrain.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pinocchio as pin
import pytest

from ow_description.description import ALL_JOINTS, ARM_JOINTS, EUROPA_GRAVITY, STOWED, URDF_PATH
from ow_sim_bullet.config import PidGains, SimConfig
from ow_sim_bullet.errors import CommandError
from ow_sim_bullet.joint_control import JointController
from ow_sim_bullet.trajectory import JointTrajectory
from ow_sim_bullet.urdf import physical_inertias, read_urdf_joints

DT = 0.01


def controller(feedforward: bool = True, config: SimConfig | None = None) -> JointController:
    text, _ = physical_inertias(URDF_PATH.read_text())
    model = pin.buildModelFromXML(text)
    model.gravity.linear = np.array([0.0, 0.0, -EUROPA_GRAVITY])
    gains = (config or SimConfig()).gains
    return JointController(model, read_urdf_joints(text), gains, DT, feedforward)


def stowed(ctrl: JointController) -> np.ndarray:
    return np.array([STOWED.get(j, 0.0) for j in ctrl.names])


class Plant:
    """The joints moved by pinocchio's forward dynamics under the controllers' torques."""

    def __init__(self, ctrl: JointController, q: np.ndarray) -> None:
        self.ctrl = ctrl
        self.data = ctrl.model.createData()
        self.q, self.v, self.time = q.copy(), np.zeros_like(q), 0.0

    def step(self) -> tuple[np.ndarray, np.ndarray]:
        v_set = self.ctrl.follow(self.time)
        effort, damping = self.ctrl.control(self.q, self.v, v_set)
        a = pin.aba(self.ctrl.model, self.data, self.q, self.v, effort + damping)
        self.v = self.v + DT * a
        self.q = self.q + DT * self.v
        self.time += DT
        return effort, damping


def test_joints_are_in_pinocchio_coordinate_order():
    ctrl = controller()
    assert sorted(ctrl.names) == sorted(ALL_JOINTS)
    order = [ctrl.model.joints[ctrl.model.getJointId(j)].idx_q for j in ctrl.names]
    assert order == list(range(len(ALL_JOINTS)))


def test_implicit_step_solves_the_documented_equation():
    """(M + dt diag(dampers)) x = r by ABA with the dampers as armature: numpy's dense solve with
    the mass matrix gives the same x, for the controllers' dampers and for a saturated step's,
    after which the controllers' are restored."""
    ctrl = controller()
    rng = np.random.default_rng(7)
    data = ctrl.model.createData()
    saturated_dampers = ctrl.dampers.copy()
    saturated_dampers[-1] = ctrl.damping[-1]  # a saturated joint loses its derivative damper
    for _ in range(5):
        q = rng.uniform(-2.0, 2.0, len(ctrl.names))
        rhs = rng.normal(0.0, 10.0, len(ctrl.names))
        mass = pin.crba(ctrl.model, data, q)
        for dampers in (saturated_dampers, ctrl.dampers):
            expected = np.linalg.solve(mass + DT * np.diag(dampers), rhs)
            assert np.allclose(ctrl.implicit_solve(q, dampers, rhs), expected, rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize("feedforward", [True, False])
def test_at_rest_on_the_setpoint_the_effort_is_the_gravity_torque(feedforward):
    ctrl = controller(feedforward)
    q = stowed(ctrl)
    ctrl.reset(q)
    effort, damping = ctrl.control(q, np.zeros_like(q), np.zeros_like(q))
    gravity = ctrl.gravity_torque(q)
    assert np.abs(gravity).max() > 1.0
    assert np.allclose(effort, gravity, rtol=1e-9, atol=1e-9)
    assert np.allclose(damping, 0.0, atol=1e-9)


@pytest.mark.parametrize("joint", ARM_JOINTS)
def test_a_setpoint_step_settles(joint):
    ctrl = controller()
    q0 = stowed(ctrl)
    ctrl.reset(q0)
    plant = Plant(ctrl, q0)
    k = ctrl.names.index(joint)
    step = 0.1 if joint != "j_shou_pitch" else -0.1
    ctrl.set_setpoint(joint, q0[k] + step)
    response = []
    for _ in range(round(10.0 / DT)):
        plant.step()
        response.append((plant.q[k] - q0[k]) / step)
    assert abs(response[-1] - 1.0) < 0.02
    assert max(response) - 1.0 < 0.2


def test_a_trajectory_moves_the_setpoints_and_ends():
    ctrl = controller()
    q0 = stowed(ctrl)
    ctrl.reset(q0)
    joints = ["j_shou_yaw", "j_hand_yaw"]
    target = [q0[ctrl.names.index(j)] + 0.4 for j in joints]
    ctrl.set_trajectory(JointTrajectory.build(joints, 1.0, [2.0], [target], None, ctrl.names), 1.0)
    k = [ctrl.names.index(j) for j in joints]
    v_set = ctrl.follow(2.0)  # halfway along the linear ramp
    assert np.allclose(ctrl.setpoint[k], q0[k] + 0.2)
    assert np.allclose(v_set[k], 0.2)
    assert np.count_nonzero(v_set) == 2
    # A set-point command takes one joint off the trajectory; the other keeps following it.
    ctrl.set_setpoint("j_hand_yaw", 0.0)
    ctrl.follow(2.5)
    assert ctrl.setpoint[k[0]] == pytest.approx(q0[k[0]] + 0.3)
    assert ctrl.setpoint[k[1]] == 0.0
    assert np.allclose(ctrl.follow(3.0), 0.0)
    assert ctrl.setpoint[k[0]] == pytest.approx(target[0])
    ctrl.set_setpoint("j_shou_yaw", 0.5)  # the trajectory has ended: nothing moves it back
    ctrl.follow(4.0)
    assert ctrl.setpoint[k[0]] == 0.5


def test_a_saturated_joint_gives_its_limit_and_does_not_wind_up():
    ctrl = controller()
    q = stowed(ctrl)
    ctrl.reset(q)
    joint = "j_hand_yaw"
    k = ctrl.names.index(joint)
    ctrl.set_gains(joint, PidGains(1e5, 10.0, 0.0))
    ctrl.set_setpoint(joint, q[k] + 2.0)
    zeros = np.zeros_like(q)
    for _ in range(100):
        effort, _ = ctrl.control(q, zeros, zeros)
        assert effort[k] == pytest.approx(ctrl.gains(joint).i_clamp)  # the effort limit
    # Back on the set-point: no integral was wound up (10 * 2 rad * 1 s = 20 N m otherwise).
    ctrl.set_setpoint(joint, q[k])
    effort, _ = ctrl.control(q, zeros, zeros)
    assert effort[k] == pytest.approx(ctrl.gravity_torque(q)[k], abs=1e-9)


def test_new_gains_keep_the_integral_within_their_clamp():
    ctrl = controller(feedforward=False)  # the integral starts at the gravity torque
    q = stowed(ctrl)
    ctrl.reset(q)
    joint = "j_shou_pitch"
    k = ctrl.names.index(joint)
    gravity = ctrl.gravity_torque(q)[k]
    assert abs(gravity) > 1.0
    gains = PidGains(2000.0, 0.2, 0.0, abs(gravity) / 2)  # no D: the effort is the integral
    ctrl.set_gains(joint, gains)
    assert ctrl.gains(joint) == gains
    effort, _ = ctrl.control(q, np.zeros_like(q), np.zeros_like(q))
    assert effort[k] == pytest.approx(np.sign(gravity) * abs(gravity) / 2)


def test_without_an_integral_clamp_the_effort_limit_bounds_the_integral():
    config = dataclasses.replace(
        SimConfig(), gains={**SimConfig().gains, "j_grinder": PidGains(2.0, 0.01, 0.1)}
    )
    ctrl = controller(config=config)
    limit = read_urdf_joints(URDF_PATH.read_text())["j_grinder"].effort_limit
    assert ctrl.gains("j_grinder").i_clamp == limit


@pytest.mark.parametrize(
    ("command", "match"),
    [
        (lambda c: c.set_setpoint("j_elbow", 0.1), "unknown joint 'j_elbow'"),
        (lambda c: c.set_setpoint("j_shou_yaw", float("nan")), "not finite"),
        (lambda c: c.set_gains("j_elbow", PidGains(1.0, 0.0, 0.0)), "unknown joint"),
        (lambda c: c.gains("j_elbow"), "unknown joint"),
    ],
)
def test_bad_commands_raise_and_change_nothing(command, match):
    ctrl = controller()
    ctrl.reset(stowed(ctrl))
    before = ctrl.setpoint
    with pytest.raises(CommandError, match=match):
        command(ctrl)
    assert np.array_equal(ctrl.setpoint, before)
