"""The bridge node answers tool states with table wrenches; the sim's "bridge" model reads them."""

from __future__ import annotations

import math
import threading
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from ow_bringup.testing import HarnessError, advertise, subscribe
from ow_dem_bridge.api import ToolState
from ow_dem_bridge.errors import ConfigError
from ow_dem_bridge.remote_node import make_remote_model
from ow_dem_bridge.table import load_table

HEADER = "tool,material,depth_m,progress_m,Fx_N,Fy_N,Fz_N,Tx_Nm,Ty_Nm,Tz_Nm"
ROWS = [
    "scoop,1,0.01,0.0,-1,0.1,2,0.01,0.1,0",
    "scoop,1,0.01,0.2,-3,0.1,4,0.01,0.3,0",
    "scoop,1,0.03,0.0,-5,0.1,6,0.01,0.5,0",
    "scoop,1,0.03,0.2,-7,0.1,8,0.01,0.7,0",
    "grinder,1,0.05,0.0,-2,-1,0,0,0,0.5",
    "grinder,1,0.05,0.2,-2,-1,0,0,0,0.5",
]


@pytest.fixture(scope="module")
def table_path(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("dem") / "table.csv"
    path.write_text("\n".join([HEADER, *ROWS]) + "\n")
    return path


@pytest.fixture(scope="module")
def bridge(ros_stack: Any, table_path: Path) -> Any:
    ros_stack.start_node(
        "ow_dem_bridge",
        "dem_bridge",
        params={"model": "table", "model_params": {"path": str(table_path)}},
        wait_for_topics=["/dem/scoop_wrench", "/dem/grinder_wrench"],
    )
    return ros_stack


class Collector:
    """Keeps the wrenches received on a topic."""

    def __init__(self, topic: str) -> None:
        from geometry_msgs.msg import WrenchStamped

        self.messages: list[Any] = []
        self.event = threading.Event()
        self.sub = subscribe(topic, WrenchStamped, self._cb)

    def _cb(self, msg: Any) -> None:
        self.messages.append(msg)
        self.event.set()

    def exchange(self, pub: Any, state: Any, timeout_s: float = 10.0) -> Any:
        """Publish ``state`` (again every 0.2 s) until its wrench arrives; return the wrench."""
        import time

        stamp = state.header.stamp
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            pub.publish(state)
            end = time.monotonic() + 0.2
            while time.monotonic() < end:
                for msg in self.messages:
                    if msg.header.stamp == stamp:
                        return msg
                time.sleep(0.01)
        pytest.fail(f"no wrench stamped {stamp.to_sec()} s within {timeout_s} s")


def state_msg(
    tool: str, link: str, depth: float, progress: float, stamp_secs: int, twist: tuple
) -> Any:
    import rospy

    from ow_msgs.msg import ToolState as ToolStateMsg

    msg = ToolStateMsg()
    msg.header.stamp = rospy.Time(stamp_secs)
    msg.header.frame_id = "base_link"
    msg.tool, msg.link = tool, link
    msg.pose.orientation.w = 1.0  # link frame = base_link, so twists need no rotation
    (msg.twist.linear.x, msg.twist.linear.y, msg.twist.linear.z) = twist
    msg.depth, msg.progress, msg.material = depth, progress, 1
    return msg


def publisher(topic: str) -> Any:
    import time

    from ow_msgs.msg import ToolState as ToolStateMsg

    pub = advertise(topic, ToolStateMsg, queue_size=10)
    deadline = time.monotonic() + 10.0
    while pub.get_num_connections() == 0 and time.monotonic() < deadline:
        time.sleep(0.02)
    return pub


SCOOP_CASES = [
    # (depth m, progress m): at keys, between keys, out of range
    (0.01, 0.0),
    (0.02, 0.1),
    (0.03, 0.15),
    (0.005, 0.1),
    (0.06, 0.3),
    (0.0, 0.1),
]


def test_scoop_wrench_matches_the_table(bridge: Any, table_path: Path) -> None:
    table = load_table(table_path)
    collector = Collector("/dem/scoop_wrench")
    pub = publisher("/sim/scoop_state")
    for i, (depth, progress) in enumerate(SCOOP_CASES, start=1):
        msg = collector.exchange(
            pub, state_msg("scoop", "l_scoop", depth, progress, i, (0.1, 0, 0))
        )
        expected = table.lookup("scoop", 1, depth, progress)
        got = [msg.wrench.force.x, msg.wrench.force.y, msg.wrench.force.z]
        got += [msg.wrench.torque.x, msg.wrench.torque.y, msg.wrench.torque.z]
        assert msg.header.frame_id == "l_scoop"
        assert np.allclose(got, expected, atol=1e-9), (depth, progress)


def test_grinder_wrench_turns_with_the_drag(bridge: Any) -> None:
    collector = Collector("/dem/grinder_wrench")
    pub = publisher("/sim/grinder_state")
    # Dragged along link +z: the table's lateral resistance (-1 N along +y drag) must point to -z.
    msg = collector.exchange(pub, state_msg("grinder", "l_grinder", 0.05, 0.1, 100, (0, 0, 0.1)))
    assert msg.header.frame_id == "l_grinder"
    f = msg.wrench.force
    assert np.allclose([f.x, f.y, f.z], [-2.0, 0.0, -1.0], atol=1e-9)


def test_sim_side_bridge_model_gets_the_bridge_wrench(bridge: Any, table_path: Path) -> None:
    import time

    model = make_remote_model({})
    pub = publisher("/sim/scoop_state")
    state = ToolState("scoop", 1, 0.02, 0.1, np.array([0.1, 0.0, 0.0]), np.zeros(3))
    expected = load_table(table_path).lookup("scoop", 1, 0.02, 0.1)
    deadline = time.monotonic() + 10.0
    force = np.zeros(3)
    while time.monotonic() < deadline:
        pub.publish(state_msg("scoop", "l_scoop", 0.02, 0.1, 200, (0.1, 0.0, 0.0)))
        force = model.wrench(state).force
        if np.allclose(force, expected[:3]):
            break
        time.sleep(0.05)
    assert np.allclose(force, expected[:3])
    above = ToolState("scoop", 1, 0.0, 0.1, np.zeros(3), np.zeros(3))
    assert np.allclose(model.wrench(above).force, 0.0)


@pytest.mark.parametrize(
    ("params", "pattern"),
    [
        ({"topic": {}}, r"unknown 'bridge' model parameter\(s\): topic"),
        ({"topics": {"drill": "/x"}}, "'bridge' parameter 'topics' must map scoop/grinder"),
        ({"topics": {"scoop": ""}}, "'bridge' parameter 'topics' must map scoop/grinder"),
    ],
)
def test_remote_model_parameter_errors(params: dict[str, Any], pattern: str) -> None:
    with pytest.raises(ConfigError, match=pattern):
        make_remote_model(params)


def test_bad_model_name_stops_the_node_with_a_clear_message(ros_stack: Any) -> None:
    with pytest.raises(HarnessError, match=r"model = 'dem' is not one of none, table, balovnev"):
        ros_stack.start_node(
            "ow_dem_bridge",
            "dem_bridge",
            name="dem_bridge_bad",
            params={"model": "dem"},
            wait_for_topics=["/dem/never_published"],
            timeout_s=30.0,
        )


def test_balovnev_bridge(ros_stack: Any) -> None:
    ros_stack.start_node(
        "ow_dem_bridge",
        "dem_bridge",
        name="dem_bridge_balovnev",
        params={
            "model": "balovnev",
            "model_params": {"grinder_table": ""},
            "tools": {"scoop": {"wrench_topic": "/dem/balovnev_wrench"}},
        },
        wait_for_topics=["/dem/balovnev_wrench"],
    )
    collector = Collector("/dem/balovnev_wrench")
    pub = publisher("/sim/scoop_state")
    msg = collector.exchange(pub, state_msg("scoop", "l_scoop", 0.05, 0.1, 300, (0.1, 0, 0)))
    assert msg.wrench.force.x == pytest.approx(-10.86, abs=0.01)
    assert msg.wrench.force.z == pytest.approx(13.90, abs=0.01)
    assert math.isclose(msg.wrench.force.y, 0.0)
