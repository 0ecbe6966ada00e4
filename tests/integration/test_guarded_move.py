"""Guarded move through the real services on the real simulation: the ground found by the paper's
detector (tf2 scoop-tip velocity on sim time) against the terrain's true height.

Each case lifts the arm clear (unstow) before it switches the terrain, so no tool is buried in
the new terrain; the true height is the terrain as made (``ow_sim_bullet.terrains``, the same
code the simulation builds it with) at the reported contact point, or the carved terrain the
simulation publishes for a trench.
"""

import re
import time

import numpy as np
import pytest
import rospy

from ow_bringup.testing import FLAT, set_terrain, subscribe
from ow_description.conversions import height_map_from_msg
from ow_description.description import DEFAULT_GROUND_Z
from ow_msgs.msg import GuardedMoveResult
from ow_msgs.msg import HeightMap as HeightMapMsg
from ow_msgs.srv import Grind, GuardedMove
from ow_sim_bullet.terrains import GRID_RESOLUTION, parse_terrain_spec

TOLERANCE_M = 0.005
SLOPE = np.tan(np.radians(10.0))


@pytest.fixture(scope="module")
def slope_file(tmp_path_factory):
    """A plane rising 10 degrees towards +y through the default ground height at y = 0 (a .npy
    height map on the simulation's default file grid: centre (1.5, 0) m, 4 cm cells)."""
    n = 101
    y = (np.arange(n) - (n - 1) / 2) * GRID_RESOLUTION
    heights = np.tile((DEFAULT_GROUND_Z + SLOPE * y)[:, None], (1, n))
    path = tmp_path_factory.mktemp("terrain") / "slope.npy"
    np.save(path, heights)
    return path


@pytest.fixture(scope="module")
def stack(start_lander):
    # In the lockstep: where the descent stops does not depend on how loaded the machine is
    # (a free-running stack under make test's load once found the slope 14 mm deep).
    return start_lander(
        terrain="flat:-0.10",
        arm={"execution": {"lockstep": True}},
        arm_services=["/arm/guarded_move"],
        sim_topics=[],
    )


def _guarded_move(stack, x, y, z, search=0.5, normal=(0.0, 0.0, 1.0)):
    results = []
    started = rospy.Time.now()
    # The topic is latched: keep only what this move published.
    sub = subscribe(
        "/guarded_move_result",
        GuardedMoveResult,
        lambda msg: results.append(msg) if msg.header.stamp >= started else None,
    )
    try:
        response = stack.service("/arm/guarded_move", GuardedMove)(
            use_defaults=False, x=x, y=y, z=z, direction_x=normal[0], direction_y=normal[1],
            direction_z=normal[2], search_distance=search,
        )  # fmt: skip
        # Every executed descent publishes its result (ground found or not) before the
        # response; on its own connection it may arrive after it, under load well after. Then
        # 0.5 s of sim time for a second one, if any.
        deadline = time.monotonic() + 10.0
        while not results and time.monotonic() < deadline:
            time.sleep(0.01)
        rospy.sleep(0.5)
    finally:
        sub.unregister()
    return response, results


@pytest.mark.parametrize("ground_z", [-0.10, DEFAULT_GROUND_Z, -0.20])
def test_finds_flat_ground_at_several_heights(stack, ground_z):
    set_terrain(stack, lift_arm=True, spec=f"flat:{ground_z}")
    response, results = _guarded_move(stack, 1.7, 0.0, ground_z + 0.2)
    assert response.success, response.message
    assert response.ground_found
    assert response.ground_position.z == pytest.approx(ground_z, abs=TOLERANCE_M)
    # Published once per move, with the same position, in base_link.
    found = [r for r in results if r.success]
    assert len(found) == 1
    assert found[0].frame == "base_link"
    assert found[0].position.z == pytest.approx(response.ground_position.z, abs=1e-6)
    # Stamped with the sim time of the contact, the time the response names.
    contact = float(re.search(r"\(t=([0-9.]+) s sim\)", response.message).group(1))
    assert found[0].header.stamp.to_sec() == pytest.approx(contact, abs=0.006)


@pytest.mark.parametrize(("spec", "x", "y"), [("europa:3", 1.6, 0.1), ("europa:7", 1.65, 0.0)])
def test_finds_rough_ground(stack, spec, x, y):
    set_terrain(stack, lift_arm=True, spec=spec)
    terrain = parse_terrain_spec(spec)
    response, results = _guarded_move(stack, x, y, float(terrain.height_at(x, y)) + 0.2)
    assert response.success, response.message
    found = response.ground_position
    assert found.z == pytest.approx(float(terrain.height_at(found.x, found.y)), abs=TOLERANCE_M)
    assert [r.success for r in results] == [True]


def test_finds_sloped_ground_along_its_normal(stack, slope_file):
    """On a 10 degree slope the user gives its normal: the scoop's bottom is turned against it
    and the descent runs along it (the paper's ``direction``)."""
    spec = f"file:{slope_file}"
    set_terrain(stack, lift_arm=True, spec=spec)
    terrain = parse_terrain_spec(spec)
    normal = np.array([0.0, -SLOPE, 1.0]) / np.hypot(SLOPE, 1.0)
    x, y = 1.7, 0.1
    start = np.array([x, y, float(terrain.height_at(x, y))]) + 0.15 * normal
    response, results = _guarded_move(stack, *start, normal=normal)
    assert response.success, response.message
    found = response.ground_position
    assert found.z == pytest.approx(float(terrain.height_at(found.x, found.y)), abs=TOLERANCE_M)
    assert [r.success for r in results] == [True]


def test_finds_the_bottom_of_a_trench_dug_earlier(stack):
    set_terrain(stack, lift_arm=True, spec=FLAT)
    response, _ = _guarded_move(stack, 1.65, 0.0, 0.05)
    assert response.success, response.message
    ground = response.ground_position.z
    # Two trenches side by side make a pit wider than the scoop (the terrain grid is 4 cm: a
    # trench just the scoop's width has sloping walls the scoop would rest on).
    for y in (-0.06, 0.06):
        grind = stack.service("/arm/grind", Grind)(
            use_defaults=False, x=1.6, y=y, depth=0.05, length=0.3, parallel=True,
            ground_position=ground,
        )  # fmt: skip
        assert grind.success, grind.message
    response, _ = _guarded_move(stack, 1.75, 0.0, ground + 0.1)
    assert response.success, response.message
    found = response.ground_position
    msg = rospy.wait_for_message("/sim/terrain", HeightMapMsg, timeout=10)
    carved = float(height_map_from_msg(msg).height_at(found.x, found.y))
    assert carved < ground - 0.03  # inside the trench, well below the old surface
    assert found.z == pytest.approx(carved, abs=TOLERANCE_M)


def test_no_ground_within_the_search_distance_is_a_failure(stack):
    set_terrain(stack, lift_arm=True, spec="flat:-0.4")
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
