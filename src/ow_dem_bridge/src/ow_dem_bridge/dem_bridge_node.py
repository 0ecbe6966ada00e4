"""The DEM bridge node: tool states in, terrain wrenches out (the co-simulation path).

ROS API (all names relative to the defaults in config/dem.yaml):

Subscribes:
    /sim/scoop_state, /sim/grinder_state (ow_msgs/ToolState): a tool's pose and twist in
        base_link, depth (m) and progress (m) of its tip below the terrain, material id.
Publishes:
    /dem/scoop_wrench, /dem/grinder_wrench (geometry_msgs/WrenchStamped, queue 10): the terrain's
        force (N) and torque (N m) on the tool, in the state's link frame (frame_id = link, e.g.
        l_scoop), about the link centre of mass, stamped with the state's stamp. One wrench per
        state message; zero when the tool is above the surface.
Parameters (private, read once at start-up):
    ~model (str, default "table"): "table", "balovnev" or "none".
    ~model_params (dict): the model's parameters (see ow_dem_bridge.models).
    ~tools (dict): tool -> {state_topic, wrench_topic}; default both tools on the topics above.
"""

from __future__ import annotations

import sys
from typing import Any

import numpy as np

from ow_dem_bridge.api import FloatArray, TerrainForceModel
from ow_dem_bridge.config import BridgeConfig, ToolTopics
from ow_dem_bridge.conversions import tool_state_from_msg, wrench_to_msg
from ow_dem_bridge.errors import DemBridgeError
from ow_dem_bridge.geometry import load_tool
from ow_dem_bridge.models import make_model


class DemBridgeNode:
    """Answers every tool state with the model's wrench (see the module docstring for the API).

    Args:
        config: validated parameters.
        model: the terrain-force model.
    """

    def __init__(self, config: BridgeConfig, model: TerrainForceModel) -> None:
        import rospy
        from geometry_msgs.msg import WrenchStamped

        from ow_msgs.msg import ToolState as ToolStateMsg

        self._rospy = rospy
        self._model = model
        self._tips: dict[str, FloatArray] = {}
        self._publishers: dict[str, Any] = {}
        self._subscribers = []
        for topics in config.tools:
            pub = rospy.Publisher(topics.wrench_topic, WrenchStamped, queue_size=10)
            self._publishers[topics.tool] = pub
            self._subscribers.append(
                rospy.Subscriber(
                    topics.state_topic,
                    ToolStateMsg,
                    self._on_state,
                    callback_args=topics,
                    queue_size=10,
                )
            )

    def _tip(self, link: str) -> FloatArray:
        if link not in self._tips:
            from ow_description.description import URDF_PATH

            self._tips[link] = load_tool(URDF_PATH, link).tip
        return self._tips[link]

    def _on_state(self, msg: Any, topics: ToolTopics) -> None:
        rospy = self._rospy
        if msg.tool and msg.tool != topics.tool:
            rospy.logwarn_throttle(
                5.0, f"{topics.state_topic}: state of tool {msg.tool!r}, expected {topics.tool!r}"
            )
        try:
            state = tool_state_from_msg(msg, self._tip(msg.link))
            wrench = self._model.wrench(state)
        except DemBridgeError as exc:
            rospy.logerr_throttle(5.0, f"{topics.state_topic}: no wrench: {exc}")
            return
        if not (np.all(np.isfinite(wrench.force)) and np.all(np.isfinite(wrench.torque))):
            rospy.logerr_throttle(5.0, f"{topics.state_topic}: model returned a non-finite wrench")
            return
        self._publishers[topics.tool].publish(wrench_to_msg(wrench, msg.header.stamp, msg.link))


def main(argv: list[str] | None = None) -> int:
    """Start the node; return a non-zero exit code on a configuration error."""
    import rospy

    from ow_runtime.node import init_node, spin

    init_node("dem_bridge", argv=argv if argv is not None else sys.argv)
    try:
        config = BridgeConfig.from_dict(rospy.get_param("~", {}))
        model = make_model(config.model, config.model_params)
    except DemBridgeError as exc:
        rospy.logfatal(f"dem_bridge: {exc}")
        return 1
    DemBridgeNode(config, model)
    rospy.loginfo(
        f"dem_bridge: model {config.model!r}; "
        + ", ".join(f"{t.state_topic} -> {t.wrench_topic}" for t in config.tools)
    )
    spin()
    return 0
