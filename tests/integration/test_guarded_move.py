"""Guarded move through the real services on the real simulation: the ground found by the paper's
detector (tf2 scoop-tip velocity on sim time) against the terrain's true height."""

import pytest
import rospy
from geometry_msgs.msg import PointStamped

from ow_msgs.msg import GuardedMoveResult
from ow_msgs.srv import GuardedMove, SetTerrain, Unstow

TOLERANCE_M = 0.005
#: Known failure (issue 5, open): after /sim/set_terrain the next guarded move is refused because
#: the planner sees the hand below the terrain; not yet tracked down.
AFTER_TERRAIN_SWITCH = pytest.mark.xfail(
    reason="issue 5: planning after a terrain switch sees the hand below the terrain",
    strict=False,
)


@pytest.fixture(scope="module")
def stack(ros_stack):
    ros_stack.start_node(
        "ow_sim_bullet",
        "sim",
        params={"terrain": "flat:-0.10", "real_time_factor": 0.0},
        wait_for_services=["/sim/set_terrain"],
    )
    ros_stack.start_node(
        "ow_lander",
        "arm_services",
        params={"plan_and_execute": True},
        wait_for_services=["/arm/guarded_move"],
    )
    response = ros_stack.service("/arm/unstow", Unstow)(delete_prev_traj=False)
    assert response.success, response.message
    return ros_stack


def _guarded_move(stack, x, y, z, search=0.5):
    results = []
    started = rospy.Time.now()
    # The topic is latched: keep only what this move published.
    sub = rospy.Subscriber(
        "/guarded_move_result",
        GuardedMoveResult,
        lambda msg: results.append(msg) if msg.header.stamp >= started else None,
    )
    try:
        response = stack.service("/arm/guarded_move", GuardedMove)(
            use_defaults=False, x=x, y=y, z=z, direction_x=0.0, direction_y=0.0,
            direction_z=1.0, search_distance=search,
        )  # fmt: skip
        rospy.sleep(0.5)  # sim time: the latched result reaches us
    finally:
        sub.unregister()
    return response, results


def _true_ground():
    """Terrain height under the scoop tip now, from the simulation's ground truth."""
    return rospy.wait_for_message("/sim/scoop_tip_ground", PointStamped, timeout=10).point.z


@pytest.mark.parametrize(
    "ground_z", [-0.10, -0.155, pytest.param(-0.20, marks=AFTER_TERRAIN_SWITCH)]
)
def test_finds_flat_ground_at_several_heights(stack, ground_z):
    terrain = stack.service("/sim/set_terrain", SetTerrain)(terrain=f"flat:{ground_z}")
    assert terrain.success, terrain.message
    response, results = _guarded_move(stack, 1.7, 0.0, ground_z + 0.2)
    assert response.success, response.message
    assert response.ground_found
    assert response.ground_position.z == pytest.approx(ground_z, abs=TOLERANCE_M)
    # Published once per move, with the same position, in base_link.
    found = [r for r in results if r.success]
    assert len(found) == 1
    assert found[0].frame == "base_link"
    assert found[0].position.z == pytest.approx(response.ground_position.z, abs=1e-6)


@AFTER_TERRAIN_SWITCH
def test_finds_the_europa_workspace_surface(stack):
    terrain = stack.service("/sim/set_terrain", SetTerrain)(terrain="europa:3")
    assert terrain.success, terrain.message
    response, _ = _guarded_move(stack, 1.6, 0.1, 0.1)
    assert response.success, response.message
    assert response.ground_position.z == pytest.approx(_true_ground(), abs=TOLERANCE_M)


def test_no_ground_within_the_search_distance_is_a_failure(stack):
    terrain = stack.service("/sim/set_terrain", SetTerrain)(terrain="flat:-0.4")
    assert terrain.success, terrain.message
    response, results = _guarded_move(stack, 1.7, 0.0, 0.1, search=0.1)
    assert not response.success
    assert "no ground within 0.10 m" in response.message
    assert not response.ground_found
    assert [r.success for r in results] == [False]


@pytest.mark.parametrize(
    ("fields", "match"),
    [
        ({"direction_z": 0.0}, "zero vector"),
        ({"search_distance": 0.0}, "search_distance=0.000 m must be > 0"),
        ({"search_distance": -0.2}, "search_distance=-0.200 m must be > 0"),
        ({"x": 5.0}, "cannot reach"),
        ({"x": float("nan")}, "not a finite number"),
    ],
)
def test_bad_requests_are_refused_with_a_reason(stack, fields, match):
    request = dict(
        use_defaults=False, x=1.7, y=0.0, z=0.1, direction_x=0.0, direction_y=0.0,
        direction_z=1.0, search_distance=0.3,
    )  # fmt: skip
    request.update(fields)
    response = stack.service("/arm/guarded_move", GuardedMove)(**request)
    assert not response.success
    assert match in response.message
