"""Exceptions of the ow_power package. Each message names the bad value and what was expected."""

from ow_runtime import errors as runtime_errors


class OwPowerError(Exception):
    """Base class of every error raised by ow_power."""


class ConfigError(OwPowerError, runtime_errors.ConfigError):
    """A configuration value is missing, unknown, of the wrong type or out of range."""


class PowerError(OwPowerError):
    """A joint state cannot be turned into power (missing joint, arrays of different lengths)."""


class RecorderError(OwPowerError):
    """A bag cannot be opened, written or closed without losing or overwriting data."""


class AnalysisError(OwPowerError):
    """Bags cannot be read or hold nothing to analyse."""


class BagReadError(OwPowerError):
    """A bag file cannot be opened or read, or a message in it does not deserialise."""
