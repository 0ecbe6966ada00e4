"""Exceptions of the ow_cameras package. Each message names the bad value and what was expected."""

from ow_runtime import errors as runtime_errors


class CameraError(Exception):
    """Base class of every error raised by ow_cameras."""


class ConfigError(CameraError, runtime_errors.ConfigError):
    """A configuration value is missing, unknown, of the wrong type or out of range."""


class GoalError(CameraError):
    """An action goal asks for something the cameras or lights cannot do (the message is the
    goal's status text)."""


class RenderError(CameraError):
    """The scene cannot be rendered (an unknown link, a bad terrain, a camera that sees nothing)."""


class StereoError(CameraError):
    """A stereo pair cannot be matched (images of different sizes or of the wrong type)."""


class RigError(CameraError):
    """The robot description lacks what the camera rig hangs from (the mast's joints)."""
