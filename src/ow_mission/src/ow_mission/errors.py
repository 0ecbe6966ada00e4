"""Exceptions of the ow_mission package. Each message names the bad value and the limit it broke."""


class OwMissionError(Exception):
    """Base class of every error raised by ow_mission."""


class ConfigError(OwMissionError):
    """A mission file or node configuration is missing, malformed or out of range."""


class HarnessError(OwMissionError, RuntimeError):
    """A master or node could not be started, or a wait timed out."""


class ReplayError(OwMissionError):
    """The bags cannot be read, or lack what a figure needs."""


class FiguresError(OwMissionError):
    """A run's figures, made after its mission, are not there and will not come."""
