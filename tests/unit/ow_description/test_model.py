"""The lander model (ow_description.model) against results derived independently of pinocchio."""

import coal
import numpy as np
import pybullet as pb
import pytest

from ow_description.description import (
    ARM_JOINTS,
    DEFAULT_GROUND_Z,
    EUROPA_GRAVITY,
    STOWED,
    UNSTOWED,
    URDF_PATH,
)
from ow_description.errors import IKError, ModelError
from ow_description.model import LanderModel
from ow_description.terrain import HeightMap


@pytest.fixture(scope="module")
def model():
    return LanderModel()


# --------------------------------------------------------------------------------------------
# Forward kinematics, derived by hand from the joint table (spec section 1.2), not from the URDF.
#
# A URDF joint places its child at T(origin xyz) * R(rpy) * Rot(axis, q), with rpy the fixed-axis
# roll-pitch-yaw, R = Rz(yaw) Ry(pitch) Rx(roll). The chain to the scoop tip is
#   base -> shou: xyz (0.79, 0.175, 0.27), rpy (-3.1416, 0, 0), axis -z
#   shou -> prox: xyz (0.16, 0, 0),        rpy (1.5708, 0, 0),  axis -z
#   prox -> dist: xyz (0.53, 0, 0),        rpy (0, 0, 0),       axis -z
#   dist -> wrist: xyz (0.586, 0, -0.15),  rpy (3.1416, 0, 1.5708), axis +z
#   wrist -> hand: xyz (0.163, 0.2, 0),    rpy (1.5708, 0, 0),  axis -z
#   hand -> scoop: xyz (0.15, 0, 0),       rpy (1.5708, 0, 1.5708), axis -z
#   scoop -> tip: xyz (0.1, 0, 0.08)
# With every joint at 0 (rounding pi/2 and pi): the shoulder frame is the base frame turned half a
# turn about x (y and z flip). shou->prox adds +0.16 along x and turns +90 deg about x, so prox's
# z axis points along base +y; prox and dist add 0.53 along x: the distal joint sits at
# x = 0.79 + 0.16 + 0.53 = 1.48. dist->wrist adds 0.586 along x and -0.15 along dist z (= base
# +y flipped twice: base y decreases by 0.15): wrist at (2.066, 0.025, 0.27). The wrist frame is
# turned so that the hand offset (0.163, 0.2, 0) maps to base (0, 0, -0.163) + (0.2, 0, 0):
# hand at (2.266, 0.025, 0.107). hand->scoop is 0.15 along hand x = base -z: scoop at
# (2.266, 0.025, -0.043); the tip offset (0.1, 0, 0.08) maps to base (0, -0.1, -0.08):
# tip at (2.266, -0.075, -0.123). These are the spec's derived figures (section 1.2).
# The numeric chain below does the same product for any q, from the table typed in here.
_TABLE = [  # joint, xyz, rpy, axis
    ("j_shou_yaw", (0.79, 0.175, 0.27), (-3.1416, 0, 0), (0, 0, -1)),
    ("j_shou_pitch", (0.16, 0, 0), (1.5708, 0, 0), (0, 0, -1)),
    ("j_prox_pitch", (0.53, 0, 0), (0, 0, 0), (0, 0, -1)),
    ("j_dist_pitch", (0.586, 0, -0.15), (3.1416, 0, 1.5708), (0, 0, 1)),
    ("j_hand_yaw", (0.163, 0.2, 0), (1.5708, 0, 0), (0, 0, -1)),
    ("j_scoop_yaw", (0.15, 0, 0), (1.5708, 0, 1.5708), (0, 0, -1)),
]


def _rot(axis, angle):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k


def _rpy(r, p, y):
    return _rot((0, 0, 1), y) @ _rot((0, 1, 0), p) @ _rot((1, 0, 0), r)


def _chain_scoop_tip(angles):
    T = np.eye(4)
    for name, xyz, rpy, axis in _TABLE:
        step = np.eye(4)
        step[:3, :3] = _rpy(*rpy) @ _rot(axis, angles.get(name, 0.0))
        step[:3, 3] = xyz
        T = T @ step
    return T @ np.array([0.1, 0.0, 0.08, 1.0])


@pytest.mark.parametrize(
    ("name", "angles", "expected_tip"),
    [
        ("all zero", {}, (2.266, -0.075, -0.123)),
        ("stowed", STOWED, None),
        ("unstowed", UNSTOWED, (1.736, 0.255, 0.537)),
    ],
)
def test_fk_matches_the_joint_table(model, name, angles, expected_tip):
    tip = model.position(model.q_from(angles), "l_scoop_tip")
    assert np.allclose(tip, _chain_scoop_tip(angles)[:3], atol=1e-6), name
    if expected_tip is not None:
        assert np.allclose(tip, expected_tip, atol=1e-3), name


def test_fixed_frames(model):
    q = model.q_from({})
    # Dock: base -> dock_link (0.53, -0.35, 0.32) rpy (-pi/2, 0, -pi/2) -> dock0 (0, -0.33, 0):
    # that rotation maps dock y to base +z, so dock0 sits 0.33 higher: (0.53, -0.35, 0.65).
    assert np.allclose(model.position(q, "lander_sample_dock0"), (0.53, -0.35, 0.65), atol=1e-4)
    # The grinder tip is 0.16 m along the grinder's x axis from its origin.
    X = model.fk(model.q_from(UNSTOWED), "l_grinder")
    tip = model.position(model.q_from(UNSTOWED), "l_grinder_tip")
    assert np.allclose(tip, X[:3, 3] + 0.16 * X[:3, 0], atol=1e-9)


def test_jacobian_matches_finite_differences(model):
    q = model.q_from(UNSTOWED)
    J = model.jacobian(q, "l_scoop_tip")
    eps = 1e-6
    for i in range(model.nq):
        dq = np.zeros(model.nq)
        dq[i] = eps
        dp = (model.position(q + dq, "l_scoop_tip") - model.position(q - dq, "l_scoop_tip")) / (
            2 * eps
        )
        assert np.allclose(J[:3, i], dp, atol=1e-6)


# --------------------------------------------------------------------------------------------
def _random_arm_configurations(model, n, seed):
    rng = np.random.default_rng(seed)
    base = model.q_from(UNSTOWED)
    for _ in range(n):
        q = base.copy()
        q[model.arm_idx] = rng.uniform(model.lower[model.arm_idx], model.upper[model.arm_idx])
        yield q


def _rotation_error(Ra, Rb):
    return np.arccos(np.clip((np.trace(Ra.T @ Rb) - 1) / 2, -1, 1))


@pytest.mark.parametrize("frame", ["l_scoop_tip", "l_grinder_tip"])
def test_ik_round_trips_random_reachable_poses(model, frame):
    q0 = model.q_from(UNSTOWED)
    n = 200 if frame == "l_scoop_tip" else 50
    for q in _random_arm_configurations(model, n, seed=7):
        X = model.fk(q, frame)
        solution = model.ik(frame, X[:3, 3], q0, rotation=X[:3, :3])
        Xs = model.fk(solution, frame)
        assert np.linalg.norm(Xs[:3, 3] - X[:3, 3]) < 1e-3
        assert _rotation_error(Xs[:3, :3], X[:3, :3]) < 0.01
        assert model.within_limits(solution)


def test_ik_position_only(model):
    q0 = model.q_from(UNSTOWED)
    for q in _random_arm_configurations(model, 50, seed=3):
        target = model.position(q, "l_scoop_tip")
        solution = model.ik("l_scoop_tip", target, q0)
        assert np.linalg.norm(model.position(solution, "l_scoop_tip") - target) < 1e-3


@pytest.mark.parametrize(
    "target",
    [(4.0, 0.0, 0.0), (0.79, 0.175, 3.0), (-2.5, 0.0, 0.2)],
)
def test_ik_reports_unreachable_targets(model, target):
    with pytest.raises(IKError, match="cannot reach"):
        model.ik("l_scoop_tip", np.array(target), model.q_from(UNSTOWED), restarts=4)


def test_ik_rejects_non_finite_targets(model):
    with pytest.raises(IKError, match="finite"):
        model.ik("l_scoop_tip", np.array([np.nan, 0, 0]), model.q_from(UNSTOWED))


# --------------------------------------------------------------------------------------------
def _potential_energy(model, q):
    """Sum of m g z_com over the moving links, computed here from link placements."""
    import pinocchio as pin

    pin.forwardKinematics(model.model, model.data, q)
    energy = 0.0
    for joint in range(1, model.model.njoints):
        inertia = model.model.inertias[joint]
        com = model.data.oMi[joint].act(inertia.lever)
        energy += inertia.mass * EUROPA_GRAVITY * com[2]
    return energy


def test_gravity_torques_are_the_gradient_of_potential_energy(model):
    eps = 1e-6
    for q in _random_arm_configurations(model, 10, seed=11):
        tau = model.gravity_torques(q)
        for i in range(model.nq):
            dq = np.zeros(model.nq)
            dq[i] = eps
            grad = (_potential_energy(model, q + dq) - _potential_energy(model, q - dq)) / (2 * eps)
            assert tau[i] == pytest.approx(grad, abs=1e-5)
        assert model.potential_energy(q) == pytest.approx(_potential_energy(model, q), abs=1e-9)


def test_rnea_at_rest_is_gravity(model):
    q = model.q_from(UNSTOWED)
    zero = np.zeros(model.nq)
    assert np.allclose(model.rnea(q, zero, zero), model.gravity_torques(q))
    # The shoulder pitch carries the whole outstretched arm: about 30 kg at ~0.8 m on Europa.
    assert 10 < abs(model.gravity_torques(model.q_from({}))[model.index("j_shou_pitch")]) < 60


# --------------------------------------------------------------------------------------------
FLAT = HeightMap.flat(DEFAULT_GROUND_Z)


@pytest.mark.parametrize("name, angles", [("stowed", STOWED), ("unstowed", UNSTOWED)])
def test_named_configurations_are_collision_free(model, name, angles):
    report = model.collision_report(model.q_from(angles), FLAT)
    assert not report.in_collision, f"{name}: {report.describe()}"


def test_scoop_driven_into_the_lander_body_is_flagged(model):
    # Put the scoop tip 5 cm deep into the top of the lander's upper body (z 0.12..0.27).
    inside = np.array([0.45, -0.05, 0.22])
    q = model.ik("l_scoop_tip", inside, model.q_from(UNSTOWED))
    report = model.collision_report(q)
    assert report.in_collision
    assert ("base_link", "l_scoop") in report.pairs, report.describe()
    assert model.in_collision(q)


def test_scoop_below_the_terrain_is_flagged_and_excludable(model):
    q = model.q_from({"j_shou_pitch": 0.9}, model.q_from(UNSTOWED))
    assert model.position(q, "l_scoop_tip")[2] > DEFAULT_GROUND_Z  # the tip is above ground...
    low = HeightMap.flat(0.0)  # ...but not above a terrain at z = 0
    report = model.collision_report(q, low)
    assert report.terrain_link in {"l_scoop", "l_hand", "l_grinder"}
    assert report.terrain_penetration > 0.0
    tools = model.collision_report(q, low, terrain_links=["l_scoop"])
    assert tools.terrain_link == "l_scoop"
    assert tools.terrain_penetration >= -0.0 - model.position(q, "l_scoop_tip")[2] - 1e-9
    assert not model.collision_report(q, low, terrain_links=["l_shou"]).in_collision


def test_terrain_margin(model):
    q = model.q_from(UNSTOWED)
    assert model.collision_report(q, FLAT).terrain_penetration == 0.0
    # With a 1 m margin the unstowed arm (scoop tip at z 0.54) is "too close" to the ground.
    assert model.in_collision(q, FLAT, terrain_margin=1.0)


def test_terrain_sample_points_lie_on_the_coal_geometry(model):
    # The points are made from the URDF's shapes (ow_description.shapes); the coal objects pinocchio
    # built from the same URDF must carry every one of them on their surface.
    checker = model.collision
    objects = checker.geom_model.geometryObjects
    for link, samples in checker._terrain_samples.items():
        on_link = [g for g in objects if model.model.frames[g.parentFrame].name == link]
        assert {g.parentJoint for g in on_link} == {samples.joint}, link
        boxes = sum(isinstance(g.geometry, coal.Box) for g in on_link)
        assert len(samples.points) == 14 * boxes + 24 * (len(on_link) - boxes), link
        on_surface = np.zeros(len(samples.points), dtype=bool)
        for g in on_link:
            local = (samples.points - g.placement.translation) @ g.placement.rotation
            shape = g.geometry
            if isinstance(shape, coal.Box):
                on_surface |= np.isclose(np.max(np.abs(local) / shape.halfSide, axis=1), 1.0)
            else:
                radial, axial = np.hypot(local[:, 0], local[:, 1]), np.abs(local[:, 2])
                on_surface |= np.isclose(radial, shape.radius) & np.isclose(axial, shape.halfLength)
        assert on_surface.all(), link
        distances = np.linalg.norm(samples.points - samples.centre, axis=1)
        assert distances.max() == pytest.approx(samples.radius)


def test_unknown_names_are_reported(model):
    with pytest.raises(ModelError, match="unknown joint 'j_elbow'"):
        model.index("j_elbow")
    with pytest.raises(ModelError, match="unknown frame"):
        model.fk(model.q_from({}), "l_nowhere")


def test_limit_violations_name_the_joint(model):
    q = model.q_from({"j_shou_yaw": 2.0}, model.q_from(UNSTOWED))
    assert model.limit_violations(q) == ["j_shou_yaw=2.000 rad is outside [-1.800, 1.800]"]


# --------------------------------------------------------------------------------------------
def test_description_loads_identically_in_pinocchio_and_pybullet(model):
    client = pb.connect(pb.DIRECT)
    try:
        # Not fixed: Bullet reports a fixed base's mass as 0. Nothing is simulated here.
        body = pb.loadURDF(str(URDF_PATH), useFixedBase=False, physicsClientId=client)
        n = pb.getNumJoints(body, physicsClientId=client)
        infos = [pb.getJointInfo(body, i, physicsClientId=client) for i in range(n)]
        bullet_links = {"base_link"} | {info[12].decode() for info in infos}
        bullet_movable = {info[1].decode() for info in infos if info[2] == pb.JOINT_REVOLUTE}
        bullet_mass = sum(
            pb.getDynamicsInfo(body, i, physicsClientId=client)[0] for i in range(-1, n)
        )
        limits = {
            info[1].decode(): (info[8], info[9], info[10], info[11])
            for info in infos
            if info[2] == pb.JOINT_REVOLUTE
        }
    finally:
        pb.disconnect(client)
    assert bullet_links == set(model.link_names())
    assert bullet_movable == set(model.joint_names)
    assert len(bullet_movable) == 9
    assert bullet_mass == pytest.approx(model.total_mass(), rel=1e-9)
    for name, (lower, upper, effort, velocity) in limits.items():
        i = model.index(name)
        assert (lower, upper) == pytest.approx((model.lower[i], model.upper[i]))
        assert (effort, velocity) == pytest.approx((model.effort_limit[i], model.velocity_limit[i]))


def test_arm_mass_matches_the_spec(model):
    arm = sum(
        model.model.inertias[model.model.getJointId(j)].mass for j in (*ARM_JOINTS, "j_grinder")
    )
    # l_shou..l_grinder, with the 1 g tip frames merged into scoop and grinder: spec says ~30.27 kg.
    assert arm == pytest.approx(30.27, abs=0.01)
