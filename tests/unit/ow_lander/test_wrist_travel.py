"""A wrist wound up by repeated operations: the continuous joints hold any angle, but the
simulated joint turns only two turns each way. An operation's approach leaves room for its own
turns, and a motion that would run past the end of the travel says so."""

import math

import numpy as np
import pytest

from ow_description.description import ARM_JOINTS, CONTINUOUS_TRAVEL, UNSTOWED
from ow_description.model import LanderModel
from ow_description.terrain import HeightMap
from ow_lander.config import PlannerConfig
from ow_lander.errors import PlanningError
from ow_lander.operations.motions import TURN_HEADROOM_RAD
from ow_lander.operations.planner import Operations
from ow_lander.planning.planner import ArmPlanner, CheckContext

GROUND = -0.155
HAND = ARM_JOINTS.index("j_hand_yaw")
#: Where OceanWATERS' scoop-circular script's third grind (x_start 2.0, y_start 0.6) left the
#: arm on our stack: the hand yaw a turn and a third below zero.
WOUND = [0.607, 0.787, -1.006, 0.219, -8.378, 0.0]
#: That script's next goal: a perpendicular circular scoop in the grind's trench.
CIRCULAR = dict(
    use_defaults=False,
    centred=True,
    x=2.0,
    y=0.6,
    depth=0.02,
    ground_position=GROUND,
    parallel=False,
)


@pytest.fixture(scope="module")
def ops():
    return Operations(ArmPlanner(LanderModel(), PlannerConfig()))


def _wound(ops, hand):
    arm = list(WOUND)
    arm[HAND] = hand
    return ops.model.q_from({**UNSTOWED, **dict(zip(ARM_JOINTS, arm, strict=True))})


@pytest.mark.parametrize("hand", [-8.378, -10.5, 10.5])
@pytest.mark.parametrize("parallel", [False, True])
def test_a_circular_scoop_from_a_wound_wrist_stays_within_the_travel(ops, hand, parallel):
    q = _wound(ops, hand)
    plan = ops.plan("dig_circular", q, HeightMap.flat(GROUND), {**CIRCULAR, "parallel": parallel})
    path = np.vstack([segment.waypoints for segment in plan.segments])
    assert np.all(np.abs(path[:, HAND]) <= CONTINUOUS_TRAVEL + 1e-9)
    # The sweep starts where the approach ended: inside the travel by the headroom (or the
    # joint did not need to move there at all).
    approach_end = plan.segments[0].waypoints[-1]
    assert abs(approach_end[HAND]) <= CONTINUOUS_TRAVEL - TURN_HEADROOM_RAD + 1e-9


def test_the_approach_turns_the_long_way_only_to_leave_room(ops):
    # Near zero the approach takes the short way, as before: no extra turn.
    q = _wound(ops, -2.09)
    plan = ops.plan("dig_circular", q, HeightMap.flat(GROUND), CIRCULAR)
    approach = plan.segments[0].waypoints
    assert abs(approach[-1, HAND] - approach[0, HAND]) < math.pi


def test_a_motion_past_the_travel_is_named(ops):
    checker = ops.planner.checker
    q = _wound(ops, -8.378)
    arm = ops.planner.arm(q)
    arm[HAND] = -CONTINUOUS_TRAVEL - 0.01
    ctx = CheckContext(q, None)
    assert not ops.planner.is_valid(arm, ctx)
    assert "j_hand_yaw=-12.576 rad is beyond the joint's travel [-12.566, 12.566]" in (
        checker.explain(arm, ctx)
    )
    start = ops.planner.arm(q)
    with pytest.raises(PlanningError, match="beyond the joint's travel"):
        ops.planner.plan_joint_sweep(start, arm, ctx)
