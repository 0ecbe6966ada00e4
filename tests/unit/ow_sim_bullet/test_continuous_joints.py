"""The simulation's controllers with continuous joints (no pybullet): set-points and trajectories
of a continuous joint are never clipped and are followed the shorter way round, and its PID error
is wrapped, as ros_control's controllers treat OceanWATERS' continuous joints."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest

from ow_description.description import CONTINUOUS_JOINTS, EUROPA_GRAVITY, STOWED, URDF_PATH
from ow_sim_bullet.config import SimConfig
from ow_sim_bullet.joint_control import ClippedSetpoint, JointController
from ow_sim_bullet.trajectory import JointTrajectory
from ow_sim_bullet.urdf import physical_inertias, read_urdf_joints

DT = 0.01


def controller() -> JointController:
    text, _ = physical_inertias(URDF_PATH.read_text())
    model = pin.buildModelFromXML(text)
    model.gravity.linear = np.array([0.0, 0.0, -EUROPA_GRAVITY])
    ctrl = JointController(model, read_urdf_joints(text), SimConfig().gains, DT, True)
    ctrl.reset(np.array([STOWED.get(j, 0.0) for j in ctrl.names]))
    return ctrl


def test_the_controller_knows_the_continuous_joints():
    ctrl = controller()
    assert [n for n, c in zip(ctrl.names, ctrl.continuous, strict=True) if c] == [
        n for n in ctrl.names if n in CONTINUOUS_JOINTS
    ]


@pytest.mark.parametrize(
    ("joint", "requested"),
    [("j_prox_pitch", 7.87143), ("j_hand_yaw", -3.15905 - 4 * math.pi), ("j_scoop_yaw", 1e3)],
)
def test_a_continuous_setpoint_is_never_clipped_and_taken_the_shorter_way(joint, requested):
    ctrl = controller()
    k = ctrl.names.index(joint)
    before = float(ctrl.setpoint[k])
    assert ctrl.set_setpoint(joint, requested) is None
    applied = float(ctrl.setpoint[k])
    # The same angle, within half a turn of the set-point it replaces.
    assert abs(applied - before) <= math.pi + 1e-9
    assert math.remainder(applied - requested, 2 * math.pi) == pytest.approx(0.0, abs=1e-9)


def test_a_revolute_setpoint_is_still_clipped_onto_its_limit():
    ctrl = controller()
    clipped = ctrl.set_setpoint("j_shou_pitch", -0.5)
    assert clipped == ClippedSetpoint("j_shou_pitch", -0.5, -0.4, -0.4, 2.2)


def test_a_continuous_trajectory_a_turn_away_is_followed_the_shorter_way():
    """A j_hand_yaw trajectory from 0 to 0.3 rad written a whole turn up (2 pi .. 2 pi + 0.3):
    the hand turns 0.3 rad, not a turn and more, and nothing is reported clipped."""
    ctrl = controller()
    k = ctrl.names.index("j_hand_yaw")
    start = float(ctrl.setpoint[k])
    points = [[start + 2 * math.pi + 0.1], [start + 2 * math.pi + 0.3]]
    trajectory = JointTrajectory.build(["j_hand_yaw"], 0.0, [1.0, 2.0], points, None, ctrl.names)
    assert ctrl.set_trajectory(trajectory, 0.0) == []
    followed = []
    for step in range(round(2.5 / DT)):
        ctrl.follow(step * DT)
        followed.append(float(ctrl.setpoint[k]))
    assert max(abs(s - start) for s in followed) <= 0.3 + 1e-9
    assert followed[-1] == pytest.approx(start + 0.3)


def test_a_continuous_joint_a_whole_turn_from_its_setpoint_is_at_it():
    """The PID error of a continuous joint is wrapped: measured a whole turn away from its
    set-point, the joint gets the effort it gets at the set-point (no turn back); a revolute
    joint would be driven back."""
    ctrl_at, ctrl_turned = controller(), controller()
    q = ctrl_at.setpoint
    v = np.zeros_like(q)
    k = ctrl_at.names.index("j_scoop_yaw")
    turned = q.copy()
    turned[k] += 2 * math.pi
    effort_at, _ = ctrl_at.control(q, v, v)
    effort_turned, _ = ctrl_turned.control(turned, v, v)
    assert effort_turned[k] == pytest.approx(effort_at[k], abs=1e-9)
    # Half a turn and a bit: driven forward, the nearer way to the set-point's angle.
    ahead = q.copy()
    ahead[k] -= math.pi + 0.2
    effort_ahead, _ = controller().control(ahead, v, v)
    assert effort_ahead[k] < effort_at[k]
