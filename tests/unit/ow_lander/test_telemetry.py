"""OceanWATERS' joint telemetry from joint states (no ROS): orders by name, finite differences,
the scoop pose against an independent forward kinematics of the URDF."""

from __future__ import annotations

import dataclasses
import math
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from ow_description.description import ALL_JOINTS, URDF_PATH
from ow_lander.errors import ConfigError
from ow_lander.telemetry.config import TelemetryConfig
from ow_lander.telemetry.joints import (
    PAN_TILT_JOINTS,
    TELEMETRY_ARM_JOINTS,
    RateGate,
    Telemetry,
    TelemetryBuilder,
    TelemetryError,
)

#: docs/owl_msgs.md, spelled out rather than derived.
OCEANWATERS_ARM_ORDER = (
    "j_dist_pitch",
    "j_grinder",
    "j_hand_yaw",
    "j_prox_pitch",
    "j_scoop_yaw",
    "j_shou_pitch",
    "j_shou_yaw",
)


@pytest.fixture(scope="module")
def builder():
    return TelemetryBuilder()


def numbered_state(names):
    """Each joint's position, velocity and effort encode the joint, whatever its index."""
    code = {j: k for k, j in enumerate(sorted(ALL_JOINTS))}
    return (
        [0.1 * code[n] for n in names],
        [0.01 * code[n] for n in names],
        [1.0 * code[n] for n in names],
    )


def test_the_orders_are_oceanwaters():
    assert TELEMETRY_ARM_JOINTS == OCEANWATERS_ARM_ORDER
    assert PAN_TILT_JOINTS == ("j_ant_pan", "j_ant_tilt")


@pytest.mark.parametrize(
    "names",
    [
        sorted(ALL_JOINTS),  # OceanWATERS' /joint_states order
        list(ALL_JOINTS),  # URDF order
        list(reversed(ALL_JOINTS)),
        [
            "j_shou_yaw",
            "j_ant_tilt",
            "j_grinder",
            "j_scoop_yaw",
            "j_ant_pan",
            "j_prox_pitch",
            "j_hand_yaw",
            "j_dist_pitch",
            "j_shou_pitch",
        ],
    ],
)
def test_arrays_follow_the_telemetry_order_whatever_the_message_order(names):
    builder = TelemetryBuilder()
    position, velocity, effort = numbered_state(names)
    t = builder.update(1.0, names, position, velocity, effort)
    code = {j: k for k, j in enumerate(sorted(ALL_JOINTS))}
    assert np.allclose(t.positions, [0.1 * code[j] for j in OCEANWATERS_ARM_ORDER])
    assert np.allclose(t.velocities, [0.01 * code[j] for j in OCEANWATERS_ARM_ORDER])
    assert np.allclose(t.torques, [1.0 * code[j] for j in OCEANWATERS_ARM_ORDER])
    assert np.allclose(t.pan_tilt, [0.1 * code["j_ant_pan"], 0.1 * code["j_ant_tilt"]])
    assert t.stamp == 1.0


def test_a_new_name_order_mid_stream_is_followed():
    builder = TelemetryBuilder()
    for k, names in enumerate([sorted(ALL_JOINTS), list(ALL_JOINTS), sorted(ALL_JOINTS)]):
        position, velocity, effort = numbered_state(names)
        t = builder.update(0.01 * k, names, position, velocity, effort)
        assert t.positions[OCEANWATERS_ARM_ORDER.index("j_shou_yaw")] == pytest.approx(0.8)


def test_accelerations_are_the_finite_difference_of_velocities_between_stamps():
    builder = TelemetryBuilder()
    names = sorted(ALL_JOINTS)
    zeros = [0.0] * len(names)
    rng = np.random.default_rng(3)
    stamps = [10.0, 10.01, 10.02, 10.05, 10.06]
    velocities = rng.normal(size=(len(stamps), len(names)))
    accelerations = []
    for stamp, v in zip(stamps, velocities, strict=True):
        accelerations.append(builder.update(stamp, names, zeros, v.tolist(), zeros).accelerations)
    arm = [names.index(j) for j in OCEANWATERS_ARM_ORDER]
    assert np.all(accelerations[0] == 0.0)  # no previous state
    for k in range(1, len(stamps)):
        expected = (velocities[k, arm] - velocities[k - 1, arm]) / (stamps[k] - stamps[k - 1])
        assert np.allclose(accelerations[k], expected, rtol=1e-9)


def test_a_skipped_state_counts_for_the_next_accelerations_all_the_same():
    names = sorted(ALL_JOINTS)
    zeros = [0.0] * len(names)
    rng = np.random.default_rng(4)
    states = [(10.0 + 0.01 * k, rng.normal(size=len(names)).tolist()) for k in range(9)]
    every, sparse = TelemetryBuilder(), TelemetryBuilder()
    for k, (stamp, v) in enumerate(states):
        full = every.update(stamp, names, zeros, v, zeros)
        if k % 3 != 2:
            sparse.skip(stamp, names, zeros, v, zeros)
            continue
        kept = sparse.update(stamp, names, zeros, v, zeros)
        for field in dataclasses.fields(Telemetry):
            assert np.array_equal(getattr(kept, field.name), getattr(full, field.name))
        assert np.any(kept.accelerations != 0.0)
    # A state without velocities, skipped, leaves no previous one: the next accelerations are 0.
    sparse.skip(11.0, names, zeros)
    assert np.all(sparse.update(11.01, names, zeros, states[0][1], zeros).accelerations == 0.0)


def test_a_bad_skipped_state_is_refused_and_the_previous_one_kept():
    names = sorted(ALL_JOINTS)
    zeros = [0.0] * len(names)
    builder = TelemetryBuilder()
    builder.update(10.0, names, zeros, [1.0] * len(names), zeros)
    with pytest.raises(TelemetryError, match="8 velocity values for 9 joints"):
        builder.skip(10.01, names, zeros, [5.0] * 8, zeros)
    t = builder.update(10.02, names, zeros, [2.0] * len(names), zeros)
    assert np.allclose(t.accelerations, 1.0 / 0.02)


@pytest.mark.parametrize("second_stamp", [10.0, 9.5])
def test_a_stamp_that_does_not_increase_gives_zero_acceleration_and_restarts(second_stamp):
    builder = TelemetryBuilder()
    names = sorted(ALL_JOINTS)
    zeros = [0.0] * len(names)
    builder.update(10.0, names, zeros, [1.0] * len(names), zeros)
    t = builder.update(second_stamp, names, zeros, [2.0] * len(names), zeros)
    assert np.all(t.accelerations == 0.0)
    t = builder.update(second_stamp + 0.5, names, zeros, [3.0] * len(names), zeros)
    assert np.allclose(t.accelerations, 2.0)  # from the second state, (3 - 2) / 0.5


def test_missing_velocities_and_efforts_are_nan_not_zero(builder):
    names = sorted(ALL_JOINTS)
    t = builder.update(1.0, names, [0.0] * len(names))
    assert np.all(np.isnan(t.velocities)) and np.all(np.isnan(t.torques))
    assert np.all(t.accelerations == 0.0)


@pytest.mark.parametrize(
    ("names", "position", "message"),
    [
        (sorted(ALL_JOINTS)[1:], [0.0] * 8, "joint state lacks joint(s) ['j_ant_pan']"),
        (sorted(ALL_JOINTS), [0.0] * 8, "joint state has 8 position values for 9 joints"),
    ],
)
def test_bad_joint_states_are_refused_with_the_reason(names, position, message):
    with pytest.raises(TelemetryError) as error:
        TelemetryBuilder().update(1.0, names, position)
    assert message in str(error.value)


# ------------------------------------------------------------- independent forward kinematics
def _rpy(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """URDF fixed-axis roll-pitch-yaw: R = Rz(yaw) Ry(pitch) Rx(roll)."""
    cr, sr, cp, sp, cy, sy = (f(a) for a in (roll, pitch, yaw) for f in (math.cos, math.sin))
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return rz @ ry @ rx


def _about(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rodrigues' rotation by ``angle`` about the unit ``axis``."""
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + math.sin(angle) * k + (1 - math.cos(angle)) * k @ k


def urdf_pose(link: str, angles: dict[str, float]) -> np.ndarray:
    """X_base_link of ``link`` by walking the URDF's joints with numpy (no pinocchio)."""
    joints = {j.find("child").get("link"): j for j in ET.parse(URDF_PATH).getroot().iter("joint")}
    chain = []
    while link in joints:
        chain.append(joints[link])
        link = joints[link].find("parent").get("link")
    X = np.eye(4)
    for joint in reversed(chain):
        origin = joint.find("origin")
        step = np.eye(4)
        step[:3, :3] = _rpy(*(float(v) for v in origin.get("rpy", "0 0 0").split()))
        step[:3, 3] = [float(v) for v in origin.get("xyz", "0 0 0").split()]
        if joint.get("type") != "fixed":
            axis = np.array([float(v) for v in joint.find("axis").get("xyz").split()])
            motion = np.eye(4)
            motion[:3, :3] = _about(axis / np.linalg.norm(axis), angles[joint.get("name")])
            step = step @ motion
        X = X @ step
    return X


def _quaternion_matrix(x: float, y: float, z: float, w: float) -> np.ndarray:
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def test_the_arm_pose_is_l_scoop_in_base_link_by_an_independent_fk(builder):
    rng = np.random.default_rng(11)
    names = sorted(ALL_JOINTS)
    for _ in range(20):
        angles = {j: float(rng.uniform(-1.5, 1.5)) for j in names}
        angles["j_shou_pitch"] = float(rng.uniform(0.05, 2.2))
        t = builder.update(0.0, names, [angles[j] for j in names])
        expected = urdf_pose("l_scoop", angles)
        assert np.allclose(t.scoop_position, expected[:3, 3], atol=1e-9)
        assert np.linalg.norm(t.scoop_orientation) == pytest.approx(1.0)
        assert np.allclose(_quaternion_matrix(*t.scoop_orientation), expected[:3, :3], atol=1e-9)


def test_all_joints_zero_put_the_scoop_where_the_spec_says(builder):
    """Spec section 1.2: with all joints 0, the l_scoop origin is at (2.266, 0.025, -0.043)."""
    names = sorted(ALL_JOINTS)
    t = builder.update(0.0, names, [0.0] * len(names))
    assert np.allclose(t.scoop_position, [2.266, 0.025, -0.043], atol=1e-3)


def test_the_rate_gate_passes_the_first_stamp_of_each_period_only():
    gate = RateGate(10.0)
    stamps = [0.0, 0.01, 0.09, 0.1, 0.15, 0.2, 0.31, 0.35, 0.4]
    assert [t for t in stamps if gate.passes(t)] == [0.0, 0.1, 0.2, 0.31, 0.4]
    # A stamp on a multiple of the period that floating point puts a hair below it still passes.
    gate = RateGate(10.0)
    assert [gate.passes(k * 0.01) for k in range(31)].count(True) == 4  # 0, 0.1, 0.2, 0.3
    every = RateGate(0.0)
    assert all(every.passes(t) for t in stamps)
    # due() says what passes() would, without taking the stamp.
    gate = RateGate(10.0)
    dues = [(gate.due(t), gate.due(t), gate.passes(t)) for t in stamps]
    assert [d for d, again, _ in dues] == [p for _, _, p in dues] == [a for _, a, _ in dues]


def test_telemetry_config_defaults_and_refusals():
    assert TelemetryConfig.from_dict({}).rate_hz == 0.0
    assert TelemetryConfig.from_dict({"rate_hz": 20}).rate_hz == 20.0
    with pytest.raises(ConfigError, match=r"telemetry/rate_hz = -1"):
        TelemetryConfig.from_dict({"rate_hz": -1.0})
    with pytest.raises(ConfigError, match=r"telemetry/rate"):
        TelemetryConfig.from_dict({"rate": 5.0})
