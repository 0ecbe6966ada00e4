"""The delivery to the sample dock (ow_lander.operations.planner): the scoop carried level from
where a dig leaves it to the staging pose over the dock, the pour by the distal pitch alone,
and where the regolith model (ow_regolith: the scoop's spill rule, the dock and the lander's
boxes) says a full scoop's content lands along that pour: in the dock."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ow_description.description import ARM_JOINTS, DEFAULT_GROUND_Z, STOWED, UNSTOWED
from ow_description.model import LanderModel
from ow_description.terrain import HeightMap
from ow_lander.config import PlannerConfig
from ow_lander.operations.planner import (
    DOCK_CENTRE,
    DOCK_POUR_HEIGHT,
    DOCK_STAGING_TIP,
    POUR_TILT,
    Operations,
)
from ow_lander.planning.planner import ArmPlanner
from ow_lander.planning.validity import densify
from ow_regolith.landing import Landing, PourTargets
from ow_regolith.scoop import ScoopGeometry

GROUND = DEFAULT_GROUND_Z
DIST = ARM_JOINTS.index("j_dist_pitch")


@pytest.fixture(scope="module")
def ops() -> Operations:
    return Operations(ArmPlanner(LanderModel(), PlannerConfig()))


@pytest.fixture(scope="module")
def terrain() -> HeightMap:
    return HeightMap.flat(GROUND)


@pytest.fixture(scope="module")
def regolith() -> tuple[ScoopGeometry, PourTargets]:
    return ScoopGeometry.from_urdf(), PourTargets.from_urdf()


def _after_dig(ops, terrain, depth: float, x: float = 1.65) -> np.ndarray:
    """(9,) rad where a linear dig of ``depth`` m at ``x`` leaves the arm (its plan's end)."""
    q = ops.model.q_from(UNSTOWED)
    request = dict(x=x, y=0.0, depth=depth, length=0.2, ground_position=GROUND)
    return ops.planner.full(ops.plan("dig_linear", q, terrain, request).end, q)


#: Where a delivery of a sample starts: where the linear digs leave the scoop, level.
STARTS = {
    "after_the_spoil_dig": lambda ops, terrain: _after_dig(ops, terrain, 0.1),
    "after_a_sample_dig": lambda ops, terrain: _after_dig(ops, terrain, 0.05, 1.75),
    "after_a_shallow_near_dig": lambda ops, terrain: _after_dig(ops, terrain, 0.03, 1.45),
}


def _tilt_deg(ops, q, arm) -> float:
    """deg, between the scoop tip frame's z and straight down: 0 with the scoop level."""
    z = ops.model.fk(ops.planner.full(arm, q), "l_scoop_tip")[2, 2]
    return math.degrees(math.acos(min(1.0, -z)))


def _landings(ops, q, path, regolith) -> dict[Landing, float]:
    """Where a full scoop's content lands along ``path`` (n, 6) rad (the spill rule: what lies
    above the mouth's lowest corner pours there, straight down), as shares of its capacity."""
    geometry, targets = regolith
    held, landed = 1.0, {}
    for arm in densify(path, 0.005):
        X = ops.model.fk(ops.planner.full(arm, q), "l_scoop")
        kept = geometry.retained_m3(X[:3, :3]) / geometry.capacity_m3
        if kept < held:
            where = targets.landing(geometry.pour_point(X), HeightMap.flat(GROUND))
            landed[where] = landed.get(where, 0.0) + held - kept
            held = kept
    return landed


@pytest.mark.parametrize("start", list(STARTS))
def test_the_scoop_is_carried_level_to_the_staging_pose_and_pours_into_the_dock(
    ops, terrain, regolith, start
):
    q = STARTS[start](ops, terrain)
    plan = ops.plan("deliver_sample", q, terrain, {"use_defaults": True})
    assert [s.label for s in plan.segments] == ["approach", "pour"]
    assert plan.notes == []
    approach, pour = (s.waypoints for s in plan.segments)
    # Level all the way (the dig leaves it level; within a degree of it anywhere between).
    assert _tilt_deg(ops, q, approach[0]) < 0.5
    assert max(_tilt_deg(ops, q, a) for a in densify(approach, 0.01)) < 1.0
    tip = ops.model.fk(ops.planner.full(approach[-1], q), "l_scoop_tip")[:3, 3]
    assert np.allclose(tip, DOCK_STAGING_TIP, atol=1e-3)
    # The pour: the distal pitch alone turns by POUR_TILT.
    turned = pour[1] - pour[0]
    assert turned[DIST] == pytest.approx(POUR_TILT)
    assert np.allclose(np.delete(turned, DIST), 0.0)
    # Everything a full scoop holds pours out there, and into the dock.
    landed = _landings(ops, q, pour[:2], regolith)
    assert sum(landed.values()) == pytest.approx(1.0)
    assert landed.get(Landing.DOCK, 0.0) > 0.99, landed
    # The delivery ends where every delivery to the dock ends: the tip over the dock centre.
    end = ops.model.fk(ops.planner.full(plan.end, q), "l_scoop_tip")[:3, 3]
    assert np.allclose(end, np.add(DOCK_CENTRE, (0.0, 0.0, DOCK_POUR_HEIGHT)), atol=1e-3)


def test_a_straight_move_between_two_level_poses_keeps_the_scoop_level(ops, terrain):
    """The hand yaw at a whole turn and the three pitches summing to zero: linear conditions,
    kept by a straight joint move and by the staged moves of ArmMotions.level_route."""
    q = _after_dig(ops, terrain, 0.05)
    start = ops.planner.arm(q)
    goal = start + np.array([-0.6, 0.2, -0.1, -0.1, 0.0, 0.8])  # pitches still sum to 0
    assert sum(goal[1:4]) == pytest.approx(sum(start[1:4]))
    ctx = ops.motions.context(q, terrain)
    route = ops.motions.level_route(start, goal, ctx)
    assert np.allclose(route[0], start) and np.allclose(route[-1], goal)
    assert max(_tilt_deg(ops, q, a) for a in densify(route, 0.01)) < 0.01
    for arm in (start, goal, 0.5 * (start + goal)):
        assert _tilt_deg(ops, q, arm) < 0.01


@pytest.mark.parametrize("pose", [STOWED, UNSTOWED])
def test_a_delivery_from_a_tilted_scoop_still_ends_over_the_dock(ops, terrain, pose):
    q = ops.model.q_from(pose)
    plan = ops.plan("deliver_sample", q, terrain, {"use_defaults": True})
    end = ops.model.fk(ops.planner.full(plan.end, q), "l_scoop_tip")[:3, 3]
    assert np.allclose(end, np.add(DOCK_CENTRE, (0.0, 0.0, DOCK_POUR_HEIGHT)), atol=1e-3)
