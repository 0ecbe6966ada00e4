"""Simulation options: the controllers' gravity feed-forward and rigid tool-terrain contact.

Gravity feed-forward (``gravity_feedforward``), checked against the statics of a PID position
controller.

Without feed-forward (the paper's pure PID) a joint holds a static load only with a position error:
``Kp e + I = tau_g(q)``, with ``I`` the integral term (preloaded at start with the stowed pose's
gravity torque, and slow with the paper's gains). At full reach the arm therefore rests below its
set-point, by millimetres at the scoop. With feed-forward the controllers add ``tau_g(q)`` of the
measured pose and the arm rests at its set-point.

Without rigid contact (``tool_contact: false``) the scoop passes through the terrain, carving it,
and feels no Bullet contact force: only a terrain-force model acts on it.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pinocchio as pin
import pybullet as pb
import pytest

from ow_description.description import ARM_JOINTS, SCOOP_ABOVE_GROUND, SCOOP_BELOW_GROUND, URDF_PATH
from ow_sim_bullet.config import SimConfig
from ow_sim_bullet.sim_core import BulletSim
from ow_sim_bullet.terrains import flat
from ow_sim_bullet.trajectory import JointTrajectory

#: s, the move to the reaching pose, then the wait until it is at rest.
MOVE_S, SETTLE_S = 5.0, 10.0
#: the joints that carry the arm's weight.
PITCH_JOINTS = ("j_shou_pitch", "j_prox_pitch", "j_dist_pitch")
#: rad/s, every joint slower than this: at rest.
REST_SPEED = 3e-3


class Independent:
    """An independent pinocchio model of the URDF on Europa: gravity torques, scoop tip."""

    def __init__(self) -> None:
        self.model = pin.buildModelFromUrdf(str(URDF_PATH))
        self.model.gravity.linear = np.array([0.0, 0.0, -1.315])
        self.data = self.model.createData()

    def q(self, values: dict[str, float]) -> np.ndarray:
        q = np.zeros(self.model.nq)
        for name, value in values.items():
            q[self.model.joints[self.model.getJointId(name)].idx_q] = value
        return q

    def gravity(self, values: dict[str, float]) -> dict[str, float]:
        tau = pin.computeGeneralizedGravity(self.model, self.data, self.q(values))
        return {
            self.model.names[i]: float(tau[self.model.joints[i].idx_v])
            for i in range(1, self.model.njoints)
        }

    def tip(self, values: dict[str, float]) -> np.ndarray:
        pin.framesForwardKinematics(self.model, self.data, self.q(values))
        return self.data.oMf[self.model.getFrameId("l_scoop_tip")].translation.copy()


def reach(feedforward: bool) -> tuple[BulletSim, dict[str, float], dict[str, float]]:
    """Move a fresh simulation to SCOOP_ABOVE_GROUND (full reach) and let it come to rest;
    return it, the pose at start and the pose at rest."""
    config = dataclasses.replace(SimConfig(), gravity_feedforward=feedforward)
    sim = BulletSim(config, flat(-0.6))
    start = dict(zip(sim.names, sim.sample.position.tolist(), strict=True))
    joints = list(ARM_JOINTS)
    target = [[SCOOP_ABOVE_GROUND[j] for j in joints]]
    sim.set_trajectory(JointTrajectory.build(joints, sim.time, [MOVE_S], target, None, sim.names))
    for _ in range(round((MOVE_S + SETTLE_S) / sim.dt)):
        sim.step()
    rest = dict(zip(sim.names, sim.sample.position.tolist(), strict=True))
    return sim, start, rest


def press_scoop_down(sim: BulletSim, settle: float) -> None:
    """Scoop above the ground at full reach, then the pose with it 5 cm below the surface; each
    move followed by ``settle`` seconds."""
    joints = list(ARM_JOINTS)
    for pose, duration in ((SCOOP_ABOVE_GROUND, 8.0), (SCOOP_BELOW_GROUND, 4.0)):
        target = [[pose[j] for j in joints]]
        sim.set_trajectory(
            JointTrajectory.build(joints, sim.time, [duration], target, None, sim.names)
        )
        for _ in range(round((duration + settle) / sim.dt)):
            sim.step()


@pytest.fixture(scope="module")
def independent() -> Independent:
    return Independent()


def test_with_feedforward_the_arm_rests_at_its_setpoint(independent, record_property):
    sim, _, rest = reach(feedforward=True)
    try:
        error = {j: rest[j] - SCOOP_ABOVE_GROUND[j] for j in ARM_JOINTS}
        target = {**rest, **SCOOP_ABOVE_GROUND}
        tip_error = independent.tip(rest) - independent.tip(target)
        record_property("joint_error_mrad", {j: round(1e3 * e, 4) for j, e in error.items()})
        record_property("tip_error_mm", (1e3 * tip_error).round(3).tolist())
        # The pitch joints carry the gravity load: they rest at their set-points. (Every joint
        # is off by what its integral term wound up while tracking the move, which decays with
        # the time constant Kp/Ki: 0.7 mrad at the shoulder yaw, 100 s.)
        assert max(abs(error[j]) for j in PITCH_JOINTS) < 5e-5, error
        assert max(abs(e) for e in error.values()) < 1e-3, error
        assert abs(tip_error[2]) < 1e-4, tip_error
        # The motors still carry the whole gravity load (feed-forward plus PID).
        effort = dict(zip(sim.names, sim.sample.effort.tolist(), strict=True))
        expected = independent.gravity(rest)
        for joint in PITCH_JOINTS:
            assert effort[joint] == pytest.approx(expected[joint], rel=0.02), joint
    finally:
        sim.close()


def test_without_feedforward_the_arm_sags_by_the_pid_statics(independent, record_property):
    """Pure PID: the error at rest is (tau_g(reach) - I) / Kp, I ~ tau_g(stowed) (preloaded)."""
    sim, start, rest = reach(feedforward=False)
    try:
        g_rest, g_start = independent.gravity(rest), independent.gravity(start)
        sags = {}
        for joint in PITCH_JOINTS:
            kp = sim.gains(joint).p
            expected = -(g_rest[joint] - g_start[joint]) / kp
            sags[joint] = rest[joint] - SCOOP_ABOVE_GROUND[joint]
            # The integral term moves a little over 15 s (Ki * error * t, a few percent).
            assert sags[joint] == pytest.approx(expected, rel=0.1, abs=5e-5), joint
        target = {**rest, **SCOOP_ABOVE_GROUND}
        drop = independent.tip(target)[2] - independent.tip(rest)[2]
        record_property("sag_mrad", {j: round(1e3 * s, 3) for j, s in sags.items()})
        record_property("tip_drop_mm", round(float(1e3 * drop), 3))
        assert drop > 1e-3  # millimetres at the scoop: why the feed-forward is on by default
    finally:
        sim.close()


def test_without_tool_contact_the_scoop_cuts_through_the_terrain_without_contact_force():
    config = dataclasses.replace(SimConfig(), tool_contact=False)
    sim = BulletSim(config, flat(-0.155))
    try:
        joints = list(ARM_JOINTS)
        press_scoop_down(sim, settle=1.0)
        below = sim.tool_snapshot("scoop")
        # The arm reached the pose the rigid terrain would have stopped it short of, untouched.
        error = [SCOOP_BELOW_GROUND[j] - sim.sample.position[sim.names.index(j)] for j in joints]
        assert np.abs(error).max() < 1e-3
        assert np.allclose(below.force, 0.0) and np.allclose(below.torque, 0.0)
        assert below.tip[2] < -0.155 - 0.02
        # The terrain around the tool was carved down to it.
        assert sim.terrain_height(below.tip[0], below.tip[1]) < -0.155 - 0.01
    finally:
        sim.close()


def test_a_scoop_pressed_on_hard_ground_takes_the_motor_torque(independent, record_property):
    """At rest with the scoop pressed on ground too hard to carve, each joint's motor torque
    less its gravity torque is held by the contact: effort - tau_g = -J^T f (the contact forces
    from Bullet, mapped with an independent pinocchio model), and the dampers carry nothing.
    (The implicit dampers once predicted the blocked joints moving and cancelled the motors.)
    The statics hold at rest: the scoop pressed into the ground at full reach slips now and then
    (stick-slip), and in a slip the links' inertia takes a share, so the check waits for a step
    with every joint still."""
    config = dataclasses.replace(
        SimConfig(), terrain_yield_force=1e6, carve_full_force=2e6, carve_step=0.0
    )
    sim = BulletSim(config, flat(-0.155))
    try:
        press_scoop_down(sim, settle=3.0)
        for _ in range(round(3.0 / sim.dt)):
            if np.abs(sim.sample.velocity).max() < REST_SPEED:
                break
            sim.step()
        sample = sim.sample
        assert np.abs(sample.velocity).max() < REST_SPEED, "the pressed arm never came to rest"
        values = dict(zip(sim.names, sample.position.tolist(), strict=True))
        model, data = independent.model, independent.data
        q = independent.q(values)
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacements(model, data)
        contact = np.zeros(model.nv)
        for c in pb.getContactPoints(bodyA=sim.robot, physicsClientId=sim.client):
            force = np.array(c[7]) * c[9] + np.array(c[11]) * c[10] + np.array(c[13]) * c[12]
            link = next(name for name, index in sim.link_index.items() if index == c[3])
            fid = model.getFrameId(link)
            point = np.array(c[5])
            origin = data.oMf[fid].translation
            jacobian = pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED)
            contact += jacobian.T @ np.concatenate([force, np.cross(point - origin, force)])
        gravity = independent.gravity(values)
        effort = dict(zip(sim.names, sample.effort.tolist(), strict=True))
        damping = dict(zip(sim.names, sample.damping_effort.tolist(), strict=True))
        held = {}
        for joint in PITCH_JOINTS:
            k = model.joints[model.getJointId(joint)].idx_v
            held[joint] = (effort[joint] - gravity[joint], float(-contact[k]), damping[joint])
        record_property("motor_minus_gravity_vs_contact_Nm", held)
        loads = [abs(c) for _, c, _ in held.values()]
        assert max(loads) > 1.0  # the scoop is really pressed on the ground
        for joint, (motor, contact_torque, damper) in held.items():
            assert abs(damper) < 0.05 * max(loads), (joint, damper)
            assert motor == pytest.approx(contact_torque, rel=0.05, abs=0.05), joint
    finally:
        sim.close()
