"""Messages to and from the pure types of ow_lander (HeightMap, joint states, requests)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from ow_lander.errors import TerrainError
from ow_lander.terrain import HeightMap


def height_map_from_msg(msg: Any) -> HeightMap:
    """A :class:`HeightMap` from an ``ow_msgs/HeightMap``.

    Raises:
        TerrainError: the sizes do not match or the map is invalid.
    """
    rows, cols = int(msg.rows), int(msg.cols)
    heights = np.asarray(msg.heights, dtype=np.float64)
    if heights.size != rows * cols:
        text = f"height map has {heights.size} heights for {rows} x {cols} cells"
        raise TerrainError(text)
    return HeightMap(heights.reshape(rows, cols), float(msg.resolution), msg.origin_x, msg.origin_y)


def request_to_dict(request: Any) -> dict[str, Any]:
    """A service request's fields as ``{name: value}`` (floats as Python floats)."""
    out: dict[str, Any] = {}
    for name in request.__slots__:
        value = getattr(request, name)
        out[name] = float(value) if isinstance(value, float) else value
    return out


def joint_positions(names: list[str], positions: Any) -> dict[str, float]:
    """``{joint: position}`` of a ``sensor_msgs/JointState`` (by name, never by order)."""
    return {name: float(p) for name, p in zip(names, positions, strict=False)}


def jsonable(values: Mapping[str, Any]) -> dict[str, Any]:
    """Parameters with numpy and float32 values turned into plain JSON numbers."""
    out: dict[str, Any] = {}
    for key, value in values.items():
        if isinstance(value, bool | str) or value is None:
            out[key] = value
        elif isinstance(value, int | float | np.floating | np.integer):
            out[key] = round(float(value), 6)
        else:
            out[key] = str(value)
    return out
