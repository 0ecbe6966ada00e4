"""The fast validity checks give the answers of the plain ones (no ROS): terrain blocks bound the
terrain, coarse-to-fine path checks agree with the sequential check, Cartesian lines report and
stop where they are blocked; batched terrain checks and kinematics agree with pinocchio and the
per-state checker, kept segment verdicts and IK outcomes never change a plan, paths through the
unstowed pose are collision-checked."""

import itertools
import re

import numpy as np
import pinocchio as pin
import pytest

from ow_description.batch_check import BatchKinematics, BatchTerrainCheck
from ow_description.collision import ARM_LINKS, TerrainBlocks
from ow_description.description import (
    ANTENNA_JOINTS,
    ARM_JOINTS,
    DEFAULT_GROUND_Z,
    GRINDER_JOINT,
    SCOOP_TIP_FRAME,
    STOWED,
    UNSTOWED,
)
from ow_description.model import LanderModel
from ow_description.terrain import HeightMap
from ow_lander.config import PlannerConfig
from ow_lander.errors import PlanningError
from ow_lander.operations.planner import DOCK_CENTRE, DOCK_POUR_HEIGHT, Operations
from ow_lander.planning.planner import ArmPlanner, CheckContext
from ow_lander.planning.validity import _coarse_to_fine, densify, segment_steps


@pytest.fixture(scope="module")
def planner():
    return ArmPlanner(LanderModel(), PlannerConfig())


def _rough(seed: int, shape=(121, 121), resolution=0.05, amplitude=0.05) -> HeightMap:
    rng = np.random.default_rng(seed)
    heights = DEFAULT_GROUND_Z + amplitude * rng.standard_normal(shape)
    return HeightMap(heights, resolution, -3.0, -3.0)


@pytest.mark.parametrize(
    ("terrain", "block"),
    [
        (_rough(1), 0.25),
        (_rough(2, (40, 61), 0.1), 0.35),
        (_rough(3, (7, 5), 0.05), 1.0),
        (HeightMap.flat(DEFAULT_GROUND_Z), 0.25),
    ],
)
def test_terrain_blocks_bound_every_height_under_the_square(terrain, block):
    blocks = TerrainBlocks(terrain, block)
    rng = np.random.default_rng(0)
    for _ in range(200):
        # Centres inside and outside the grid (beyond it the edge continues).
        x, y = rng.uniform(-4.0, 4.0, 2)
        radius = rng.uniform(0.0, 0.6)
        xs, ys = np.meshgrid(
            np.linspace(x - radius, x + radius, 15), np.linspace(y - radius, y + radius, 15)
        )
        assert terrain.height_at(xs, ys).max() <= blocks.highest(x, y, radius) + 1e-12
    assert blocks.top == pytest.approx(terrain.heights.max())


def _random_states(planner, n, seed):
    rng = np.random.default_rng(seed)
    return rng.uniform(planner.lower, planner.upper, (n, 6))


def test_a_far_spike_changes_no_answer_and_a_near_bump_is_found(planner):
    model = planner.model
    base = model.q_from(UNSTOWED)
    terrain = _rough(4)
    spiked_heights = terrain.heights.copy()
    spiked_heights[0, 0] = 5.0  # (-3, -3) m: out of the arm's reach, above everything
    spiked = HeightMap(spiked_heights, terrain.resolution, terrain.origin_x, terrain.origin_y)
    for arm in _random_states(planner, 400, 5):
        q = planner.full(arm, base)
        for margin in (0.0, 0.05):
            a = model.collision_report(q, terrain, ARM_LINKS, margin)
            b = model.collision_report(q, spiked, ARM_LINKS, margin)
            assert (a.terrain_link, a.terrain_penetration) == (
                b.terrain_link,
                b.terrain_penetration,
            )
            assert model.in_collision(q, terrain, ARM_LINKS, margin) == a.in_collision
            assert model.in_collision(q, spiked, ARM_LINKS, margin) == a.in_collision
    # A 2 cm bump right under the unstowed scoop tip: found, with its depth.
    tip = model.position(base, "l_scoop_tip")
    bumped_heights = spiked_heights.copy()
    col = round((tip[0] - terrain.origin_x) / terrain.resolution)
    row = round((tip[1] - terrain.origin_y) / terrain.resolution)
    bumped_heights[row - 1 : row + 2, col - 1 : col + 2] = tip[2] + 0.02
    bumped = HeightMap(bumped_heights, terrain.resolution, terrain.origin_x, terrain.origin_y)
    report = model.collision_report(base, bumped)
    assert report.terrain_link in {"l_scoop", "l_hand", "l_grinder"}
    assert report.terrain_penetration > 0.01
    assert model.in_collision(base, bumped)


def test_coarse_to_fine_visits_every_index_once():
    for n in (1, 2, 3, 9, 16, 100):
        order = _coarse_to_fine(n)
        assert order[0] == 0
        assert sorted(order.tolist()) == list(range(n))


def test_path_valid_agrees_with_the_sequential_check(planner):
    ctx = CheckContext(planner.model.q_from(UNSTOWED), _rough(6))
    states = _random_states(planner, 60, 7)
    start = planner.arm(ctx.base)
    verdicts = []
    for goal in states:
        for path in (np.vstack([start, goal]), np.vstack([start, (start + goal) / 2, goal])):
            expected = planner.first_invalid(path, ctx) is None
            assert planner.path_valid(path, ctx) == expected
            verdicts.append(expected)
    assert any(verdicts) and not all(verdicts)  # both cases were exercised


def test_cartesian_line_into_the_ground_stops_before_it_or_names_the_waypoint(planner):
    model = planner.model
    base = model.q_from(UNSTOWED)
    X = model.fk(base, "l_scoop_tip")
    # A 0.45 m high block under the scoop; the scoop must stay above it (it is not digging).
    flat = HeightMap.flat(DEFAULT_GROUND_Z)
    xs, ys = flat.cell_centres()
    block = (np.abs(ys[:, None] - X[1, 3]) < 0.3) & (np.abs(xs[None, :] - X[0, 3]) < 0.3)
    heights = np.where(block, 0.3, flat.heights)
    ctx = CheckContext(base, HeightMap(heights, flat.resolution, flat.origin_x, flat.origin_y))
    start = planner.arm(base)
    points = [X[:3, 3] - np.array([0.0, 0.0, 0.01 * (k + 1)]) for k in range(40)]
    rotations = [X[:3, :3]] * len(points)
    with pytest.raises(PlanningError) as error:
        planner.plan_cartesian(start, "l_scoop_tip", points, rotations, ctx)
    match = re.search(r"is blocked at waypoint (\d+) \(", str(error.value))
    assert match, str(error.value)
    assert "below the terrain" in str(error.value)
    blocked = int(match.group(1))
    partial = planner.plan_cartesian(start, "l_scoop_tip", points, rotations, ctx, partial=True)
    # The start and every waypoint before the blocked one, all valid.
    assert len(partial) == blocked + 1 > 1
    assert planner.first_invalid(partial, ctx, 0.01) is None
    tips = [model.position(planner.full(arm, base), "l_scoop_tip") for arm in partial[1:]]
    assert np.allclose(tips, points[:blocked], atol=1e-3)


def test_plan_straight_is_direct_staged_or_none(planner):
    ctx = CheckContext(planner.model.q_from(UNSTOWED), HeightMap.flat(DEFAULT_GROUND_Z))
    start = planner.arm(ctx.base)
    kinds = set()
    for goal in _random_states(planner, 40, 8):
        if not planner.is_valid(goal, ctx):
            continue
        path = planner.plan_straight(start, goal, ctx)
        if path is None:
            kinds.add("none")
            continue
        kinds.add(len(path))
        assert np.array_equal(path[0], start) and np.array_equal(path[-1], goal)
        assert planner.first_invalid(path, ctx, 0.01) is None
    assert {2, "none"} <= kinds


def _configurations(model: LanderModel, n: int, seed: int) -> np.ndarray:
    """(n, 9) rad: random configurations of every joint (antenna too) within the limits."""
    rng = np.random.default_rng(seed)
    return rng.uniform(model.lower, model.upper, (n, model.nq))


def test_batch_kinematics_places_every_joint_as_pinocchio(planner):
    model = planner.model
    Q = _configurations(model, 50, 1)
    frames = BatchKinematics(model.model).placements(Q, range(1, model.model.njoints))
    for i, q in enumerate(Q):
        pin.forwardKinematics(model.model, model.data, q)
        for j in range(1, model.model.njoints):
            R, t = frames[j]
            assert np.allclose(R[i], model.data.oMi[j].rotation, atol=1e-12)
            assert np.allclose(t[i], model.data.oMi[j].translation, atol=1e-12)


@pytest.mark.parametrize(
    ("terrain", "links", "margin"),
    [
        (_rough(1, amplitude=0.3), ARM_LINKS, 0.0),
        (_rough(2, amplitude=0.3), ("l_prox", "l_dist", "l_wrist", "l_hand"), 0.05),
        (HeightMap.flat(DEFAULT_GROUND_Z), ARM_LINKS, 0.0),
        (HeightMap.flat(0.4, half_extent=1.0), ("l_scoop", "l_grinder"), 0.02),
    ],
)
def test_batch_terrain_check_agrees_with_the_per_state_check(planner, terrain, links, margin):
    model = planner.model
    Q = _configurations(model, 400, 2)
    batch = BatchTerrainCheck(model.model, model.collision).below(Q, terrain, links, margin)
    # The coal model is left out: only the terrain decides, as in the batch.
    expected = [
        model.collision_report(q, terrain, links, margin).terrain_link is not None for q in Q
    ]
    assert batch.tolist() == expected
    assert 0 < sum(expected) < len(Q)  # both answers were exercised


@pytest.mark.parametrize(
    "terrain", [_rough(3, amplitude=0.3), _rough(4, (40, 61), 0.1), _rough(5, (7, 5))]
)
def test_highest_many_is_highest_for_each_square(terrain):
    blocks = TerrainBlocks(terrain)
    rng = np.random.default_rng(6)
    x = rng.uniform(terrain.origin_x - 1.0, terrain.x_max + 1.0, 300)
    y = rng.uniform(terrain.origin_y - 1.0, terrain.y_max + 1.0, 300)
    radius = rng.uniform(0.0, 1.0, 300)
    many = blocks.highest_many(x, y, radius)
    single = [blocks.highest(*args) for args in zip(x, y, radius, strict=True)]
    # Squares too large for the window table get the map's top, an upper bound of the same.
    exact = many == np.array(single)
    assert exact.mean() > 0.5
    assert np.all(many[~exact] == blocks.top)


def test_densify_matches_its_definition_segment_by_segment():
    rng = np.random.default_rng(7)
    points = rng.uniform(-1.0, 1.0, (6, 6))
    states = densify(points, 0.01)
    expected = [points[:1]]
    for (a, b), n in zip(itertools.pairwise(points), segment_steps(points, 0.01), strict=True):
        expected.append(a + (np.arange(1, n + 1)[:, None] / n) * (b - a))
    assert np.array_equal(states, np.concatenate(expected))


def test_a_segment_verdict_is_not_kept_across_contexts(planner):
    start = planner.arm(planner.model.q_from(UNSTOWED))
    goal = start.copy()
    goal[1] += 0.4  # lowers the arm towards the ground
    path = np.vstack([start, goal])
    base = planner.model.q_from(UNSTOWED)
    low = CheckContext(base, HeightMap.flat(-1.0))
    high = CheckContext(base, HeightMap.flat(planner.model.fk(base, SCOOP_TIP_FRAME)[2, 3] - 0.05))
    assert planner.path_valid(path, low)
    assert not planner.path_valid(path, high)
    assert planner.path_valid(path, low)
    assert planner.first_invalid(path, high) is not None


def test_straight_moves_through_the_unstowed_pose_are_checked(planner):
    ctx = CheckContext(planner.model.q_from(UNSTOWED), HeightMap.flat(DEFAULT_GROUND_Z))
    rng = np.random.default_rng(11)
    through_safe = 0
    zero = np.zeros(6)
    for _ in range(400):
        # A continuous joint's angles within one turn (of 0): its whole range of orientations.
        start, goal = (
            planner.unwrap(arm, zero) for arm in rng.uniform(planner.lower, planner.upper, (2, 6))
        )
        if not (planner.is_valid(start, ctx) and planner.is_valid(goal, ctx)):
            continue
        direct = np.vstack([start, goal])
        path = planner.plan_straight(start, goal, ctx)
        if path is None or len(path) < 4:
            continue
        # Neither the direct segment nor the staged moves: the path passes the unstowed pose.
        assert planner.first_invalid(direct, ctx) is not None
        assert any(np.allclose(planner.unwrap(planner.safe, row), row) for row in path[1:-1])
        assert np.array_equal(path[0], start) and np.array_equal(path[-1], goal)
        assert planner.first_invalid(path, ctx, 0.01) is None
        through_safe += 1
        if through_safe == 2:
            break
    assert through_safe == 2


def test_a_kept_ik_outcome_gives_the_plan_a_fresh_planner_makes():
    # Deliveries to the dock need random IK restarts; their outcome is kept per target. A
    # planner that delivered before (from elsewhere) plans the same as a fresh one.
    model = LanderModel()
    terrain = HeightMap.flat(DEFAULT_GROUND_Z)
    request = {"use_defaults": True}
    used = Operations(ArmPlanner(model, PlannerConfig(seed=1)))
    used.plan("deliver_sample", model.q_from(STOWED), terrain, request)
    assert used.planner._cartesian._restart_outcomes  # the case this test is about
    again = used.plan("deliver_sample", model.q_from(UNSTOWED), terrain, request)
    fresh = Operations(ArmPlanner(LanderModel(), PlannerConfig(seed=1)))
    first = fresh.plan("deliver_sample", model.q_from(UNSTOWED), terrain, request)
    assert [s.label for s in again.segments] == [s.label for s in first.segments]
    for a, b in zip(again.segments, first.segments, strict=True):
        assert np.array_equal(a.waypoints, b.waypoints)
    tip = model.fk(used.planner.full(again.end, model.q_from(UNSTOWED)), SCOOP_TIP_FRAME)
    dock = np.add(DOCK_CENTRE, (0.0, 0.0, DOCK_POUR_HEIGHT))
    assert np.allclose(tip[:3, 3], dock, atol=1e-3)


def _same_plan(a, b):
    assert [s.label for s in a.segments] == [s.label for s in b.segments]
    for x, y in zip(a.segments, b.segments, strict=True):
        assert np.array_equal(x.waypoints, y.waypoints)


@pytest.mark.parametrize("off_chain", [0.0, 0.3])
def test_a_prepared_planner_delivers_to_the_dock_with_no_new_ik_restarts_and_the_same_plan(
    off_chain,
):
    # Prepared at start-up (grinder and antenna at 0), a planner needs no random IK restarts for
    # a dock delivery, even from where they are needed (the arm tipped over the dock) and
    # with the grinder and antenna elsewhere (they do not move the scoop), and plans what an
    # unprepared planner plans.
    model = LanderModel()
    terrain = HeightMap.flat(DEFAULT_GROUND_Z)
    request = {"use_defaults": True}
    first = Operations(ArmPlanner(model, PlannerConfig(seed=2)))
    unstowed = model.q_from(UNSTOWED)
    tipped = first.planner.full(
        first.plan("deliver_sample", unstowed, terrain, request).end, unstowed
    )
    off = dict.fromkeys((GRINDER_JOINT, *ANTENNA_JOINTS), off_chain)
    start = model.q_from(off, tipped)

    fresh = Operations(ArmPlanner(LanderModel(), PlannerConfig(seed=2)))
    expected = fresh.plan("deliver_sample", start, terrain, request)
    assert fresh.planner._cartesian._restart_outcomes  # the case this test is about

    prepared = Operations(ArmPlanner(LanderModel(), PlannerConfig(seed=2)))
    prepared.prepare(model.q_from({}))
    kept = dict(prepared.planner._cartesian._restart_outcomes)
    assert len(kept) == 12  # six headings, carrying and pouring
    _same_plan(prepared.plan("deliver_sample", start, terrain, request), expected)
    assert prepared.planner._cartesian._restart_outcomes.keys() == kept.keys()


def test_the_chain_of_a_tool_frame_is_its_arm_joints_and_the_grinders_spin_for_its_tip():
    model = LanderModel()
    arm = [model.index(j) for j in ARM_JOINTS]
    assert list(model.chain_columns(SCOOP_TIP_FRAME)) == arm
    grinder = list(model.chain_columns("l_grinder_tip"))
    assert grinder == [*arm[:5], model.index(GRINDER_JOINT)]
