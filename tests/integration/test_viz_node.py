"""The viz node on a running stack: the description, the world frame and the three markers."""

from __future__ import annotations

import time

import numpy as np
import pytest
import rospy
from std_msgs.msg import String
from visualization_msgs.msg import Marker

from ow_bringup.testing import subscribe, tf_buffer
from ow_description.conversions import height_map_from_msg
from ow_description.description import SCOOP_TIP_FRAME, URDF_PATH
from ow_msgs.msg import GuardedMoveResult
from ow_msgs.msg import HeightMap as HeightMapMsg
from ow_msgs.srv import GuardedMove, Unstow
from ow_runtime.lockstep_client import simulation_status
from ow_viz.scene import terrain_mesh

WORLD_XYZ = (0.5, -0.25, 0.1)  # m, base_link in world for this test


@pytest.fixture(scope="module")
def stack(start_lander):
    stack = start_lander(arm_services=["/arm/unstow", "/arm/guarded_move"])
    stack.start_node(
        "ow_viz",
        "viz",
        params={"base_link_in_world": list(WORLD_XYZ)},
        wait_for_topics=["/viz/terrain", "/robot_description"],
    )
    return stack


def _latest(topic, msg_type, timeout=20.0):
    return rospy.wait_for_message(topic, msg_type, timeout=timeout)


def test_the_description_is_a_parameter_and_a_latched_topic(stack):
    urdf = URDF_PATH.read_text()
    assert rospy.get_param("/robot_description") == urdf
    assert _latest("/robot_description", String).data == urdf


def test_base_link_sits_in_the_world_frame_where_configured(stack):
    buffer = tf_buffer()
    transform = buffer.lookup_transform("world", "base_link", rospy.Time(0), rospy.Duration(10))
    t = transform.transform.translation
    assert np.allclose([t.x, t.y, t.z], WORLD_XYZ)
    # The simulation's links hang below it: the scoop tip has a pose in world too.
    buffer.lookup_transform("world", SCOOP_TIP_FRAME, rospy.Time(0), rospy.Duration(10))


def test_the_terrain_marker_is_the_mesh_of_the_simulations_terrain(stack):
    terrain = height_map_from_msg(_latest("/sim/terrain", HeightMapMsg))
    marker = _latest("/viz/terrain", Marker)
    mesh = terrain_mesh(terrain)
    assert marker.type == Marker.TRIANGLE_LIST and marker.header.frame_id == "base_link"
    assert len(marker.points) == len(marker.colors) == mesh.triangles.size
    corners = np.array([[p.x, p.y, p.z] for p in marker.points])
    assert np.allclose(corners, mesh.vertices[mesh.triangles.ravel()], atol=1e-6)


def test_a_plan_is_drawn_and_the_ground_found_is_marked(stack):
    paths = []
    sub = subscribe("/viz/tool_path", Marker, paths.append)
    try:
        response = stack.service("/arm/unstow", Unstow)(delete_prev_traj=False)
        assert response.success, response.message
        deadline = rospy.Time.now() + rospy.Duration(30)
        while not paths and rospy.Time.now() < deadline:
            rospy.sleep(0.1)
        assert paths, "no /viz/tool_path after a plan"
    finally:
        sub.unregister()
    path = np.array([[p.x, p.y, p.z] for p in paths[-1].points])
    assert paths[-1].type == Marker.LINE_STRIP and len(path) > 10
    # The path ends where the arm came to rest: the scoop tip's pose after the unstow, from a
    # transform stamped after it. This process takes /tf (600 messages a wall second at the
    # tests' 20x) on the subscription an earlier test's listener made; under load it lagged
    # seconds behind, and the newest transform it had was the stowed pose.
    rested = simulation_status().sim_time
    buffer = tf_buffer()
    deadline = time.monotonic() + 60.0
    while True:
        tip = buffer.lookup_transform(
            "base_link", SCOOP_TIP_FRAME, rospy.Time(0), rospy.Duration(10)
        )
        if tip.header.stamp.to_sec() >= rested - 0.05:  # /tf at 30 Hz of sim time
            break
        assert time.monotonic() < deadline, f"no /tf after t = {rested} s"
        time.sleep(0.05)
    t = tip.transform.translation
    assert np.allclose(path[-1], [t.x, t.y, t.z], atol=0.02)

    result = stack.service("/arm/guarded_move", GuardedMove)(use_defaults=True)
    assert result.success, result.message
    found = _latest("/guarded_move_result", GuardedMoveResult)
    assert found.success
    marker = _latest("/viz/ground_point", Marker)
    assert marker.type == Marker.SPHERE
    p = marker.pose.position
    assert np.allclose([p.x, p.y, p.z], [found.position.x, found.position.y, found.position.z])
