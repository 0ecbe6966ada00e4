"""The robot model against OceanWATERS' (HEAD's) kinematic limits and collision checks: the wider
limits, continuous joints that take any angle, and a collision model that accepts every
configuration OceanWATERS' test scripts command while catching real contacts (no ROS)."""

import math

import numpy as np
import pinocchio as pin
import pytest

from ow_description.collision import ARM_LINKS, DISABLED_COLLISION_PAIRS
from ow_description.description import (
    ARM_JOINTS,
    CONTINUOUS_JOINTS,
    CONTINUOUS_TRAVEL,
    UNSTOWED,
    nearest_turn,
    wrap_angle,
)
from ow_description.model import LanderModel
from ow_description.terrain import HeightMap

#: m, the flat ground OceanWATERS' test scripts assume (their DEFAULT_GROUND_HEIGHT).
OW_GROUND = HeightMap.flat(-0.172)


@pytest.fixture(scope="module")
def model():
    return LanderModel()


def _arm(model, values, base=None):
    return model.q_from(dict(zip(ARM_JOINTS, values, strict=True)), base)


# -------------------------------------------------------------------------------------- limits
@pytest.mark.parametrize(
    ("joint", "lower", "upper"),
    [
        ("j_shou_yaw", -1.8, 1.8),  # the paper's (HEAD's -1.56..1.43 is narrower)
        ("j_shou_pitch", -0.4, 2.2),  # HEAD's lower limit (the paper's was 0.05)
        ("j_grinder", -3.2, 3.2),  # HEAD's (the paper's was +-3.14)
    ],
)
def test_revolute_limits_are_the_wider_of_the_paper_and_head(model, joint, lower, upper):
    i = model.index(joint)
    assert (model.lower[i], model.upper[i]) == pytest.approx((lower, upper))
    assert not model.continuous[i]


def test_the_continuous_joints_are_heads_and_take_any_angle(model):
    assert CONTINUOUS_JOINTS == ("j_prox_pitch", "j_dist_pitch", "j_hand_yaw", "j_scoop_yaw")
    assert [name for name in model.joint_names if model.continuous[model.index(name)]] == [
        name for name in model.joint_names if name in CONTINUOUS_JOINTS
    ]
    for joint in CONTINUOUS_JOINTS:
        i = model.index(joint)
        assert (model.lower[i], model.upper[i]) == pytest.approx(
            (-CONTINUOUS_TRAVEL, CONTINUOUS_TRAVEL), abs=1e-6
        )
    # ArmMoveJoints test_03's goal: j_prox_pitch 7.87 rad (= 1.588 rad) is a valid goal; so is
    # any finite angle of a continuous joint, and the shoulder pitch at 0 (refused before).
    goal = _arm(model, [0.837758, 1.48353, 7.87143, -0.314159, 3.47321, 2.28638])
    assert model.limit_violations(goal) == []
    assert model.limit_violations(_arm(model, [0, 0, 0, 100.0, -100.0, 1e6])) == []
    assert model.limit_violations(_arm(model, [0, -0.4, 0, 0, 0, 0])) == []


@pytest.mark.parametrize(
    ("values", "message"),
    [
        ([0, -0.41, 0, 0, 0, 0], "j_shou_pitch=-0.410 rad is outside [-0.400, 2.200]"),
        ([1.81, 1.0, 0, 0, 0, 0], "j_shou_yaw=1.810 rad is outside [-1.800, 1.800]"),
        ([0, 1.0, math.nan, 0, 0, 0], "j_prox_pitch=nan rad is not a finite angle"),
        ([0, 1.0, 0, 0, math.inf, 0], "j_hand_yaw=inf rad is not a finite angle"),
    ],
)
def test_limit_violations_name_the_joint_and_its_limits(model, values, message):
    assert model.limit_violations(_arm(model, values)) == [message]


@pytest.mark.parametrize(
    ("angle", "reference", "expected"),
    [
        (7.87143, 0.0, 7.87143 - 2 * math.pi),
        (8.08087, 1.0, 8.08087 - 2 * math.pi),
        (-3.15905, 0.0, -3.15905 + 2 * math.pi),  # just past half a turn: the other way round
        (3.0, 3.0, 3.0),
        (2.9, -2.9, 2.9 - 2 * math.pi),
        (0.1, 12.0, 0.1 + 4 * math.pi),
    ],
)
def test_nearest_turn_is_the_same_angle_nearest_the_reference(angle, reference, expected):
    turned = float(nearest_turn(angle, reference))
    assert turned == pytest.approx(expected, abs=1e-12)
    assert abs(turned - reference) <= math.pi + 1e-12
    assert float(wrap_angle(turned - angle)) == pytest.approx(0.0, abs=1e-12)


def test_nearest_turn_keeps_an_angle_within_half_a_turn_exactly_and_works_on_arrays():
    assert float(nearest_turn(2.9, 2.9)) == 2.9
    assert float(nearest_turn(-1.5707, 0.0)) == -1.5707
    assert np.allclose(
        nearest_turn([7.87143, -3.15905], [1.5, 0.0]),
        [7.87143 - 2 * math.pi, -3.15905 + 2 * math.pi],
    )
    assert np.allclose(
        wrap_angle([math.pi, -math.pi, 7.0]), [-math.pi, -math.pi, 7.0 - 2 * math.pi]
    )


# ------------------------------------------------------------------------ collision: the pairs
def test_the_pairs_never_checked_are_oceanwaters_srdf_list(model):
    checker = model.collision
    checked = {
        frozenset((checker._geom_link[p.first], checker._geom_link[p.second]))
        for p in checker.geom_model.collisionPairs
    }
    assert not checked & DISABLED_COLLISION_PAIRS
    # The pairs OceanWATERS' SRDF disables and re-implementations tend to check...
    for pair in [("l_grinder", "l_scoop"), ("l_ant_foot", "l_dist"), ("l_scoop", "l_wrist")]:
        assert frozenset(pair) in DISABLED_COLLISION_PAIRS, pair
    # ...and the ones it checks: the distal link against the hand (refused too eagerly once),
    # the scoop against the body, the dock and the antenna panel.
    for pair in [
        ("l_dist", "l_hand"),
        ("l_dist", "l_scoop"),
        ("l_shou", "l_wrist"),
        ("base_link", "l_scoop"),
        ("base_link", "l_prox"),
        ("l_scoop", "lander_sample_dock0"),
        ("l_ant_panel", "l_scoop"),
    ]:
        assert frozenset(pair) in checked, pair


def test_every_arm_link_has_several_primitives(model):
    objects = model.collision.geom_model.geometryObjects
    counts = {link: 0 for link in ARM_LINKS}
    for g in objects:
        link = model.model.frames[g.parentFrame].name
        if link in counts:
            counts[link] += 1
    assert all(count >= 3 for count in counts.values()), counts


# ----------------------------------------------- collision: what OceanWATERS' scripts command
def _move_joint_sequence() -> list[tuple[str, list[float]]]:
    """ArmMoveJoint's test script from the stowed pose (HEAD's): six absolute joint moves, then
    six relative ones."""
    q = [-1.5, 1.5708, -2.65, 2.9, 0.0, 0.0]
    out = []
    for j, angle in enumerate([0, 1.5708, -1.5708, 0, 1.5708, 0]):
        q[j] = angle
        out.append((f"ArmMoveJoint test_{j + 1:02d}", list(q)))
    for k, (j, delta) in enumerate(
        [(5, 0.261799), (4, -0.436332), (3, -0.314159), (2, 0.314159), (1, 0.174533), (0, 0.174533)]
    ):
        q[j] += delta
        out.append((f"ArmMoveJoint test_{k + 7:02d}", list(q)))
    return out


#: Arm joint configurations OceanWATERS commands (its test scripts and SRDF named states), rad.
OW_CONFIGURATIONS = [
    ("ArmMoveJoints test_01", [0, 1.5708, -1.5708, 0, 1.5708, 0]),
    ("ArmMoveJoints test_02", [0, 0, 0, 0, 0, 0]),
    ("ArmMoveJoints test_03", [0.837758, 1.48353, 7.87143, -0.314159, 3.47321, 2.28638]),
    ("ArmMoveJoints test_04", [0.750492, 1.23918, 8.08087, 0.0872665, -3.15905, 2.37365]),
    ("ArmMoveJoints test_05", [0.977384, 1.78024, 0.959931, 1.97222, 2.54818, 1.5708]),
    ("ArmMoveJoints test_06", [-1.50098, 1.5708, -2.6529, 2.89725, 0, 0]),
    ("ArmMoveJoints test_07", [0, 1.5708, -1.5700, 0, 1.5708, 0]),
    ("ArmMoveJointsGuarded test_01", [0.0349066, 0.890118, -1.78024, 0.907571, 0.994838, -0.01745]),
    ("default_pose", [0, 1.125, 0, 0, 0, 0]),
    ("arm_stowed", [-1.5, 1.5708, -2.65, 2.9, 0, 0]),
    ("arm_stowed (paper)", [-1.5, 1.5708, -2.75, 2.9, 0, 0]),
    ("arm_extended", [0, 0, 0, 0, 0, 0]),
    ("arm_unstowed", [0, 1.5707, -1.5707, 0, 1.5707, 0]),
    ("arm_digging", [0, 0.8537, -1.5707, 0.7171, 1.5, 0]),
    ("arm_deliver_staging_1", [0.840285, 1.481847, 7.877803, -0.322703, 3.478371, 2.286525]),
    ("arm_deliver_staging_2", [0.752349, 1.241723, 8.083221, 0.095078, -3.161033, 2.380401]),
    ("arm_deliver_final", [0.977762, 1.78236, 0.95687, 1.97512, 2.54991, 1.56586]),
    ("pos_deliver (paper)", [0.4439, 1.5708, 1.5708, 0, 3.1415, 0]),
    *_move_joint_sequence(),
]


@pytest.mark.parametrize(
    ("name", "values"), OW_CONFIGURATIONS, ids=[n for n, _ in OW_CONFIGURATIONS]
)
def test_configurations_oceanwaters_commands_are_valid(model, name, values):
    q = _arm(model, values)
    assert model.within_limits(q), model.limit_violations(q)
    report = model.collision_report(q, OW_GROUND)
    assert not report.in_collision, f"{name}: {report.describe()}"
    # The same configuration a whole turn of each continuous joint away is the same.
    turned = _arm(
        model,
        [
            v + (2 * math.pi if j in CONTINUOUS_JOINTS else 0.0)
            for j, v in zip(ARM_JOINTS, values, strict=True)
        ],
    )
    assert not model.in_collision(turned, OW_GROUND)


@pytest.mark.parametrize("hand_turn", [-0.6, -0.8])
@pytest.mark.parametrize("yaw_turn", [0.0, -0.2, -0.4])
def test_guarded_moves_oceanwaters_commands_touch_only_the_ground_with_the_scoop(
    model, hand_turn, yaw_turn
):
    """ArmMoveJointsGuarded test_02..04: the hand yaw turned by -0.6 rad (the guard may stop it
    early or let it overshoot a little) and then the shoulder yaw by -0.2 rad twice; the scoop
    goes into the ground, where the force guard stops it."""
    values = [0.0349066 + yaw_turn, 0.890118, -1.78024, 0.907571, 0.994838 + hand_turn, -0.01745]
    q = _arm(model, values)
    links = tuple(link for link in ARM_LINKS if link != "l_scoop")
    report = model.collision_report(q, OW_GROUND, links)
    assert not report.in_collision, report.describe()


def test_the_guarded_hand_turn_oceanwaters_commands_is_free_all_the_way(model):
    """ArmMoveJointsGuarded test_02 from where test_01 leaves the arm (measured): the hand yaw
    from 1.01 rad down past 0.41 rad; the distal link passes the hand (refused once)."""
    reached = [0.0356, 0.8898, -1.7805, 0.9069, 1.0124, -0.0169]
    links = tuple(link for link in ARM_LINKS if link != "l_scoop")
    for hand in np.linspace(1.0124, 0.3, 40):
        q = _arm(model, [*reached[:4], hand, reached[5]])
        report = model.collision_report(q, OW_GROUND, links)
        assert not report.in_collision, f"hand yaw {hand:.3f} rad: {report.describe()}"


# ------------------------------------------------------------ collision: real contacts caught
@pytest.mark.parametrize(
    ("point", "pair"),
    [
        ((0.3, 0.0, 0.5), ("base_link", "l_hand")),  # the upper block of the body
        ((0.45, -0.05, 0.22), ("base_link", "l_scoop")),  # the band below it
        ((0.0, 0.5, 0.6), ("base_link", "l_scoop")),  # the far side of the body
        ((0.6, 0.6, 0.05), ("base_link", "l_scoop")),  # the deck by the front-left strut
        ((1.0, -1.0, 0.3), ("base_link", "l_scoop")),  # the front-right leg
        ((0.555, -0.35, 0.65), ("l_scoop", "lander_sample_dock0")),  # into the dock
    ],
)
def test_the_scoop_driven_into_the_lander_is_caught(model, point, pair):
    q = model.ik("l_scoop_tip", np.array(point), model.q_from(UNSTOWED))
    report = model.collision_report(q)
    assert frozenset(pair) in {frozenset(p) for p in report.pairs}, report.describe()
    assert model.in_collision(q)


@pytest.mark.parametrize(
    ("values", "pair"),
    [
        # The distal link folded back onto the shoulder, either way round.
        ([0, 1.5707, 3.0, 0, 1.5707, 0], ("l_dist", "l_shou")),
        ([0, 1.5707, -3.0, 0, 1.5707, 0], ("l_dist", "l_shou")),
        ([0, 2.0, 2.8, 0.5, 0, 0], ("l_dist", "l_shou")),
        # The wrist folded onto the upper arm.
        ([0, 1.0, -2.9, 0, 0, 0], ("l_prox", "l_wrist")),
        # The unstowed arm turned left into the front-left leg (HEAD's limit is 1.43 rad).
        ([1.45, 1.5707, -1.5707, 0, 1.5707, 0], ("base_link", "l_hand")),
        # The stowed arm turned back into the body.
        ([-1.7, 1.5708, -2.65, 2.9, 0, 0], ("base_link", "l_dist")),
    ],
)
def test_real_self_and_lander_contacts_are_caught(model, values, pair):
    report = model.collision_report(_arm(model, values))
    assert frozenset(pair) in {frozenset(p) for p in report.pairs}, report.describe()


# -------------------------------------------------------------- IK of the poses scripts send
def _rotation(x, y, z, w):
    q = np.array([w, x, y, z]) / np.linalg.norm([w, x, y, z])
    return np.asarray(pin.Quaternion(*q).matrix())


@pytest.mark.parametrize(
    ("position", "quaternion"),
    [
        # ArmMoveCartesianGuarded test_07 and test_10: the arm all but stretched out, the
        # rounded quaternions a hair away from any exact solution.
        ((1.797, 1.277, -0.16), (0.959, -0.284, 0.003, 0.006)),
        ((2.265, 0.167, -0.14), (0.625, -0.616, -0.338, -0.339)),
    ],
)
def test_ik_meets_both_tolerances_at_the_edge_of_reach(model, position, quaternion):
    target = _rotation(*quaternion)
    q = model.ik("l_scoop_tip", np.array(position), model.q_from(UNSTOWED), target)
    X = model.fk(q, "l_scoop_tip")
    assert np.linalg.norm(X[:3, 3] - position) <= 1e-4
    assert np.linalg.norm(pin.log3(target @ X[:3, :3].T)) <= 1e-3


def test_ik_solutions_are_the_distinct_branches_reaching_the_target(model):
    # ArmMoveCartesian test_03: several elbow and wrist branches, some into the lander body.
    position, target = np.array([1.166, 0.356, 0.588]), _rotation(-0.254, 0.727, -0.456, 0.446)
    solutions = model.ik_solutions("l_scoop_tip", position, model.q_from(UNSTOWED), target)
    assert len(solutions) >= 3
    for q in solutions:
        X = model.fk(q, "l_scoop_tip")
        assert np.linalg.norm(X[:3, 3] - position) <= 1e-4
    arms = np.array([q[model.arm_idx] for q in solutions])
    continuous = model.continuous[model.arm_idx]
    for i in range(len(arms)):
        for j in range(i):
            d = arms[i] - arms[j]
            assert np.abs(np.where(continuous, wrap_angle(d), d)).max() >= 1e-3
    verdicts = [model.in_collision(q) for q in solutions]
    assert any(verdicts) and not all(verdicts)
