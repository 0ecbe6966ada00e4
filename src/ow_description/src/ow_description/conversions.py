"""Messages to the pure types of ow_description (message classes read by attribute only: no rospy,
no generated-message import)."""

from __future__ import annotations

from typing import Any

import numpy as np

from ow_description.errors import TerrainError
from ow_description.terrain import HeightMap


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
