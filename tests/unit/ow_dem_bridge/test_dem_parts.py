"""Tool geometry from the URDF, bridge parameters, message conversions."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from ow_dem_bridge.config import CONFIG_FILE, BridgeConfig
from ow_dem_bridge.conversions import tool_state_from_msg
from ow_dem_bridge.errors import ConfigError, GeometryError
from ow_dem_bridge.geometry import load_tool
from ow_dem_bridge.models import TableModel, make_model
from ow_description.description import URDF_PATH


def test_scoop_plates_from_the_urdf() -> None:
    scoop = load_tool(URDF_PATH, "l_scoop")
    assert len(scoop.facets) == 2 * 7  # seven plates, two triangles each
    assert np.allclose(scoop.tip, [0.1, 0.0, 0.08])
    vertices = np.array([v for tri in scoop.facets for v in tri])
    # About 0.127 long (x), 0.082 wide (y), 0.077 deep (z): spec section 1.4.
    assert np.allclose(vertices.min(axis=0), [-0.033, -0.0418, -0.0006], atol=2e-3)
    assert np.allclose(vertices.max(axis=0), [0.0985, 0.0418, 0.0815], atol=2e-3)


def test_grinder_is_a_stepped_surface_of_revolution() -> None:
    grinder = load_tool(URDF_PATH, "l_grinder", segments=12)
    assert np.allclose(grinder.tip, [0.16, 0.0, 0.0])
    vertices = np.array([v for tri in grinder.facets for v in tri])
    radius = np.hypot(vertices[:, 1], vertices[:, 2])
    assert radius.max() == pytest.approx(0.075, abs=1e-9)
    near_tip = radius[vertices[:, 0] > 0.125]
    assert near_tip.max() == pytest.approx(0.04, abs=1e-9)


@pytest.mark.parametrize(
    ("text", "link", "pattern"),
    [
        ("<robot name='r'><link name='a'/></robot>", "l_scoop", "no link named 'l_scoop'"),
        ("<robot name='r'><link name='l_scoop'/></robot>", "l_scoop", "no box or cylinder"),
        (
            "<robot name='r'><link name='l_scoop'><collision><geometry><box size='1 1 0.1'/>"
            "</geometry></collision></link></robot>",
            "l_scoop",
            "no fixed joint from 'l_scoop' to 'l_scoop_tip'",
        ),
        (
            "<robot name='r'><link name='l_scoop'><collision><geometry><sphere radius='1'/>"
            "</geometry></collision></link></robot>",
            "l_scoop",
            "only box and cylinder collision shapes are supported",
        ),
        (
            "<robot name='r'><link name='l_grinder'><collision name='off'>"
            "<origin xyz='0 0.1 0'/><geometry><cylinder radius='0.1' length='0.2'/></geometry>"
            "</collision></link></robot>",
            "l_grinder",
            "l_grinder cylinder 'off' is not on the link x axis",
        ),
    ],
)
def test_geometry_errors(tmp_path: Path, text: str, link: str, pattern: str) -> None:
    path = tmp_path / "r.urdf"
    path.write_text(text)
    with pytest.raises(GeometryError, match=pattern):
        load_tool(path, link)


def test_bridge_config_defaults_and_overrides() -> None:
    default = BridgeConfig.from_dict({})
    assert default.model == "table"
    assert [(t.tool, t.state_topic, t.wrench_topic) for t in default.tools] == [
        ("scoop", "/sim/scoop_state", "/dem/scoop_wrench"),
        ("grinder", "/sim/grinder_state", "/dem/grinder_wrench"),
    ]
    one = BridgeConfig.from_dict({"tools": {"scoop": {"wrench_topic": "/x"}}})
    assert [(t.tool, t.wrench_topic) for t in one.tools] == [("scoop", "/x")]


def test_the_shipped_config_file_is_valid_and_holds_the_defaults() -> None:
    config = BridgeConfig.from_dict(yaml.safe_load(CONFIG_FILE.read_text()))
    assert config.model == "table"
    assert config.tools == BridgeConfig().tools
    # Its model parameters are the model's defaults: the shipped table, the state's material.
    assert config.model_params == {
        "path": "",
        "material": 0,
        "pass_number": 1,
        "table_tool": "scoop",
    }
    model = make_model(config.model, config.model_params)
    assert isinstance(model, TableModel)
    assert model.material is None


@pytest.mark.parametrize(
    ("params", "pattern"),
    [
        ({"modle": "table"}, "unknown key 'modle' \\(did you mean 'model'\\?\\)"),
        ({"model": "bridge"}, "model = 'bridge' is not one of none, table, balovnev"),
        ({"model": 3}, "model must be a string, got 3"),
        ({"model_params": [1]}, "model_params must be a mapping"),
        ({"tools": {}}, "tools must be a non-empty mapping of tool name to topics"),
        ({"tools": ["scoop"]}, "tools must be a mapping, got \\['scoop'\\]"),
        ({"tools": {"drill": {}}}, "unknown key 'tools/drill'"),
        ({"tools": {"scop": {}}}, "unknown key 'tools/scop' \\(did you mean 'scoop'\\?\\)"),
        ({"tools": {"scoop": {"state_topic": ""}}}, "tools/scoop/state_topic must be a topic"),
        ({"tools": {"scoop": {"topic": "/a"}}}, "unknown key 'tools/scoop/topic'"),
    ],
)
def test_bridge_config_errors_name_the_key(params: dict[str, Any], pattern: str) -> None:
    with pytest.raises(ConfigError, match=pattern):
        BridgeConfig.from_dict(params)


def test_bridge_config_reports_every_problem_at_once() -> None:
    with pytest.raises(ConfigError) as error:
        BridgeConfig.from_dict({"model": "dem", "tools": {"grinder": {"wrench_topic": 5}}})
    message = str(error.value)
    assert message.startswith("2 problems in the parameters:")
    assert "model = 'dem' is not one of" in message
    assert "tools/grinder/wrench_topic must be a string, got 5" in message


def test_tool_state_from_msg_gives_tip_velocity_in_the_link_frame() -> None:
    from ow_msgs.msg import ToolState as ToolStateMsg

    msg = ToolStateMsg()
    msg.tool, msg.link, msg.material, msg.depth, msg.progress = "scoop", "l_scoop", 2, 0.03, 0.1
    # Link turned 90 deg about base z; origin moving along base x; spinning about base z.
    half = math.pi / 4
    msg.pose.orientation.z, msg.pose.orientation.w = math.sin(half), math.cos(half)
    msg.twist.linear.x = 0.1
    msg.twist.angular.z = 1.0
    tip = np.array([0.1, 0.0, 0.08])
    state = tool_state_from_msg(msg, tip)
    R = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])  # 90 deg about z
    v_tip_base = np.array([0.1, 0, 0]) + np.cross([0, 0, 1.0], R @ tip)
    assert np.allclose(state.velocity, R.T @ v_tip_base)
    # The spin moves the tip at 0.1 m/s along -x of base, cancelling the translation.
    assert np.allclose(state.velocity, 0.0)
    assert np.allclose(state.angular_velocity, [0, 0, 1.0])
    assert (state.tool, state.material, state.depth, state.progress) == ("scoop", 2, 0.03, 0.1)


def test_tool_state_from_msg_normalises_the_orientation() -> None:
    from ow_msgs.msg import ToolState as ToolStateMsg

    msg = ToolStateMsg()
    msg.twist.linear.x = 0.1
    unset = tool_state_from_msg(msg, np.zeros(3))  # all-zero quaternion: the identity
    assert np.allclose(unset.velocity, [0.1, 0.0, 0.0])
    msg.pose.orientation.z, msg.pose.orientation.w = 2.0, 2.0  # 90 deg about z, not unit length
    turned = tool_state_from_msg(msg, np.zeros(3))
    assert np.allclose(turned.velocity, [0.0, -0.1, 0.0])
