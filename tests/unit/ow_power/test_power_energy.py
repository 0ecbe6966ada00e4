"""Work-energy balance helpers (the physics acceptance's bookkeeping), without ROS."""

import numpy as np
import pinocchio as pin
import pytest

from ow_description.description import EUROPA_GRAVITY, URDF_PATH
from ow_description.model import LanderModel
from ow_power.energy import ArmEnergyModel, EnergyBalance, dissipated_work_j
from ow_power.errors import PowerError


def test_damping_and_friction_losses_in_closed_form():
    t = np.linspace(0.0, 2.0, 201)
    velocity = np.column_stack([np.full_like(t, 0.1), np.full_like(t, -0.2)])
    # 50 * 0.01 + 10 * 0.04 = 0.9 W viscous, 2 * 0.1 + 1 * 0.2 = 0.4 W Coulomb, for 2 s.
    loss = dissipated_work_j(t, velocity, damping=[50.0, 10.0], friction=[2.0, 1.0])
    assert loss == pytest.approx(2.6)


def test_balance_relative_error():
    assert EnergyBalance(105.0, 80.0, 0.0, 20.0).relative_error == pytest.approx(0.05)
    assert EnergyBalance(0.0, 0.0, 0.0, 0.0).relative_error == 0.0


def test_inverse_dynamics_torques_balance_potential_kinetic_and_damping():
    """Torques from pinocchio's RNEA plus URDF damping, integrated like the power node does."""
    arm = ArmEnergyModel()
    model = pin.buildModelFromUrdf(str(URDF_PATH))
    model.gravity.linear = np.array([0.0, 0.0, -EUROPA_GRAVITY])  # the simulation's gravity
    data = model.createData()
    names = [model.names[i] for i in range(1, model.njoints)]
    # A 4 s lift of the shoulder and proximal pitch joints with a smooth (min-jerk) profile.
    q0, q1 = pin.neutral(model), pin.neutral(model)
    q0[model.joints[model.getJointId("j_shou_pitch")].idx_q] = 0.3
    q1[model.joints[model.getJointId("j_shou_pitch")].idx_q] = 1.2
    q1[model.joints[model.getJointId("j_prox_pitch")].idx_q] = -0.8
    t = np.linspace(0.0, 4.0, 401)  # 100 Hz
    s = t / 4.0
    shape, dshape, ddshape = (
        10 * s**3 - 15 * s**4 + 6 * s**5,
        (30 * s**2 - 60 * s**3 + 30 * s**4) / 4.0,
        (60 * s - 180 * s**2 + 120 * s**3) / 16.0,
    )
    dq = q1 - q0
    q, v, a = q0 + np.outer(shape, dq), np.outer(dshape, dq), np.outer(ddshape, dq)
    tau = np.array([pin.rnea(model, data, q[k], v[k], a[k]) for k in range(t.size)])
    tau += v * model.damping
    # Joint states list joints in a different order than the URDF: matched by name.
    order = np.argsort(names)
    balance = arm.balance(t, [names[i] for i in order], q[:, order], v[:, order], tau[:, order])
    expected_rise = pin.computePotentialEnergy(model, data, q[-1]) - pin.computePotentialEnergy(
        model, data, q[0]
    )
    assert balance.potential_rise_j == pytest.approx(expected_rise)
    assert balance.potential_rise_j > 10.0  # the arm is lifted
    assert balance.kinetic_rise_j == pytest.approx(0.0, abs=1e-9)  # at rest at both ends
    assert balance.dissipated_j > 0.0
    assert balance.relative_error < 0.01


def test_potential_energy_is_europas_like_the_simulation_and_the_lander_model():
    """pinocchio's default gravity is the Earth's; the balance must use the simulation's."""
    arm = ArmEnergyModel()
    lander = LanderModel()
    q = lander.q_from({"j_shou_pitch": 1.2, "j_prox_pitch": -0.8})
    names = [lander.model.names[i] for i in range(1, lander.model.njoints)]
    position = [q[lander.index(n)] for n in names]
    assert arm.gravity == EUROPA_GRAVITY
    assert arm.potential_energy_j(names, position) == pytest.approx(lander.potential_energy(q))
    moon = ArmEnergyModel(gravity=1.62)
    assert moon.potential_energy_j(names, position) == pytest.approx(
        lander.potential_energy(q) * 1.62 / EUROPA_GRAVITY
    )


def test_kinetic_energy_is_half_v_m_v_with_joints_matched_by_name():
    arm = ArmEnergyModel()
    model = pin.buildModelFromUrdf(str(URDF_PATH))
    data = model.createData()
    names = ["j_scoop_yaw", "j_shou_pitch", "not_a_joint", "j_prox_pitch"]
    position, velocity = [0.2, 1.2, 5.0, -0.8], [0.3, -0.4, 9.0, 0.5]
    q, v = pin.neutral(model), np.zeros(model.nv)
    for name, p, w in zip(names, position, velocity, strict=True):
        if model.existJointName(name):
            q[model.joints[model.getJointId(name)].idx_q] = p
            v[model.joints[model.getJointId(name)].idx_v] = w
    expected = 0.5 * v @ pin.crba(model, data, q) @ v
    assert expected > 0.0
    assert arm.kinetic_energy_j(names, position, velocity) == pytest.approx(expected, rel=1e-12)


def test_non_finite_gravity_is_an_error():
    with pytest.raises(PowerError, match="gravity=nan m/s\\^2 is not a finite number"):
        ArmEnergyModel(gravity=float("nan"))


def test_balance_with_the_simulations_damping_torque():
    """Losses from a recorded damping torque, -sum tau_d * w * dt: -5 N m x 0.1 rad/s for 1 s is
    0.5 J, what the motor's 5 N m did (position held fixed: no potential or kinetic rise)."""
    arm = ArmEnergyModel()
    t = np.linspace(0.0, 1.0, 101)
    velocity = np.full((t.size, 1), 0.1)
    balance = arm.balance(
        t, ["j_ant_pan"], np.zeros((t.size, 1)), velocity, np.full((t.size, 1), 5.0),
        damping_effort=np.full((t.size, 1), -5.0),
    )  # fmt: skip
    assert balance.dissipated_j == pytest.approx(0.5)
    assert balance.work_j == pytest.approx(0.5)
    with pytest.raises(PowerError, match=r"damping_effort has shape \(101, 2\)"):
        arm.balance(
            t, ["j_ant_pan"], velocity, velocity, velocity, damping_effort=np.zeros((101, 2))
        )


def test_balance_needs_two_samples():
    with pytest.raises(PowerError, match="at least two joint states, got 1"):
        ArmEnergyModel().balance([0.0], ["j_shou_yaw"], [[0.0]], [[0.0]], [[0.0]])


def test_unknown_urdf_is_an_error(tmp_path):
    with pytest.raises(PowerError, match="cannot load URDF"):
        ArmEnergyModel(tmp_path / "none.urdf")
