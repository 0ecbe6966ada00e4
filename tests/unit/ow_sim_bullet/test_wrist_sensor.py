"""The wrist force/torque sensor and the tool-terrain contact it measures, against closed forms.

The sensor (``BulletSim.wrist_wrench``) is an ideal gravity- and inertia-compensated 6-axis sensor
at ``j_dist_pitch``: the external wrench on the links beyond the joint. Rigid-body dynamics fix
that wrench from the joints alone: with the scoop the only link touched, the arm's six joints obey
``tau + J^T w = RNEA(q, v, a)`` (``tau`` the motor and damping torques applied, ``J`` the scoop
link's Jacobian, ``a`` the joint accelerations over the step), so ``w = J^-T (RNEA(q, v, a) -
tau)``, and at rest ``w = J^-T (g(q) - tau)``. Both are computed here with an independent
pinocchio model of the URDF. The contacts obey Coulomb's law with ``terrain_friction``.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pinocchio as pin
import pybullet as pb
import pytest

from ow_description.description import (
    ARM_JOINTS,
    EUROPA_GRAVITY,
    SCOOP_ABOVE_GROUND,
    SCOOP_BELOW_GROUND,
    URDF_PATH,
)
from ow_sim_bullet.config import SimConfig
from ow_sim_bullet.sim_core import BulletSim
from ow_sim_bullet.terrains import flat
from ow_sim_bullet.tool_tracking import WRIST_FT_LINK
from ow_sim_bullet.trajectory import JointTrajectory

GROUND = -0.155
#: rad, the arm joints with the level scoop 5 cm into the ground (its tip at the surface at
#: SCOOP_BELOW_GROUND, 5 cm above it at SCOOP_ABOVE_GROUND).
PRESSED = {
    j: SCOOP_ABOVE_GROUND[j] + 2.0 * (SCOOP_BELOW_GROUND[j] - SCOOP_ABOVE_GROUND[j])
    for j in SCOOP_ABOVE_GROUND
}
#: rad/s, every joint slower than this: at rest.
REST_SPEED = 3e-3


def follow(sim: BulletSim, pose: dict[str, float], duration: float) -> None:
    """Start a linear move of the joints of ``pose`` to it over ``duration`` s."""
    joints = list(pose)
    sim.set_trajectory(
        JointTrajectory.build(
            joints, sim.time, [duration], [[pose[j] for j in joints]], None, sim.names
        )
    )


def run(sim: BulletSim, seconds: float) -> None:
    for _ in range(round(seconds / sim.dt)):
        sim.step()


def sensed(sim: BulletSim) -> tuple[np.ndarray, np.ndarray]:
    """The wrist sensor over the last step alone (both tools' means taken, as the node does)."""
    sim.tool_snapshot("scoop")
    sim.tool_snapshot("grinder")
    return sim.wrist_wrench()


class Dynamics:
    """An independent pinocchio model of the URDF on Europa (not the simulation's)."""

    def __init__(self, names: tuple[str, ...]) -> None:
        self.model = pin.buildModelFromUrdf(str(URDF_PATH))
        self.model.gravity.linear = np.array([0.0, 0.0, -EUROPA_GRAVITY])
        self.data = self.model.createData()
        # The simulation's joint order -> this model's coordinates.
        self.index = [self.model.joints[self.model.getJointId(j)].idx_q for j in names]
        self.arm = [self.model.joints[self.model.getJointId(j)].idx_v for j in ARM_JOINTS]

    def array(self, values: np.ndarray) -> np.ndarray:
        out = np.zeros(self.model.nq)
        out[self.index] = values
        return out

    def wrist_wrench(self, q: np.ndarray, needed: np.ndarray, applied: np.ndarray):
        """The wrench on the scoop that makes up ``needed - applied`` (N m, joint torques, this
        model's order), about the j_dist_pitch origin, in l_dist: (force N, torque N m)."""
        model, data = self.model, self.data
        scoop = model.getFrameId("l_scoop")
        jacobian = pin.computeFrameJacobian(model, data, q, scoop, pin.LOCAL_WORLD_ALIGNED)
        wrench = np.linalg.solve(jacobian[:, self.arm].T, (needed - applied)[self.arm])
        pin.framesForwardKinematics(model, data, q)
        X_dist = data.oMf[model.getFrameId(WRIST_FT_LINK)]
        force = wrench[:3]
        moment = wrench[3:] + np.cross(data.oMf[scoop].translation - X_dist.translation, force)
        return X_dist.rotation.T @ force, X_dist.rotation.T @ moment


@pytest.fixture()
def sim():
    simulation = BulletSim(SimConfig(), flat(GROUND))
    yield simulation
    simulation.close()


def test_the_wrist_sensor_reads_the_wrench_the_joints_balance(sim):
    """Driven 5 cm into solid ground and held there, the sensor reads at every step the wrench
    that Newton-Euler's equations of the arm's joints give (the impact, the push, the slips),
    and at rest the static wrench ``J^-T (g - tau)``: what the motors do not hold against
    gravity, the ground holds. In the air it reads zero: the links' weight is compensated."""
    dynamics = Dynamics(sim.names)
    follow(sim, SCOOP_ABOVE_GROUND, 8.0)
    run(sim, 10.0)
    sim.step()
    force, torque = sensed(sim)
    assert np.array_equal(force, np.zeros(3)) and np.array_equal(torque, np.zeros(3))

    follow(sim, PRESSED, 6.0)
    largest, worst_force, worst_torque = 0.0, 0.0, 0.0
    rest = None
    for _ in range(round(12.0 / sim.dt)):
        sim.step()
        sample = sim.sample
        force, torque = sensed(sim)
        sim.step()  # the velocity at the end of the step: its acceleration
        acceleration = (sim.sample.velocity - sample.velocity) / sim.dt
        sim.tool_snapshot("scoop")  # this second step's mean is not compared
        sim.tool_snapshot("grinder")
        q = dynamics.array(sample.position)
        applied = dynamics.array(sample.effort + sample.damping_effort)
        needed = pin.rnea(
            dynamics.model,
            dynamics.data,
            q,
            dynamics.array(sample.velocity),
            dynamics.array(acceleration),
        )
        expected_force, expected_torque = dynamics.wrist_wrench(q, needed, applied)
        largest = max(largest, float(np.linalg.norm(force)))
        worst_force = max(worst_force, float(np.linalg.norm(force - expected_force)))
        worst_torque = max(worst_torque, float(np.linalg.norm(torque - expected_torque)))
        if np.abs(sample.velocity).max() < REST_SPEED and np.linalg.norm(force) > 0.0:
            rest = (q, applied, force, torque)
    assert largest > 200.0  # a real push: OceanWATERS' guarded-move threshold
    assert worst_force < 1e-3  # N (measured: a few uN at up to 660 N)
    assert worst_torque < 1e-3  # N m

    assert rest is not None, "the pressed arm never came to rest"
    q, applied, force, torque = rest
    gravity = pin.computeGeneralizedGravity(dynamics.model, dynamics.data, q)
    static_force, static_torque = dynamics.wrist_wrench(q, gravity, applied)
    assert np.allclose(force, static_force, rtol=0.01, atol=0.5)
    assert np.allclose(torque, static_torque, rtol=0.01, atol=0.5)


@pytest.mark.parametrize("friction", [0.5, 0.8])
def test_the_scoop_slides_on_the_ground_by_coulombs_law(friction):
    """The scoop pressed on the ground and swept sideways: every contact force stays in the
    friction cone ``|f_t| <= mu f_n`` of ``terrain_friction`` and the slipping ones are on it."""
    sim = BulletSim(dataclasses.replace(SimConfig(), terrain_friction=friction), flat(GROUND))
    try:
        follow(sim, SCOOP_ABOVE_GROUND, 8.0)
        run(sim, 10.0)
        pressed = {
            j: SCOOP_ABOVE_GROUND[j] + 1.1 * (SCOOP_BELOW_GROUND[j] - SCOOP_ABOVE_GROUND[j])
            for j in SCOOP_ABOVE_GROUND
        }
        follow(sim, pressed, 3.0)
        run(sim, 5.0)
        follow(sim, {"j_shou_yaw": pressed["j_shou_yaw"] + 0.2}, 10.0)
        ratios = []
        for _ in range(round(8.0 / sim.dt)):
            sim.step()
            for contact in pb.getContactPoints(bodyA=sim.robot, physicsClientId=sim.client):
                normal, first, second = contact[9], contact[10], contact[12]
                if normal > 1.0:  # N
                    ratios.append(np.hypot(first, second) / normal)
        assert len(ratios) > 100
        assert max(ratios) <= friction * (1.0 + 1e-6)
        assert max(ratios) == pytest.approx(friction, rel=0.01)
    finally:
        sim.close()
