"""Exceptions of the ow_lander package. Each message names the bad value and the limit it broke."""


class OwLanderError(Exception):
    """Base class of every error raised by ow_lander."""


class ConfigError(OwLanderError):
    """A configuration value is missing, of the wrong type or out of range."""


class ModelError(OwLanderError):
    """The robot description cannot be loaded or a frame or joint name is unknown."""


class TerrainError(OwLanderError):
    """A terrain height map or terrain specification is invalid."""


class IKError(OwLanderError):
    """Inverse kinematics found no configuration reaching the target."""


class PlanningError(OwLanderError):
    """No valid plan exists for a request (unreachable, in collision, or out of limits)."""


class TrajectoryError(OwLanderError):
    """A trajectory file is missing, malformed or outside the trajectory directory."""


class GoalError(OwLanderError):
    """An action goal field is not finite, out of range or of the wrong size."""
