"""The telemetry node's parameters (:mod:`ow_lander.telemetry.joints`), apart from its kinematics:
the mission reads them before it starts anything, and imports nothing heavy for that. No ROS."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ow_lander.errors import ConfigError
from ow_runtime.params import Params

#: The telemetry node's parameter file; its ``telemetry:`` section is the node's ``~``.
CONFIG_FILE = Path(__file__).resolve().parents[3] / "config" / "telemetry.yaml"


@dataclass(frozen=True)
class TelemetryConfig:
    """Parameters of the telemetry node (private namespace ``~``).

    Attributes:
        rate_hz: Hz of simulation time at which the telemetry is published: the first joint
            state at or after each multiple of 1 / rate_hz; 0 = one message of each topic per
            joint state, as OceanWATERS.
    """

    rate_hz: float = 0.0

    @classmethod
    def from_dict(cls, params: Mapping[str, Any]) -> TelemetryConfig:
        """Validate the node's parameters (missing keys take their defaults).

        Raises:
            ConfigError: unknown keys or a negative or non-finite rate, named.
        """
        p = Params(params, "telemetry", ConfigError)
        config = cls(rate_hz=p.non_negative("rate_hz", cls.rate_hz, "Hz"))
        p.finish()
        return config
