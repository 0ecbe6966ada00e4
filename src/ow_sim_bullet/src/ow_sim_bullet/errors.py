"""Exceptions of ow_sim_bullet. Each message names the bad value and the rule it broke."""

from ow_runtime import errors as runtime_errors


class SimError(Exception):
    """Base class of every error raised by ow_sim_bullet."""


class ConfigError(SimError, runtime_errors.ConfigError):
    """A node parameter is missing, of the wrong type or out of range (names the key)."""


class TerrainSpecError(SimError):
    """A terrain specification cannot be parsed or its height-map file cannot be read."""


class CommandError(SimError):
    """A joint command, trajectory or gain change is invalid (unknown joint, NaN, bad timing)."""
