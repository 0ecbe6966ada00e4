"""Exceptions of the ow_lander package. Each message names the bad value and the limit it broke."""

from ow_description.errors import DescriptionError
from ow_runtime import errors as runtime_errors


class OwLanderError(Exception):
    """Base class of every error raised by ow_lander."""


class ConfigError(OwLanderError, runtime_errors.ConfigError):
    """A configuration value is missing, of the wrong type or out of range."""


class PlanningError(OwLanderError):
    """No valid plan exists for a request (unreachable, in collision, or out of limits)."""


class GoalError(OwLanderError):
    """An action goal field is not finite, out of range or of the wrong size."""


#: What a request handler reports as a failed request rather than a programming error: the arm's
#: own errors and those of the description it plans on (no IK solution, an unknown frame, a bad
#: height map or trajectory file).
REQUEST_ERRORS: tuple[type[Exception], ...] = (OwLanderError, DescriptionError)
