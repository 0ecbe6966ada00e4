"""The fast validity checks give the answers of the plain ones (no ROS): terrain blocks bound the
terrain, coarse-to-fine path checks agree with the sequential check, Cartesian lines report and
stop where they are blocked."""

import re

import numpy as np
import pytest

from ow_lander.collision import ARM_LINKS, TerrainBlocks
from ow_lander.config import PlannerConfig
from ow_lander.description import DEFAULT_GROUND_Z, UNSTOWED
from ow_lander.errors import PlanningError
from ow_lander.model import LanderModel
from ow_lander.planning import ArmPlanner, CheckContext
from ow_lander.terrain import HeightMap
from ow_lander.validity import _coarse_to_fine


@pytest.fixture(scope="module")
def planner():
    return ArmPlanner(LanderModel(), PlannerConfig())


def _rough(seed: int, shape=(121, 121), resolution=0.05) -> HeightMap:
    rng = np.random.default_rng(seed)
    heights = DEFAULT_GROUND_Z + 0.05 * rng.standard_normal(shape)
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
