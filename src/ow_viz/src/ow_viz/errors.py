"""Exceptions of the ow_viz package. Each message names the bad value and what was expected."""

from ow_runtime import errors as runtime_errors


class OwVizError(Exception):
    """Base class of every error raised by ow_viz."""


class ConfigError(OwVizError, runtime_errors.ConfigError):
    """A configuration value is missing, unknown, of the wrong type or out of range."""


class SceneError(OwVizError):
    """A message cannot be drawn (a trajectory without the arm's joints, an empty height map)."""
