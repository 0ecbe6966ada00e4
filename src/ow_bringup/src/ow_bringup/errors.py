"""Exceptions of the ow_bringup package. Each message names the bad value and the limit it broke."""

from ow_runtime import errors as runtime_errors


class OwBringupError(Exception):
    """Base class of every error raised by ow_bringup."""


class ConfigError(OwBringupError, runtime_errors.ConfigError):
    """A node configuration is missing, malformed or out of range."""


class HarnessError(OwBringupError, RuntimeError):
    """A master or node could not be started, or a wait timed out."""
