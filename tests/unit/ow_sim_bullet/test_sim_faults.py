"""Injected faults in the simulation core, without ROS: a locked joint does not move whatever its
motor does, a released one is held where it is, the F/T sensor faults change its output
reproducibly (ow_sim_bullet.faults through BulletSim.apply_faults)."""

from __future__ import annotations

import numpy as np
import pytest

from ow_faults.injection import LOCKABLE_JOINTS, FaultSet
from ow_sim_bullet.config import SimConfig
from ow_sim_bullet.faults import WristFaults
from ow_sim_bullet.sim_core import BulletSim
from ow_sim_bullet.terrains import flat


def run(sim: BulletSim, seconds: float) -> None:
    for _ in range(round(seconds / sim.dt)):
        sim.step()


def position(sim: BulletSim, joint: str) -> float:
    return float(sim.sample.position[sim.names.index(joint)])


@pytest.fixture()
def sim():
    simulation = BulletSim(SimConfig(), flat(-0.155))
    run(simulation, 0.2)
    yield simulation
    simulation.close()


@pytest.mark.parametrize("joint", ["j_shou_pitch", "j_shou_yaw", "j_scoop_yaw", "j_ant_tilt"])
def test_a_locked_joint_does_not_move_at_full_motor_torque(sim, joint):
    k = sim.names.index(joint)
    start = position(sim, joint)
    locked, released = sim.apply_faults(
        FaultSet.from_dict({f"{joint[2:]}_joint_locked_failure": True})
    )
    assert locked == {joint} and not released
    sim.set_setpoint(joint, start + 1.0)  # 1 rad away
    run(sim, 2.0)
    # the motor pushes with p * 1 rad or all it can ...
    limit = min(sim.controller._effort_limit[k], sim.gains(joint).p * 1.0)
    assert abs(sim.sample.effort[k]) >= 0.99 * limit
    assert abs(position(sim, joint) - start) < 1e-4  # ... and the joint stays
    # another joint still follows its commands (within 1e-2 rad while the locked joint's motor
    # pushes at its limit: the controllers' implicit step does not model the lock exactly)
    other = "j_hand_yaw" if joint in ("j_shou_yaw", "j_shou_pitch", "j_ant_tilt") else "j_shou_yaw"
    start_other = position(sim, other)
    sim.set_setpoint(other, start_other + 0.2)
    run(sim, 5.0)
    assert position(sim, other) == pytest.approx(start_other + 0.2, abs=1e-2)


def test_without_the_lock_the_same_command_moves_the_joint(sim):
    start = position(sim, "j_shou_pitch")
    sim.set_setpoint("j_shou_pitch", start - 0.1)
    run(sim, 2.0)
    assert position(sim, "j_shou_pitch") == pytest.approx(start - 0.1, abs=1e-3)


def test_a_released_joint_is_held_where_it_is_then_follows_again(sim):
    joint = "j_shou_pitch"
    start = position(sim, joint)
    sim.apply_faults(FaultSet(shou_pitch_joint_locked_failure=True))
    sim.set_setpoint(joint, start - 0.3)
    run(sim, 1.0)
    locked, released = sim.apply_faults(FaultSet())
    assert released == {joint} and not locked
    run(sim, 1.0)
    # held at the locked position: the wound-up integral does not throw it
    assert position(sim, joint) == pytest.approx(start, abs=2e-3)
    sim.set_setpoint(joint, start - 0.1)
    run(sim, 2.0)
    assert position(sim, joint) == pytest.approx(start - 0.1, abs=1e-3)


def test_flags_name_every_lockable_joint_alphabetically(sim):
    sim.apply_faults(
        FaultSet(ant_pan_joint_locked_failure=True, hand_yaw_joint_locked_failure=True)
    )
    names, flags = sim.locks.flags()
    assert list(names) == sorted(names) == list(LOCKABLE_JOINTS)
    assert {n for n, f in zip(names, flags, strict=True) if f} == {"j_ant_pan", "j_hand_yaw"}


def test_zero_signal_zeroes_the_wrist_sensor_only_while_enabled():
    wrist = WristFaults(seed=0)
    force, torque = np.array([1.0, 2.0, 3.0]), np.array([0.1, 0.2, 0.3])
    wrist.set(FaultSet(zero_signal_failure=True))  # enable false: no effect
    assert np.array_equal(wrist.apply(force, torque, 5)[0], force)
    wrist.set(FaultSet(enable=True, zero_signal_failure=True))
    f, t = wrist.apply(force, torque, 5)
    assert not f.any() and not t.any()


def test_bias_and_noise_have_the_asked_mean_and_spread_and_repeat():
    wrist = WristFaults(seed=7)
    wrist.set(FaultSet(enable=True, signal_bias_failure=0.5, signal_noise_failure=0.2))
    zero = np.zeros(3)
    samples = np.array([np.concatenate(wrist.apply(zero, zero, step)) for step in range(4000)])
    assert samples.mean() == pytest.approx(0.5, abs=0.01)
    assert samples.std() == pytest.approx(0.2, rel=0.03)
    again = WristFaults(seed=7)
    again.set(FaultSet(enable=True, signal_bias_failure=0.5, signal_noise_failure=0.2))
    assert np.array_equal(np.concatenate(again.apply(zero, zero, 123)), samples[123])
    other = WristFaults(seed=8)
    other.set(FaultSet(enable=True, signal_bias_failure=0.5, signal_noise_failure=0.2))
    assert not np.array_equal(np.concatenate(other.apply(zero, zero, 123)), samples[123])


def test_the_sim_wrist_output_carries_the_bias(sim):
    true_force, _ = sim.tracker.wrist_wrench(sim.sample)
    sim.apply_faults(FaultSet(enable=True, signal_bias_failure=-0.75))
    force, _ = sim.wrist_wrench()
    assert np.allclose(force, true_force - 0.75)
