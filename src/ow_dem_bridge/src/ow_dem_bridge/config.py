"""Parameters of the bridge node, validated into a frozen dataclass (ROS-free)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from ow_dem_bridge.api import LOCAL_MODEL_NAMES
from ow_dem_bridge.errors import ConfigError

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

        Raises:
            ConfigError: unknown key, unknown model, or a malformed ``tools`` entry (names the key).
        """
        unknown = set(params) - {"model", "model_params", "tools"}
        if unknown:
            names = ", ".join(sorted(unknown))
            msg = f"unknown parameter(s) {names} (known: model, model_params, tools)"
            raise ConfigError(msg)
        model = params.get("model", "table")
        # The bridge serves the in-process models: the topic-backed one would ask itself.
        if model not in LOCAL_MODEL_NAMES:
            msg = f"model: {model!r} is not one of {', '.join(LOCAL_MODEL_NAMES)}"
            raise ConfigError(msg)
        model_params = params.get("model_params", {}) or {}
        if not isinstance(model_params, Mapping):
            msg = f"model_params must be a mapping, got {model_params!r}"
            raise ConfigError(msg)
        raw_tools = params.get("tools", DEFAULT_TOOLS)
        if not isinstance(raw_tools, Mapping) or not raw_tools:
            msg = f"tools must be a non-empty mapping of tool name to topics, got {raw_tools!r}"
            raise ConfigError(msg)
        tools = []
        for tool, topics in raw_tools.items():
            if tool not in DEFAULT_TOOLS:
                msg = f"tools.{tool}: unknown tool (known: {', '.join(DEFAULT_TOOLS)})"
                raise ConfigError(msg)
            merged = {**DEFAULT_TOOLS[tool], **(topics or {})}
            extra = set(merged) - {"state_topic", "wrench_topic"}
            if extra:
                msg = f"tools.{tool}: unknown key(s) {', '.join(sorted(extra))}"
                raise ConfigError(msg)
            for key, value in merged.items():
                if not isinstance(value, str) or not value:
                    msg = f"tools.{tool}.{key} must be a topic name, got {value!r}"
                    raise ConfigError(msg)
            tools.append(ToolTopics(tool, merged["state_topic"], merged["wrench_topic"]))
        return cls(str(model), dict(model_params), tuple(tools))
