"""Planning the goals OceanWATERS' test scripts send (no ROS): continuous joints take any angle
and turn the shorter way round, and the poses the scripts command are reachable without a
collision; the sampled search turns a continuous joint the other way round only when it must."""

import math

import numpy as np
import pinocchio as pin
import pytest

from ow_description.description import (
    ARM_JOINTS,
    CONTINUOUS_JOINTS,
    SCOOP_TIP_FRAME,
    STOWED,
    UNSTOWED,
    wrap_angle,
)
from ow_description.model import LanderModel
from ow_description.terrain import HeightMap
from ow_lander.config import PlannerConfig
from ow_lander.planning.planner import ArmPlanner, CheckContext

#: m, the flat ground OceanWATERS' test scripts assume (their DEFAULT_GROUND_HEIGHT).
OW_GROUND = HeightMap.flat(-0.172)

CONTINUOUS = np.array([j in CONTINUOUS_JOINTS for j in ARM_JOINTS])


@pytest.fixture(scope="module")
def planner():
    return ArmPlanner(LanderModel(), PlannerConfig())


@pytest.fixture(scope="module")
def ctx(planner):
    return CheckContext(planner.model.q_from(UNSTOWED), OW_GROUND)


def _arm(pose):
    return np.array([pose[j] for j in ARM_JOINTS])


def _rotation(x, y, z, w):
    """(3, 3) rotation of the quaternion (x, y, z, w), normalised (the scripts round them)."""
    q = np.array([w, x, y, z]) / np.linalg.norm([w, x, y, z])
    return np.asarray(pin.Quaternion(*q).matrix())


def _same_configuration(a, b):
    """True when the arm states a and b (6,) rad differ only by whole turns of continuous
    joints."""
    difference = np.asarray(a) - np.asarray(b)
    return np.allclose(np.where(CONTINUOUS, wrap_angle(difference), difference), 0.0, atol=1e-9)


# ------------------------------------------------------------------------- continuous joints
def test_arm_move_joints_goals_are_reached_the_shorter_way_round(planner, ctx):
    """ArmMoveJoints' test script, goal after goal from the stowed pose, on valid paths:
    j_prox_pitch 7.87 and 8.08 rad, j_hand_yaw 3.47 and -3.16 rad are reached as the same
    angles less whole turns, each continuous joint turning less than half a turn. (For the last
    goal the search finds no path the shorter way round: j_prox_pitch turns the other way.)"""
    goals = [
        [0, 1.5708, -1.5708, 0, 1.5708, 0],
        [0, 0, 0, 0, 0, 0],
        [0.837758, 1.48353, 7.87143, -0.314159, 3.47321, 2.28638],
        [0.750492, 1.23918, 8.08087, 0.0872665, -3.15905, 2.37365],
        [0.977384, 1.78024, 0.959931, 1.97222, 2.54818, 1.5708],
        [-1.50098, 1.5708, -2.6529, 2.89725, 0, 0],
    ]
    arm = _arm(STOWED)
    for k, goal in enumerate(goals):
        path = planner.plan_free(arm, np.array(goal), ctx)
        assert np.array_equal(path[0], arm)
        assert _same_configuration(path[-1], goal), (path[-1], goal)
        turned = np.abs(path[-1] - arm)[CONTINUOUS]
        assert np.all(turned <= math.pi + 1e-9) or k == len(goals) - 1, turned
        assert planner.first_invalid(path, ctx, 0.01) is None
        arm = path[-1]
    # test_03's j_prox_pitch: 7.87143 - 2 pi, from 0.
    assert planner.plan_free(np.zeros(6), np.array(goals[2]), ctx)[-1][2] == pytest.approx(
        7.87143 - 2 * math.pi
    )


def test_goal_turns_are_the_goal_and_each_moving_continuous_joint_the_other_way(planner):
    start = np.array([0.0, 1.0, 0.5, 0.0, -12.0, 1.0])
    goal = np.array([0.5, 1.2, 2.0, 0.0, -11.0, 0.0])
    turns = planner.goal_turns(start, goal)
    assert np.array_equal(turns[0], goal)
    # j_prox_pitch forward: also 2 pi back; j_scoop_yaw back: also 2 pi forward; j_dist_pitch
    # does not move; j_hand_yaw's other way (-11 - 2 pi) is beyond its travel.
    expected = [goal + 2 * math.pi * np.array(d) for d in ([0, 0, -1, 0, 0, 0], [0, 0, 0, 0, 0, 1])]
    assert len(turns) == 3
    assert all(np.allclose(t, e) for t, e in zip(turns[1:], expected, strict=True))


def test_the_search_spans_one_turn_beyond_the_ends_of_a_continuous_joint(planner):
    sampled = planner._sampled
    start = np.array([0.0, 1.0, 0.5, 0.0, 11.0, 1.0])
    goal = np.array([0.5, 1.2, 2.0, 0.0, 12.0, 0.0])
    low, high = sampled.sampling_bounds(start, planner.goal_turns(start, goal))
    revolute = ~CONTINUOUS
    assert np.array_equal(low[revolute], planner.lower[revolute])
    assert np.array_equal(high[revolute], planner.upper[revolute])
    # prox 0.5 -> 2.0 either way round (also to 2.0 - 2 pi), half a turn beyond.
    assert (low[2], high[2]) == pytest.approx((2.0 - 3 * math.pi, 2.0 + math.pi))
    assert (low[3], high[3]) == pytest.approx((-math.pi, math.pi))  # still: a turn around it
    assert high[4] == pytest.approx(planner.upper[4])  # never beyond the travel
    assert (low[5], high[5]) == pytest.approx((-math.pi, 3 * math.pi))  # 1 -> 0 or 2 pi


# --------------------------------------------------------------------- poses the scripts send
def _reach(planner, ctx, frame, pose, seed):
    """A valid arm state placing ``frame`` at ``pose`` ((x, y, z), (qx, qy, qz, qw)) and the
    valid path to it from ``seed``."""
    position, quaternion = pose
    goal = planner.solve_ik(frame, np.array(position), _rotation(*quaternion), seed, ctx)
    path = planner.plan_free(seed, goal, ctx)
    assert planner.first_invalid(path, ctx, 0.01) is None
    return path[-1]


#: ArmMoveCartesian's test script, absolute poses of l_scoop_tip in base_link, in order.
ARM_MOVE_CARTESIAN = [
    ((1.736, 0.255, 0.535), (-0.499, 0.501, 0.501, 0.499)),
    ((1.639, -0.996, 0.511), (0.675, -0.465, 0.072, 0.568)),
    ((1.166, 0.356, 0.588), (-0.254, 0.727, -0.456, 0.446)),
    ((1.833, 0.713, 0.782), (-0.539, -0.332, 0.37, 0.681)),
    ((2.115, 0.345, 0.3), (0.191, 0.455, -0.544, 0.678)),
]

#: ArmFindSurface's test script: where it puts l_scoop_tip, scoop bottom facing the surface,
#: before the guarded approach (position + distance along the normal).
ARM_FIND_SURFACE = [
    ((1.7, 0.5, 0.028), (-1, 0, 0, 0)),
    ((1.86, 0.1, 0.328), (-1, 0, 0, 0)),
    ((1.5, -0.01, 0.028), (-1, 0, 0, 0)),
    ((1.8, -0.3, 0.028), (-1, 0, 0, 0)),
    ((2.0, 0.17, 0.028), (-1, 0, 0, 0)),
    ((1.86, -0.63, 0.428), (-1, 0, 0, 0)),
    ((1.883, -0.561, 0.014), (0.932, -0.311, 0.0, 0.185)),
]


@pytest.mark.parametrize(
    ("frame", "poses"),
    [(SCOOP_TIP_FRAME, ARM_MOVE_CARTESIAN), (SCOOP_TIP_FRAME, ARM_FIND_SURFACE)],
    ids=["ArmMoveCartesian", "ArmFindSurface"],
)
def test_the_poses_the_scripts_command_are_reached_without_a_collision(planner, ctx, frame, poses):
    arm = _arm(UNSTOWED)
    for pose in poses:
        arm = _reach(planner, ctx, frame, pose, arm)
        X = planner.model.fk(planner.full(arm, ctx.base), frame)
        assert np.allclose(X[:3, 3], pose[0], atol=1e-3)


def test_a_pose_whose_nearest_branch_collides_is_reached_on_another(planner, ctx):
    """ArmMoveCartesian test_03's pose from an arm on the elbow branch that puts the upper arm
    into the lander body at that pose: IK follows the arm onto that branch, then takes the
    nearest branch that is free."""
    position, quaternion = (1.166, 0.356, 0.588), (-0.254, 0.727, -0.456, 0.446)
    model = planner.model
    rotation = _rotation(*quaternion)
    # The colliding branch, and an arm a little away from it on the same branch.
    into_body = np.array([1.383, 0.257, 1.774, 3.294, -1.241, -2.992])
    q = model.ik(SCOOP_TIP_FRAME, np.array(position), planner.full(into_body, ctx.base), rotation)
    assert not planner.is_valid(planner.arm(q), ctx)
    seed = planner.arm(q) + np.array([0.0, 0.05, 0.0, 0.0, 0.0, 0.0])
    arm = planner.solve_ik(SCOOP_TIP_FRAME, np.array(position), rotation, seed, ctx)
    assert planner.is_valid(arm, ctx)
    X = model.fk(planner.full(arm, ctx.base), SCOOP_TIP_FRAME)
    assert np.allclose(X[:3, 3], position, atol=1e-4)
    assert not np.allclose(arm, planner.arm(q), atol=0.05)


#: rad, the arm where the default mission's delivery ends (scoop poured over the dock, hand yaw
#: near 5.26 rad): straight to the stowed pose the scoop would sweep through base_link.
DELIVERED = np.array([0.435579, 0.98012, 1.721025, 1.299564, 5.264812, 0.93364])


def test_stowing_after_a_delivery_turns_the_hand_the_other_way_in_one_straight_move(planner):
    ctx = CheckContext(planner.model.q_from(dict(zip(ARM_JOINTS, DELIVERED, strict=True))), None)
    goal = planner.unwrap(_arm(STOWED), DELIVERED)
    assert not planner.path_valid(np.vstack([DELIVERED, goal]), ctx)
    before = planner.stats.rrt_iterations
    path = planner.plan_free(DELIVERED, goal, ctx)
    # RRT* ran to its cap; no RRTConnect search was needed.
    assert planner.stats.rrt_iterations - before == PlannerConfig().rrt_max_iterations + 1
    assert path.shape == (2, 6)
    turned = np.flatnonzero(~np.isclose(path[-1], goal))
    assert len(turned) == 1 and CONTINUOUS[turned[0]]
    assert abs(path[-1][turned[0]] - goal[turned[0]]) == pytest.approx(2 * math.pi)
    assert planner.path_valid(path, ctx)


def test_a_search_that_finds_nothing_ends_on_its_iteration_cap():
    """RRTConnect the shorter way round from the delivery's end finds nothing: it ends on its
    iteration cap, not on the clock, so the same request fails the same way at any load."""
    config = PlannerConfig(connect_max_iterations=150)
    capped = ArmPlanner(LanderModel(), config)
    ctx = CheckContext(capped.model.q_from(dict(zip(ARM_JOINTS, DELIVERED, strict=True))), None)
    goal = capped.unwrap(_arm(STOWED), DELIVERED)
    sampler = capped._sampled
    counts = []
    for _ in range(2):
        before = capped.stats.rrt_iterations
        path = sampler._solve(
            DELIVERED, [goal], ctx, config.seed, config.joint_resolution_rad, "work", connect=True
        )
        assert path is None
        counts.append(capped.stats.rrt_iterations - before)
    assert counts == [config.connect_max_iterations + 1] * 2
