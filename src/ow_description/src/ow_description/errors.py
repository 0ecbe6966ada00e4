"""Exceptions of ow_description. Each message names the bad value and the limit it broke."""


class DescriptionError(Exception):
    """Base class of every error raised by ow_description."""


class ModelError(DescriptionError):
    """The robot description cannot be loaded or a frame or joint name is unknown."""


class TerrainError(DescriptionError):
    """A terrain height map or terrain specification is invalid."""


class IKError(DescriptionError):
    """Inverse kinematics found no configuration reaching the target."""


class TrajectoryError(DescriptionError):
    """A trajectory file is missing, malformed or outside the trajectory directory."""
