"""Exceptions of the ow_mission package. Each message names the bad value and the limit it broke."""

from ow_runtime import errors as runtime_errors


class OwMissionError(Exception):
    """Base class of every error raised by ow_mission."""


class ConfigError(OwMissionError, runtime_errors.ConfigError):
    """A mission file or node configuration is missing, malformed or out of range."""


class ReplayError(OwMissionError):
    """The bags cannot be read, or lack what a figure needs."""


class FiguresError(OwMissionError):
    """A run's figures, made after its mission, are not there and will not come."""


class CaptureError(OwMissionError):
    """The mission's capture of the workspace failed (the camera refused it, or its images did
    not come)."""
