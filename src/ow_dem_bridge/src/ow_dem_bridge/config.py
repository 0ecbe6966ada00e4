"""Parameters of the bridge node, validated into a frozen dataclass (ROS-free).

``config/dem.yaml`` (:data:`CONFIG_FILE`) holds the defaults below; the node loads it into its
private namespace and passes that mapping to :meth:`BridgeConfig.from_dict`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ow_dem_bridge.api import LOCAL_MODEL_NAMES
from ow_dem_bridge.errors import ConfigError
from ow_runtime.params import Params

#: The bridge node's parameter file (``src/ow_dem_bridge/config/dem.yaml``).
CONFIG_FILE = Path(__file__).resolve().parents[2] / "config" / "dem.yaml"

#: Default topics: the simulation publishes tool states, the bridge answers with wrenches.
DEFAULT_TOOLS: dict[str, dict[str, str]] = {
    "scoop": {"state_topic": "/sim/scoop_state", "wrench_topic": "/dem/scoop_wrench"},
    "grinder": {"state_topic": "/sim/grinder_state", "wrench_topic": "/dem/grinder_wrench"},
}


@dataclass(frozen=True)
class ToolTopics:
    """Where one tool's state comes from and where its wrench goes.

    Attributes:
        tool: "scoop" or "grinder".
        state_topic: ``ow_msgs/ToolState`` input.
        wrench_topic: ``geometry_msgs/WrenchStamped`` output (frame: the state's link).
    """

    tool: str
    state_topic: str
    wrench_topic: str


@dataclass(frozen=True)
class BridgeConfig:
    """The bridge node's parameters.

    Attributes:
        model: terrain-force model name for :func:`ow_dem_bridge.models.make_model`.
        model_params: that model's parameters.
        tools: the tools to serve.
    """

    model: str = "table"
    model_params: Mapping[str, Any] = field(default_factory=dict)
    tools: tuple[ToolTopics, ...] = tuple(ToolTopics(t, **v) for t, v in DEFAULT_TOOLS.items())

    @classmethod
    def from_dict(cls, params: Mapping[str, Any]) -> BridgeConfig:
        """Validate the node's private parameters (missing keys keep their defaults).

        Every problem is collected and reported at once; a misspelt key gets the nearest known
        key as a suggestion.

        Args:
            params: the node's private namespace, e.g. ``config/dem.yaml`` as loaded.

        Raises:
            ConfigError: unknown key, unknown model, ``model_params`` not a mapping, or a
                malformed ``tools`` entry; the message names each key.
        """
        p = Params(params, error=ConfigError)
        # The bridge serves the in-process models: the topic-backed one would ask itself.
        model = p.string("model", cls.model, choices=LOCAL_MODEL_NAMES)
        model_params = dict(p.section("model_params").values)
        tools = _read_tools(p) if p.has("tools") else cls.tools
        p.finish()
        return cls(model, model_params, tools)


def _read_tools(p: Params) -> tuple[ToolTopics, ...]:
    """The ``tools`` mapping (tool -> topics, each topic defaulting to :data:`DEFAULT_TOOLS`)."""
    raw = p.raw("tools")
    if not raw and (raw is None or isinstance(raw, Mapping)):
        p.problem(f"{p.name('tools')} must be a non-empty mapping of tool name to topics")
    section = p.section("tools")
    tools = []
    for tool in section.values:
        if tool not in DEFAULT_TOOLS:
            continue  # reported by check_unknown below
        topics = section.section(tool)
        names = {}
        for key, default in DEFAULT_TOOLS[tool].items():
            names[key] = topics.string(key, default)
            if not names[key]:
                topics.problem(f"{topics.name(key)} must be a topic name, got ''")
        topics.check_unknown()
        tools.append(ToolTopics(tool, names["state_topic"], names["wrench_topic"]))
    section.check_unknown(DEFAULT_TOOLS)
    return tuple(tools)
