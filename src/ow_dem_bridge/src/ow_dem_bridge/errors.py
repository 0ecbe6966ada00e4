"""Errors of ow_dem_bridge: one hierarchy, messages that name the bad value."""

from __future__ import annotations

from ow_runtime import errors as runtime_errors


class DemBridgeError(Exception):
    """Base of every error raised by ow_dem_bridge."""


class TableError(DemBridgeError):
    """A force table cannot be read: missing column, bad number, NaN, duplicate or unsorted key."""


class QueryError(DemBridgeError):
    """A model was asked about a tool or material it has no data for."""


class ConfigError(DemBridgeError, runtime_errors.ConfigError):
    """A model or node parameter is missing or invalid (the message names the key)."""


class GeometryError(DemBridgeError):
    """The tool geometry cannot be read from the URDF."""


class DemRunError(DemBridgeError):
    """A DEM (YADE) run failed or is unavailable."""
