"""Geometry of every operation's plan, re-checked at 0.01 rad (no ROS)."""

import itertools
import math
from dataclasses import replace

import numpy as np
import pytest

from ow_description.description import (
    ARM_JOINTS,
    DEFAULT_GROUND_Z,
    SCOOP_ABOVE_GROUND,
    STOWED,
    UNSTOWED,
)
from ow_description.model import ARM_LINKS, LanderModel
from ow_description.terrain import HeightMap
from ow_description.trajectory import Speed
from ow_lander.config import PlannerConfig
from ow_lander.errors import PlanningError
from ow_lander.operations.planner import DOCK_CENTRE, Operations, shoulder_yaw_for
from ow_lander.planning.planner import ArmPlanner, CheckContext

GROUND = DEFAULT_GROUND_Z
DIGGING = {
    "descend",
    "pass_1",
    "shift",
    "pass_2",
    "retract",
    "dip_in",
    "cut",
    "lift_out",
    "sweep",
    "guarded",
}
#: The speed class of each labelled motion (the rest: free space): what the node's timing
#: policy, a table keyed by these labels, gave them before the plans carried their speeds.
SPEEDS = {
    "guarded": Speed.GUARDED,
    **dict.fromkeys(
        ("descend", "pass_1", "shift", "pass_2", "dip_in", "cut", "lift_out", "sweep"), Speed.DIG
    ),
}
TOOL = {
    "grind": "l_grinder",
    "dig_linear": "l_scoop",
    "dig_circular": "l_scoop",
    "guarded_move": "l_scoop",
}


@pytest.fixture(scope="module")
def ops():
    model = LanderModel()
    return Operations(ArmPlanner(model, PlannerConfig()))


@pytest.fixture(scope="module")
def terrain():
    return HeightMap.flat(GROUND)


def _q(model, pose):
    return model.q_from(pose)


def _tips(ops, q, path, frame):
    return np.array([ops.model.position(ops.planner.full(a, q), frame) for a in path])


def _check_collision_free(ops, q, terrain, plan):
    for segment in plan.segments:
        tool = TOOL.get(plan.operation) if segment.label in DIGGING else None
        links = tuple(link for link in ARM_LINKS if link != tool)
        ctx = CheckContext(q, terrain, links)
        assert ops.planner.first_invalid(segment.waypoints, ctx, 0.01) is None, segment.label
        previous = segment.waypoints[-1]
    assert previous is not None


@pytest.mark.parametrize(
    ("x", "y", "expected"), [(2.0, 0.0, -0.02063), (1.65, 0.0, -0.02899), (1.46, 0.0, -0.03714)]
)
def test_shoulder_yaw_matches_oceanwaters(x, y, expected):
    assert shoulder_yaw_for(x, y, -1.8, 1.8) == pytest.approx(expected, abs=1e-4)


CASES = [
    ("unstow", STOWED, None),
    ("stow", UNSTOWED, None),
    ("guarded_move", UNSTOWED, {"use_defaults": True}),
    ("grind", UNSTOWED, {"use_defaults": True}),
    (
        "grind",
        UNSTOWED,
        dict(x=1.7, y=0.1, depth=0.04, length=0.3, parallel=False, ground_position=GROUND),
    ),
    ("dig_linear", UNSTOWED, {"use_defaults": True}),
    ("dig_circular", UNSTOWED, {"use_defaults": True}),
    (
        "dig_circular",
        UNSTOWED,
        dict(x=1.6, y=0.1, depth=0.03, parallel=False, ground_position=GROUND),
    ),
    ("deliver_sample", UNSTOWED, {"use_defaults": True}),
]


@pytest.mark.parametrize(("name", "pose", "request_"), CASES)
def test_plan_starts_here_and_is_collision_free(ops, terrain, name, pose, request_):
    q = _q(ops.model, pose)
    method = getattr(ops, f"plan_{name}")
    plan = method(q, terrain) if request_ is None else method(q, terrain, request_)
    assert np.allclose(plan.segments[0].waypoints[0], q[ops.model.arm_idx])
    for a, b in itertools.pairwise(plan.segments):
        assert np.allclose(a.waypoints[-1], b.waypoints[0])
    assert [s.speed for s in plan.segments] == [
        SPEEDS.get(s.label, Speed.FREE) for s in plan.segments
    ]
    _check_collision_free(ops, q, terrain, plan)


@pytest.mark.parametrize(("parallel", "depth", "length"), [(True, 0.05, 0.6), (False, 0.03, 0.3)])
def test_grind_passes_at_depth_and_length(ops, terrain, parallel, depth, length):
    q = _q(ops.model, UNSTOWED)
    plan = ops.plan_grind(
        q,
        terrain,
        dict(x=1.65, y=0.0, depth=depth, length=length, parallel=parallel, ground_position=GROUND),
    )
    for label in ("pass_1", "pass_2"):
        path = next(s for s in plan.segments if s.label == label).waypoints
        tips = _tips(ops, q, path, "l_grinder_tip")
        assert np.allclose(tips[:, 2], GROUND - depth, atol=0.01)
        assert np.linalg.norm(tips[-1, :2] - tips[0, :2]) == pytest.approx(length, abs=0.01)
        axis = [ops.model.fk(ops.planner.full(a, q), "l_grinder_tip")[:3, 0] for a in path]
        assert np.allclose(axis, [0, 0, -1], atol=0.01)  # grinder vertical, pointing down


def test_dig_linear_cuts_at_depth_for_length(ops, terrain):
    q = _q(ops.model, UNSTOWED)
    plan = ops.plan_dig_linear(
        q, terrain, dict(x=1.6, y=0.0, depth=0.03, length=0.15, ground_position=GROUND)
    )
    path = next(s for s in plan.segments if s.label == "cut").waypoints
    tips = _tips(ops, q, path, "l_scoop_tip")
    assert np.allclose(tips[:, 2], GROUND - 0.03, atol=0.01)
    assert np.linalg.norm(tips[-1, :2] - tips[0, :2]) == pytest.approx(0.15, abs=0.01)
    assert _tips(ops, q, plan.segments[-1].waypoints[-1:], "l_scoop_tip")[0, 2] > GROUND


def _tilts_deg(ops, q, path):
    """deg, the angle between the scoop tip frame's z and straight down at each of ``path``:
    0 with the scoop level, its bottom down and its mouth up."""
    z = [ops.model.fk(ops.planner.full(a, q), "l_scoop_tip")[:3, 2] for a in path]
    return np.degrees(np.arccos(np.clip(-np.array(z)[:, 2], -1.0, 1.0)))


@pytest.mark.parametrize(("depth", "length"), [(0.05, 0.2), (0.03, 0.15), (0.1, 0.3), (0.05, 0.04)])
def test_dig_linear_curls_the_scoop_level_before_it_lifts_out(ops, terrain, depth, length):
    """The cut ends with the scoop curled level, its tip at the cut's depth, and the scoop lifts
    out and retracts level: it leaves the trench with what it cut (at its cutting attitude, its
    lip ~32 degrees from level, half a full scoop spilled as the dig ended)."""
    q = _q(ops.model, UNSTOWED)
    request = dict(x=1.6, y=0.0, depth=depth, length=length, ground_position=GROUND)
    plan = ops.plan_dig_linear(q, terrain, request)
    segments = {s.label: s.waypoints for s in plan.segments}
    cut = segments["cut"]
    assert _tilts_deg(ops, q, cut[:1])[0] > 10.0  # it cuts pitched into the ground
    assert np.allclose(_tilts_deg(ops, q, cut[-1:]), 0.0, atol=0.5)
    assert np.allclose(_tips(ops, q, cut, "l_scoop_tip")[:, 2], GROUND - depth, atol=0.01)
    out = np.vstack([segments["lift_out"], segments["retract"]])
    dense = np.linspace(out[0], out[-1], 50) if len(out) == 2 else out
    assert np.all(_tilts_deg(ops, q, dense) < 1.0)
    # The curl turns the scoop a little at a time: no joint jumps between waypoints.
    assert np.max(np.abs(np.diff(cut, axis=0))) <= PlannerConfig().max_joint_jump_rad + 1e-9


@pytest.mark.parametrize("parallel", [True, False])
def test_dig_circular_sweeps_120_degrees_to_depth(ops, terrain, parallel):
    q = _q(ops.model, UNSTOWED)
    plan = ops.plan_dig_circular(
        q, terrain, dict(x=1.65, y=0.0, depth=0.02, parallel=parallel, ground_position=GROUND)
    )
    sweep = next(s for s in plan.segments if s.label == "sweep").waypoints
    joint = ARM_JOINTS.index("j_dist_pitch" if parallel else "j_hand_yaw")
    change = sweep[-1] - sweep[0]
    assert abs(change[joint]) == pytest.approx(2 * math.pi / 3, abs=1e-6)
    assert np.allclose(np.delete(change, joint), 0.0)
    dense = np.linspace(sweep[0], sweep[-1], 241)
    tips = _tips(ops, q, dense, "l_scoop_tip")
    deepest = tips[np.argmin(tips[:, 2])]
    assert np.allclose(deepest, [1.65, 0.0, GROUND - 0.02], atol=0.01)


def test_deliver_ends_over_the_dock_tipped(ops, terrain):
    q = _q(ops.model, UNSTOWED)
    plan = ops.plan_deliver_sample(q, terrain, {"use_defaults": True})
    X = ops.model.fk(ops.planner.full(plan.end, q), "l_scoop_tip")
    assert np.allclose(X[:2, 3], DOCK_CENTRE[:2], atol=0.01)
    assert X[2, 3] > DOCK_CENTRE[2]
    # Tipped: the scoop's mouth (+x) points down, its bottom (+z) no longer faces down.
    assert X[2, 0] < -0.7
    assert X[2, 2] > -0.5


@pytest.mark.parametrize("seed", [1, 6, 12, 42])
def test_deliver_from_unstowed_takes_a_heading_straight_moves_reach(terrain, seed):
    # With some seeds the IK of the first heading gives a pour only a sampled detour reaches
    # (RRT*); another heading's straight joint moves are preferred to it.
    model = LanderModel()
    ops = Operations(ArmPlanner(model, PlannerConfig(seed=seed)))
    q = _q(model, UNSTOWED)
    plan = ops.plan_deliver_sample(q, terrain, {"use_defaults": True})
    assert ops.planner.stats.rrt_segments == 0
    assert all(len(segment.waypoints) <= 3 for segment in plan.segments)
    _check_collision_free(ops, q, terrain, plan)
    X = model.fk(ops.planner.full(plan.end, q), "l_scoop_tip")
    assert np.allclose(X[:2, 3], DOCK_CENTRE[:2], atol=0.01)
    assert X[2, 0] < -0.7


def test_unstow_ends_unstowed(ops, terrain):
    plan = ops.plan_unstow(_q(ops.model, STOWED), terrain)
    assert np.allclose(plan.end, [UNSTOWED[j] for j in ARM_JOINTS])


def test_same_request_same_plan(ops, terrain):
    q = _q(ops.model, UNSTOWED)
    a = ops.plan_deliver_sample(q, terrain, {"use_defaults": True})
    b = ops.plan_deliver_sample(q, terrain, {"use_defaults": True})
    for sa, sb in zip(a.segments, b.segments, strict=True):
        assert np.array_equal(sa.waypoints, sb.waypoints)


BAD = [
    (
        "plan_grind",
        dict(x=1.6, y=0, depth=-0.1, length=0.2, parallel=True, ground_position=GROUND),
        "depth=-0.100 m must not be negative",
    ),
    (
        "plan_grind",
        dict(x=1.6, y=0, depth=0.2, length=0.2, parallel=True, ground_position=GROUND),
        "deeper than the grinder can go (max 0.14 m)",
    ),
    (
        "plan_grind",
        dict(x=0.8, y=0.2, depth=0.05, length=0.2, parallel=True, ground_position=GROUND),
        "closer than the arm plane offset",
    ),
    (
        "plan_dig_linear",
        dict(x=1.6, y=0, depth=0.02, length=-1, ground_position=GROUND),
        "length=-1.000 m must be in (0, 1.0] m",
    ),
    (
        "plan_dig_circular",
        dict(x=math.nan, y=0, depth=0.02, parallel=True, ground_position=GROUND),
        "x=nan is not a finite number",
    ),
    (
        "plan_guarded_move",
        dict(x=2, y=0, z=0.3, direction_x=0, direction_y=0, direction_z=0, search_distance=0.5),
        "zero vector",
    ),
    (
        "plan_guarded_move",
        dict(x=2, y=0, z=0.3, direction_x=0, direction_y=0, direction_z=1, search_distance=-1),
        "search_distance=-1.000 m must be > 0",
    ),
    (
        "plan_guarded_move",
        dict(
            x=0.0, y=-2.0, z=0.3, direction_x=0, direction_y=0, direction_z=1, search_distance=0.5
        ),
        "outside the joint limits",
    ),
]


@pytest.mark.parametrize(("method", "request_", "message"), BAD)
def test_bad_requests_name_the_value_and_limit(ops, terrain, method, request_, message):
    with pytest.raises(PlanningError) as error:
        getattr(ops, method)(_q(ops.model, UNSTOWED), terrain, request_)
    assert message in str(error.value)


def test_approach_takes_the_near_turn_of_a_wrist_left_a_turn_away(ops, terrain):
    # Where the mission's second grind left the arm: the hand yaw at 4.19 rad (= -2.09 + 2 pi).
    left = dict(zip(ARM_JOINTS, [0.064, 1.478, -2.185, 0.707, 4.189, 0.0], strict=True))
    q = _q(ops.model, {**UNSTOWED, **left})
    request = dict(x=1.65, y=0.0, depth=0.05, length=0.2, ground_position=GROUND)
    plan = ops.plan_dig_linear(q, terrain, request)
    approach = plan.segments[0].waypoints
    hand = ARM_JOINTS.index("j_hand_yaw")
    # The same scoop pose as the operation's own turn, reached by turning the hand less than
    # half a turn instead of 4.19 rad back through the elbow.
    assert abs(approach[-1, hand] - approach[0, hand]) < math.pi
    assert abs(np.diff(approach[:, hand])).sum() < math.pi
    _check_collision_free(ops, q, terrain, plan)


def test_a_start_inside_the_lander_model_is_left_by_an_escape_first(ops, terrain):
    """The shoulder yaw on its -1.8 rad limit (where a -1e9 set-point leaves it: the simulation
    has no arm-lander contacts) puts l_prox inside the lander body of the planner's model. Every
    operation then starts with a straight move towards the unstowed pose that ends collision-free
    (and no further than 0.05 rad past the first collision-free state); the rest of the plan is
    collision-free as usual."""
    q = _q(ops.model, {**UNSTOWED, "j_shou_yaw": -1.8})
    arm = ops.planner.arm(q)
    assert not ops.planner.is_valid(arm, CheckContext(q, None))
    for name, request_ in (("unstow", None), ("stow", None), ("grind", {"use_defaults": True})):
        plan = ops.plan(name, q, terrain, request_)
        escape = plan.segments[0]
        assert escape.label == "escape"
        start, end = escape.waypoints
        assert np.array_equal(start, arm)
        assert ops.planner.is_valid(end, CheckContext(q, terrain))
        back = end - (end - start) * (0.06 / np.max(np.abs(end - start)))  # 0.06 rad back
        assert not ops.planner.is_valid(back, CheckContext(q, None))  # out, and not much further
        _check_collision_free(
            ops, ops.planner.full(end, q), terrain, replace(plan, segments=plan.segments[1:])
        )
        assert "moved out first" in " ".join(plan.notes)


def test_no_escape_from_a_valid_start(ops, terrain):
    assert ops.motions.escape(_q(ops.model, STOWED), terrain) is None
    assert ops.plan("unstow", _q(ops.model, STOWED), terrain).segments[0].label != "escape"


def _cut_state(ops, terrain):
    """The end of a 0.1 m deep linear dig's cut, the scoop curled level (where a dig cancelled
    before its lift leaves the arm: the hand in the trench, below the ground beside it)."""
    q = _q(ops.model, UNSTOWED)
    request = dict(x=1.65, y=0.0, depth=0.1, length=0.3, ground_position=GROUND)
    cut = next(s for s in ops.plan_dig_linear(q, terrain, request).segments if s.label == "cut")
    return ops.planner.full(cut.waypoints[-1], q)


def _deepest_sweep_state(ops, terrain):
    """The state of a 0.1 m deep circular dig's sweep with the hand lowest."""
    q = _q(ops.model, UNSTOWED)
    request = dict(x=1.65, y=0.0, depth=0.1, parallel=True, ground_position=GROUND)
    sweep = ops.plan_dig_circular(q, terrain, request).segments[-1].waypoints
    states = np.linspace(sweep[0], sweep[-1], 121)
    return ops.planner.full(
        min(states, key=lambda a: ops.model.fk(ops.planner.full(a, q), "l_hand")[2, 3]), q
    )


def _hand_bottom(ops, q) -> float:
    """m, the height of l_hand's lowest point at ``q``."""
    return 1.0 - ops.model.collision.terrain_contact(q, HeightMap.flat(1.0), ("l_hand",))[1]


#: Starts in the terrain: (name, configuration maker, l_hand's depth in the terrain m: the
#: terrain is flat at that height above the hand's lowest point; None: the ground at GROUND).
IN_THE_TERRAIN = [
    ("scoop_buried", lambda ops, terrain: _q(ops.model, SCOOP_ABOVE_GROUND), 0.02),
    ("hand_buried", lambda ops, terrain: _q(ops.model, SCOOP_ABOVE_GROUND), 0.12),
    ("dig_cancelled_in_its_cut", _cut_state, None),
    ("circular_dig_stopped_deep", _deepest_sweep_state, 0.1),
]


@pytest.mark.parametrize(("start", "make", "hand_depth"), IN_THE_TERRAIN)
@pytest.mark.parametrize("name", ["unstow", "stow", "move_joints", "move_cartesian"])
def test_a_start_in_the_terrain_is_left_by_a_lift_first(
    ops, terrain, start, make, hand_depth, name
):
    """Item 5 ("never stranded"): with links in the terrain (the hand too: a burial, a dig
    stopped deep) every operation starts with a lift of the scoop tip out of the terrain;
    before, every one was refused with "the arm's current configuration is invalid". On the
    way out only the links already in the terrain may be in it; after it none is."""
    q = make(ops, terrain)
    ground = GROUND if hand_depth is None else _hand_bottom(ops, q) + hand_depth
    buried = HeightMap.flat(ground)
    _, hand_below = ops.model.collision.terrain_contact(q, buried, ("l_hand",))
    assert hand_below > 0.0  # the dig's cut: the hand is below the ground beside it
    here = ops.model.fk(q, "l_scoop_tip")
    requests = {
        "move_joints": {"angles": [UNSTOWED[j] for j in ARM_JOINTS]},
        "move_cartesian": {
            "position": here[:3, 3] + [0.0, 0.0, ground - here[2, 3] + 0.3],
            "rotation": here[:3, :3],
        },
    }
    plan = ops.plan(name, q, buried, requests.get(name))
    lift = plan.segments[0]
    assert lift.label == "lift_off" and "lifted it out first" in " ".join(plan.notes)
    assert np.array_equal(lift.waypoints[0], ops.planner.arm(q))
    leaving, depths = ops.motions.leaving(q, buried, tools=True)
    assert depths["l_hand"] == pytest.approx(hand_below)
    assert ops.planner.first_invalid(lift.waypoints, leaving, 0.01) is None
    out = ops.planner.full(lift.waypoints[-1], q)
    assert ops.planner.is_valid(lift.waypoints[-1], CheckContext(out, buried))
    _check_collision_free(ops, out, buried, replace(plan, segments=plan.segments[1:]))


def test_a_lander_in_the_terrain_up_to_its_shoulder_is_refused_with_the_reason(ops):
    """The terrain up to the shoulder (z 0.27 m): no motion takes the arm out of it, and the
    refusal says which link stays in it."""
    with pytest.raises(
        PlanningError, match=r"cannot lift l_\w+ out of the terrain: .*l_\w+ is \d+ mm below"
    ):
        ops.plan("unstow", _q(ops.model, SCOOP_ABOVE_GROUND), HeightMap.flat(0.15))
