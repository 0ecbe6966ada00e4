"""The simulation's side of the co-simulation path: wrenches from the bridge, over ROS topics.

The simulation node makes the ``"bridge"`` terrain-force model with :func:`make_remote_model`
(:func:`ow_dem_bridge.models.make_model` makes the in-process ones). The simulation keeps calling
``wrench(state)`` every step as for any model (and publishes its tool states for the bridge); the
model answers with the latest wrench received on the tool's wrench topic. The answer lags by the
round trip (about one simulation step when the bridge keeps up). Needs an initialised rospy node.

ROS API:

Subscribes:
    /dem/scoop_wrench, /dem/grinder_wrench (geometry_msgs/WrenchStamped, queue 1; names set by
        the ``topics`` parameter): force (N) and torque (N m) on the tool in its link frame, about
        the link centre of mass (what :mod:`ow_dem_bridge.dem_bridge_node` publishes).
"""

from __future__ import annotations

import threading
from collections.abc import Mapping
from typing import Any

import numpy as np
import rospy
from geometry_msgs.msg import WrenchStamped

from ow_dem_bridge.api import REMOTE_MODEL_NAME, TerrainForceModel, ToolState, Wrench
from ow_dem_bridge.config import DEFAULT_TOOLS
from ow_dem_bridge.conversions import wrench_from_msg
from ow_dem_bridge.errors import ConfigError


class TopicWrenchModel:
    """Latest ``geometry_msgs/WrenchStamped`` per tool; zero before the first one and above ground.

    Args:
        topics: tool -> wrench topic (default ``/dem/scoop_wrench``, ``/dem/grinder_wrench``).
    """

    def __init__(self, topics: Mapping[str, str] | None = None) -> None:
        self._lock = threading.Lock()
        self._latest: dict[str, Wrench] = {}
        names = topics or {t: v["wrench_topic"] for t, v in DEFAULT_TOOLS.items()}
        self._subscribers = [
            rospy.Subscriber(
                topic, WrenchStamped, self._on_wrench, callback_args=tool, queue_size=1
            )
            for tool, topic in names.items()
        ]

    def _on_wrench(self, msg: Any, tool: str) -> None:
        wrench = wrench_from_msg(msg)
        with self._lock:
            self._latest[tool] = wrench

    def wrench(self, state: ToolState) -> Wrench:
        """The latest wrench received for ``state.tool`` (zero above the surface or before any)."""
        with self._lock:
            latest = self._latest.get(state.tool)
        if state.depth <= 0.0 or latest is None:
            return Wrench(np.zeros(3), np.zeros(3))
        return latest


def make_remote_model(params: Mapping[str, Any]) -> TerrainForceModel:
    """The ``"bridge"`` model, a :class:`TopicWrenchModel`, from ``{"topics": {tool: topic}}``.

    Args:
        params: the model's parameters; ``topics`` (optional) maps scoop/grinder to wrench topics.

    Returns:
        A model with ``wrench(state) -> Wrench``, subscribed to the wrench topics.

    Raises:
        ConfigError: an unknown parameter, or ``topics`` is not a mapping of known tools to topic
            names.
    """
    unknown = set(params) - {"topics"}
    if unknown:
        msg = f"unknown {REMOTE_MODEL_NAME!r} model parameter(s): {', '.join(sorted(unknown))}"
        raise ConfigError(msg)
    topics = params.get("topics")
    if topics is not None and (
        not isinstance(topics, Mapping)
        or not all(t in DEFAULT_TOOLS and isinstance(v, str) and v for t, v in topics.items())
    ):
        msg = (
            f"{REMOTE_MODEL_NAME!r} parameter 'topics' must map scoop/grinder to topics, "
            f"got {topics!r}"
        )
        raise ConfigError(msg)
    return TopicWrenchModel(topics)
