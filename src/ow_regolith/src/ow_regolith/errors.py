"""Exceptions of ow_regolith. Each message names the bad value and what was expected."""

from ow_runtime.errors import ConfigError as RuntimeConfigError


class RegolithError(Exception):
    """Base class of every error raised by ow_regolith."""


class ConfigError(RegolithError, RuntimeConfigError):
    """A regolith parameter (material, layer, scoop shape, dock) is missing, of the wrong type or
    out of range."""


class MaterialError(RegolithError):
    """An unknown material or layer, a composition that does not sum to 1, or a volume taken
    from a bulk that does not hold it."""


class BudgetError(RegolithError):
    """A transfer of more regolith than an account holds, or to an account that cannot take it."""


class GeometryError(RegolithError):
    """The scoop's or the dock's collision shapes do not describe a container (no cavity, no
    mouth, a missing shape)."""


class CarvingError(RegolithError):
    """A carve update the ledger cannot account for: height maps of another shape than the
    terrain's, or a cut that raises the terrain."""
