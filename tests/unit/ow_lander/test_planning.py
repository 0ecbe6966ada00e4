"""Free-space planning: direct segment, RRT* with the work objective, determinism (no ROS)."""

import numpy as np
import pytest

from ow_description.description import DEFAULT_GROUND_Z, UNSTOWED
from ow_description.model import LanderModel
from ow_description.terrain import HeightMap
from ow_lander.config import PlannerConfig
from ow_lander.errors import PlanningError
from ow_lander.operations.planner import Operations
from ow_lander.planning.planner import ArmPlanner, CheckContext
from ow_lander.planning.validity import densify


@pytest.fixture(scope="module")
def planner():
    return ArmPlanner(LanderModel(), PlannerConfig(rrt_time_limit_s=2.0))


@pytest.fixture(scope="module")
def ctx(planner):
    return CheckContext(planner.model.q_from(UNSTOWED), HeightMap.flat(DEFAULT_GROUND_Z))


def _blocked_goal(planner, ctx):
    """A valid goal no straight joint motion reaches from the unstowed pose, whichever way round
    its continuous joints turn."""
    rng = np.random.default_rng(1)
    start = planner.arm(ctx.base)
    while True:
        # A continuous joint's goal is reached the shorter way round: the goal at that turn.
        goal = planner.unwrap(rng.uniform(planner.lower, planner.upper), start)
        if planner.is_valid(goal, ctx) and all(
            planner.first_invalid(np.vstack([start, turned]), ctx) is not None
            for turned in planner.goal_turns(start, goal)
        ):
            return goal


def test_densify_keeps_waypoints_and_resolution():
    path = densify(np.array([[0.0, 0.0], [0.1, -0.05], [0.1, 0.0]]), 0.01)
    assert np.max(np.abs(np.diff(path, axis=0))) <= 0.01 + 1e-12
    assert any(np.allclose(p, [0.1, -0.05]) for p in path)


def test_direct_segment_kept_when_valid(planner, ctx):
    start = planner.arm(ctx.base)
    goal = start + np.array([0.2, 0.0, 0.0, 0.1, 0.0, 0.0])
    assert np.array_equal(planner.plan_free(start, goal, ctx), np.vstack([start, goal]))


def test_rrt_star_finds_a_valid_repeatable_path(planner, ctx):
    start, goal = planner.arm(ctx.base), _blocked_goal(planner, ctx)
    a = planner.plan_free(start, goal, ctx)
    b = planner.plan_free(start, goal, ctx)
    assert np.array_equal(a, b)
    assert len(a) > 2 and np.allclose(a[0], start)
    assert any(np.allclose(a[-1], turned) for turned in planner.goal_turns(start, goal))
    assert planner.first_invalid(a, ctx, 0.01) is None


def test_work_is_gravity_work(planner, ctx):
    start = planner.arm(ctx.base)
    up = start.copy()
    up[1] += 0.3  # shoulder pitch lifts or lowers the whole arm
    work = planner.work(np.vstack([start, up]), ctx.base)
    energy = abs(
        planner.model.potential_energy(planner.full(up, ctx.base))
        - planner.model.potential_energy(ctx.base)
    )
    assert work == pytest.approx(energy, rel=0.02)


def test_invalid_goal_is_explained(planner, ctx):
    start = planner.arm(ctx.base)
    goal = start.copy()
    goal[1] = 5.0
    with pytest.raises(PlanningError, match=r"j_shou_pitch=5\.000 rad is outside"):
        planner.plan_free(start, goal, ctx)


def test_deliveries_from_the_tipped_discard_pose_need_no_sampled_path():
    # Left tipped at the discard point, the arm's wrist is on a branch whose carrying poses touch
    # the hand: the IK also starts from the unstowed pose, and the approach may pass it.
    model = LanderModel()
    ops = Operations(ArmPlanner(model, PlannerConfig()))
    terrain = HeightMap.flat(DEFAULT_GROUND_Z)
    discard = {"x": 1.3, "y": 0.9, "z": 0.4}
    q = model.q_from(UNSTOWED)
    tipped = ops.planner.full(ops.plan("deliver_sample", q, terrain, discard).end, q)
    ctx = CheckContext(tipped, terrain)
    for request in (discard, {"use_defaults": True}):
        plan = ops.plan("deliver_sample", tipped, terrain, request)
        for segment in plan.segments:
            assert ops.planner.first_invalid(segment.waypoints, ctx, 0.01) is None
    assert ops.planner.stats.rrt_segments == 0
