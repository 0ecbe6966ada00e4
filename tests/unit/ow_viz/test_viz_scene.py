"""The viz node's pure parts: configuration, terrain mesh, tool path, markers (no master)."""

import copy
import io

import genpy
import numpy as np
import pytest
import yaml
from geometry_msgs.msg import Point
from std_msgs.msg import ColorRGBA
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint
from visualization_msgs.msg import Marker

from ow_description.description import ARM_JOINTS, SCOOP_TIP_FRAME, STOWED, UNSTOWED
from ow_description.model import LanderModel
from ow_description.terrain import HeightMap
from ow_viz.config import CONFIG_FILE, VizConfig
from ow_viz.conversions import terrain_marker, trajectory_arrays
from ow_viz.errors import ConfigError, SceneError
from ow_viz.scene import TERRAIN_HIGH_RGBA, TERRAIN_LOW_RGBA, terrain_mesh, tool_path


@pytest.fixture(scope="module")
def model():
    return LanderModel()


def test_the_shipped_yaml_holds_the_defaults():
    assert VizConfig.from_dict(yaml.safe_load(CONFIG_FILE.read_text())) == VizConfig()


@pytest.mark.parametrize(
    ("params", "message"),
    [
        ({"world_frame": "base_link"}, "viz/world_frame = 'base_link' must name a frame"),
        ({"base_link_in_world": [0.0, 1.0]}, r"viz/base_link_in_world must be \[x, y, z\]"),
        ({"base_link_in_world": [0.0, "a", 0.0]}, r"viz/base_link_in_world\[1\] must be a number"),
        ({"terrain_max_side": 1}, "viz/terrain_max_side = 1 is outside"),
        ({"path_width": 0.02}, "path_width"),
    ],
)
def test_bad_parameters_are_named(params, message):
    with pytest.raises(ConfigError, match=message):
        VizConfig.from_dict(params)


def test_the_mesh_covers_the_map_with_upward_triangles_coloured_by_height():
    heights = np.arange(12.0).reshape(3, 4) * 0.01  # rising along x, then y
    hm = HeightMap(heights, 0.1, -0.5, 1.0)
    mesh = terrain_mesh(hm)
    assert mesh.vertices.shape == (12, 3) and mesh.triangles.shape == (2 * 2 * 3, 3)
    assert np.allclose(mesh.vertices[5], [-0.4, 1.1, 0.05])  # row 1, column 1
    a, b, c = (mesh.vertices[mesh.triangles[:, k]] for k in range(3))
    normals = np.cross(b - a, c - a)
    assert (normals[:, 2] > 0).all()  # counter-clockwise seen from above
    assert np.allclose(mesh.colours[0], TERRAIN_LOW_RGBA)
    assert np.allclose(mesh.colours[-1], TERRAIN_HIGH_RGBA)


def test_a_large_map_is_strided_but_keeps_its_edges():
    hm = HeightMap(np.zeros((201, 150)), 0.02, 0.0, 0.0)
    mesh = terrain_mesh(hm, max_side=101)
    xs, ys = np.unique(mesh.vertices[:, 0]), np.unique(mesh.vertices[:, 1])
    assert len(xs) <= 101 and len(ys) <= 101
    assert np.isclose(xs.max(), 149 * 0.02) and np.isclose(ys.max(), 200 * 0.02)
    assert np.allclose(mesh.colours, np.mean([TERRAIN_LOW_RGBA, TERRAIN_HIGH_RGBA], axis=0))


def test_a_mesh_needs_two_vertices_per_side():
    with pytest.raises(SceneError, match="max_side = 1 must be at least 2"):
        terrain_mesh(HeightMap(np.zeros((3, 5)), 0.1, 0.0, 0.0), max_side=1)


def _wire(msg, seq=7):
    """The message's bytes with its header numbered ``seq``, as a publisher numbers it."""
    msg.header.seq = seq
    buff = io.BytesIO()
    msg.serialize(buff)
    return buff.getvalue()


def test_the_terrain_marker_is_a_triangle_list_of_every_corner():
    heights = np.array([[0.0, 0.1, 0.3], [0.2, -0.1, 0.0], [0.05, 0.0, 0.4]])
    mesh = terrain_mesh(HeightMap(heights, 0.1, 0.5, -0.2))
    stamp = genpy.Time(12, 340_000_000)
    marker = terrain_marker(mesh, "base_link", stamp)
    received = Marker()
    received.deserialize(_wire(marker))
    assert received.type == Marker.TRIANGLE_LIST and received.header.frame_id == "base_link"
    assert received.header.stamp == stamp and received.header.seq == 7
    assert len(received.points) == len(received.colors) == 8 * 3
    corners = np.array([[p.x, p.y, p.z] for p in received.points])
    assert np.array_equal(corners, mesh.vertices[mesh.triangles.ravel()])
    # The bytes genpy writes for the same marker built point by point (colours are float32).
    points = [Point(*p) for p in corners.tolist()]
    colours = [ColorRGBA(*c) for c in mesh.colours[mesh.triangles.ravel()].tolist()]
    built = copy.deepcopy(received)
    built.points, built.colors, built.text = points, colours, ""
    assert _wire(marker) == _wire(built)
    marker.text = "terrain"  # the tail after the arrays: text, mesh resource, flag
    marker.mesh_resource = "package://x/y.dae"
    built.text, built.mesh_resource = "terrain", "package://x/y.dae"
    assert _wire(marker) == _wire(built)


def test_an_array_marker_refuses_points_given_as_messages():
    mesh = terrain_mesh(HeightMap(np.zeros((2, 2)), 0.1, 0.0, 0.0))
    marker = terrain_marker(mesh, "base_link", genpy.Time(1))
    marker.points = [Point(0.0, 0.0, 0.0)]
    with pytest.raises(ValueError, match="as arrays only"):
        _wire(marker)


def _trajectory(joints, rows, dt=1.0):
    msg = JointTrajectory(joint_names=list(joints))
    for k, row in enumerate(rows):
        point = JointTrajectoryPoint(positions=list(row))
        point.time_from_start.secs = int(k * dt)
        msg.points.append(point)
    return msg


def test_the_tool_path_passes_through_the_forward_kinematics_of_each_waypoint(model):
    joints = list(reversed(ARM_JOINTS))  # any column order: joints are looked up by name
    rows = [[pose[j] for j in joints] for pose in (STOWED, UNSTOWED)]
    names, times, positions, velocities = trajectory_arrays(_trajectory(joints, rows))
    path = tool_path(model, SCOOP_TIP_FRAME, names, times, positions, velocities, 0.1)
    assert len(path) == 11
    for row, index in ((rows[0], 0), (rows[1], -1)):
        q = model.q_from(dict(zip(joints, row, strict=True)))
        assert np.allclose(path[index], model.position(q, SCOOP_TIP_FRAME))


@pytest.mark.parametrize(
    ("joints", "frame", "message"),
    [
        (["j_nope"], SCOOP_TIP_FRAME, r"trajectory joints \['j_nope'\] are not joints"),
        (["j_shou_yaw"], "l_nope", "tool frame 'l_nope' is not a frame"),
    ],
)
def test_a_path_that_cannot_be_drawn_says_why(model, joints, frame, message):
    with pytest.raises(SceneError, match=message):
        tool_path(model, frame, joints, [0.0], np.zeros((1, 1)), None, 0.1)


def test_an_empty_trajectory_is_refused():
    with pytest.raises(SceneError, match="no points"):
        trajectory_arrays(JointTrajectory(joint_names=["j_shou_yaw"]))


@pytest.mark.parametrize("launch", sorted((CONFIG_FILE.parents[1] / "launch").glob("*.launch")))
def test_the_launch_files_are_well_formed_xml(launch):
    import xml.etree.ElementTree as ET

    assert ET.parse(launch).getroot().tag == "launch"
