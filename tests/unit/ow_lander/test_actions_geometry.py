"""Where OceanWATERS' task actions put their trenches and the scoop (HEAD's semantics on the
paper's operations: ``centred`` requests, ArmFindSurface's scoop orientation), re-checked by
forward kinematics of the plans (no ROS master)."""

import math

import numpy as np
import pytest

from ow_description.description import GRINDER_TIP_FRAME, SCOOP_TIP_FRAME, UNSTOWED
from ow_description.model import LanderModel
from ow_description.terrain import HeightMap
from ow_lander.actions.owl import rotation_between
from ow_lander.config import PlannerConfig
from ow_lander.errors import PlanningError
from ow_lander.operations.planner import Operations, shoulder_yaw_for
from ow_lander.operations.workspace import GRIND_PASS_SHIFT
from ow_lander.planning.planner import ArmPlanner

GROUND = -0.172  # m, OceanWATERS' DEFAULT_GROUND_HEIGHT


@pytest.fixture(scope="module")
def ops():
    return Operations(ArmPlanner(LanderModel(), PlannerConfig()))


@pytest.fixture(scope="module")
def terrain():
    return HeightMap.flat(GROUND)


@pytest.fixture(scope="module")
def q(ops):
    return ops.model.q_from(UNSTOWED)


def _ends(ops, q, plan, frame):
    """(3,) m, the tool frame at the end of each labelled segment."""
    return {
        s.label: ops.model.position(ops.planner.full(s.waypoints[-1], q), frame)
        for s in plan.segments
    }


def _yaw(x, y):
    return shoulder_yaw_for(x, y, -math.pi, math.pi)


@pytest.mark.parametrize(
    ("x", "y", "depth", "length", "parallel"),
    [(1.65, 0.0, 0.05, 0.6, False), (2.0, 0.6, 0.1, 0.4, False), (1.8, -0.2, 0.05, 0.4, True)],
)
def test_grind_centred_between_its_passes(ops, terrain, q, x, y, depth, length, parallel):
    request = dict(x=x, y=y, depth=depth, length=length, parallel=parallel, ground_position=GROUND)
    plan = ops.plan_grind(q, terrain, {**request, "centred": True})
    ends = _ends(ops, q, plan, GRINDER_TIP_FRAME)
    corners = [ends["descend"], ends["pass_1"], ends["shift"], ends["pass_2"]]
    assert np.allclose(np.mean(corners, axis=0), [x, y, GROUND - depth], atol=2e-3)
    assert np.linalg.norm(corners[1] - corners[0]) == pytest.approx(length, abs=2e-3)
    assert np.linalg.norm(corners[2] - corners[1]) == pytest.approx(GRIND_PASS_SHIFT, abs=2e-3)
    yaw = _yaw(x, y)
    radial = np.array([math.cos(yaw), math.sin(yaw), 0.0])
    along = (corners[1] - corners[0]) / length
    assert abs(along @ radial) == pytest.approx(1.0 if parallel else 0.0, abs=1e-3)
    # The grinder stays vertical (its axis, the tip's x, straight down) along the passes.
    for segment in plan.segments[2:5]:
        for arm in segment.waypoints:
            X = ops.model.fk(ops.planner.full(arm, q), GRINDER_TIP_FRAME)
            assert X[:3, 0] @ [0.0, 0.0, -1.0] == pytest.approx(1.0, abs=1e-3)


def test_grind_depth_oceanwaters_accepts_is_not_refused(ops, terrain, q):
    request = dict(x=1.8, y=0.0, depth=0.15, length=0.4, parallel=True, ground_position=GROUND)
    with pytest.raises(PlanningError, match="deeper than the grinder can go"):
        ops.plan_grind(q, terrain, request)  # the paper's service keeps its limit
    plan = ops.plan_grind(q, terrain, {**request, "centred": True})
    assert _ends(ops, q, plan, GRINDER_TIP_FRAME)["pass_1"][2] == pytest.approx(GROUND - 0.15)


@pytest.mark.parametrize(
    ("x", "y", "length"), [(1.4, 0.0, 0.3), (1.6, 0.4, 0.1), (1.6, -0.2, 0.03)]
)
def test_linear_dig_point_is_the_middle_of_the_cut(ops, terrain, q, x, y, length):
    request = dict(x=x, y=y, depth=0.01, length=length, ground_position=GROUND, centred=True)
    ends = _ends(ops, q, ops.plan_dig_linear(q, terrain, request), SCOOP_TIP_FRAME)
    start, end = ends["dip_in"], ends["cut"]
    assert np.allclose((start + end) / 2, [x, y, GROUND - 0.01], atol=2e-3)
    yaw = _yaw(x, y)
    assert np.allclose(end - start, length * np.array([math.cos(yaw), math.sin(yaw), 0]), atol=2e-3)


@pytest.mark.parametrize(
    ("point", "normal", "distance", "overdrive"),
    [
        ((1.7, 0.5, GROUND), (0.0, 0.0, 1.0), 0.2, 0.05),
        ((2.0, 0.17, GROUND), (0.0, 0.0, 1.0), 0.2, 0.1),
        ((1.86, -0.63, GROUND), (0.1, 0.3, 0.8124), 0.2, 0.1),
    ],
)
def test_guarded_move_takes_the_asked_scoop_orientation(
    ops, terrain, q, point, normal, distance, overdrive
):
    n = np.asarray(normal) / np.linalg.norm(normal)
    start = np.asarray(point) + distance * n
    R = rotation_between([0.0, 0.0, 1.0], -n)
    request = dict(
        x=start[0], y=start[1], z=start[2],
        direction_x=n[0], direction_y=n[1], direction_z=n[2],
        search_distance=distance + overdrive, rotation=R.tolist(),
    )  # fmt: skip
    plan = ops.plan_guarded_move(q, terrain, request)
    approach, descent = plan.segments[-2], plan.segments[-1]
    X = ops.model.fk(ops.planner.full(approach.waypoints[-1], q), SCOOP_TIP_FRAME)
    assert np.allclose(X[:3, 3], start, atol=1e-3)
    assert np.allclose(X[:3, :3], R, atol=2e-3)
    end = ops.model.position(ops.planner.full(descent.waypoints[-1], q), SCOOP_TIP_FRAME)
    assert np.allclose(end, np.asarray(point) - overdrive * n, atol=2e-3)
    assert not plan.notes


def test_guarded_move_turns_about_the_normal_when_the_asked_orientation_fails(
    ops, terrain, q, monkeypatch
):
    asked = rotation_between([0.0, 0.0, 1.0], [0.0, 0.0, -1.0])
    solve_ik = ops.planner.solve_ik

    def refuse_asked(frame, position, rotation, seed, ctx):
        if rotation is not None and np.allclose(rotation, asked):
            raise PlanningError("placing l_scoop_tip there is not possible without a collision")
        return solve_ik(frame, position, rotation, seed, ctx)

    monkeypatch.setattr(ops.planner, "solve_ik", refuse_asked)
    request = dict(
        x=1.7, y=0.0, z=GROUND + 0.2, direction_x=0.0, direction_y=0.0, direction_z=1.0,
        search_distance=0.3, rotation=asked.tolist(),
    )  # fmt: skip
    plan = ops.plan_guarded_move(q, terrain, request)
    X = ops.model.fk(ops.planner.full(plan.segments[-2].waypoints[-1], q), SCOOP_TIP_FRAME)
    assert np.allclose(X[:3, 3], [1.7, 0.0, GROUND + 0.2], atol=1e-3)
    assert X[:3, 2] @ [0.0, 0.0, -1.0] == pytest.approx(1.0, abs=1e-3)  # bottom still down
    assert not np.allclose(X[:3, :3], asked, atol=1e-2)
    assert any("turned about the normal" in note for note in plan.notes)


@pytest.mark.parametrize("point", [(2.0, -0.3, 0.545), (2.1, 0.2, 0.528), (1.3, 0.9, 0.4)])
def test_discard_holds_the_scoop_link_at_the_point(ops, terrain, q, point):
    # OceanWATERS' TaskDiscardSample places l_scoop's origin (not the tip) and tips about it.
    plan = ops.plan_discard(q, terrain, dict(x=point[0], y=point[1], z=point[2]))
    carry, pour = plan.segments[-2].waypoints[-1], plan.segments[-1].waypoints[-1]
    for arm in (carry, pour):
        assert np.allclose(
            ops.model.position(ops.planner.full(arm, q), "l_scoop"), point, atol=2e-3
        )
    tipped = ops.model.fk(ops.planner.full(pour, q), SCOOP_TIP_FRAME)[:3, :3]
    upright = ops.model.fk(ops.planner.full(carry, q), SCOOP_TIP_FRAME)[:3, :3]
    assert math.degrees(math.acos((np.trace(upright.T @ tipped) - 1) / 2)) == pytest.approx(
        110, abs=1
    )
