"""Terrain height maps in base_link, shared by planner, collision checker and simulation.

A :class:`HeightMap` is a regular grid of terrain heights z(x, y) in ``base_link`` (metres). Cell
(r, c) has its centre at ``(origin_x + c * resolution, origin_y + r * resolution)``; heights between
cell centres are bilinear, and outside the grid the nearest edge cell is used (the terrain
continues flat beyond its edge). The same layout is used by ``ow_msgs/HeightMap``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ow_description.errors import TerrainError

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class HeightMap:
    """Terrain heights on a regular grid.

    Attributes:
        heights: (rows, cols) m, terrain z in base_link; row index along y, column index along x.
        resolution: m, cell size in x and y (> 0).
        origin_x: m, x of the centre of cell (0, 0).
        origin_y: m, y of the centre of cell (0, 0).
    """

    heights: FloatArray
    resolution: float
    origin_x: float
    origin_y: float

    def __post_init__(self) -> None:
        heights = np.asarray(self.heights, dtype=np.float64)
        if heights.ndim != 2 or heights.shape[0] < 2 or heights.shape[1] < 2:
            msg = f"height map must be a 2-D grid of at least 2x2 cells, got shape {heights.shape}"
            raise TerrainError(msg)
        if not np.all(np.isfinite(heights)):
            bad = np.argwhere(~np.isfinite(heights))[0]
            msg = f"height map has a non-finite height at cell (row {bad[0]}, col {bad[1]})"
            raise TerrainError(msg)
        if not (np.isfinite(self.resolution) and self.resolution > 0):
            msg = f"height map resolution {self.resolution} m must be a positive number"
            raise TerrainError(msg)
        object.__setattr__(self, "heights", heights)

    @classmethod
    def flat(
        cls, z: float, half_extent: float = 3.0, resolution: float = 0.05, centre_x: float = 0.0
    ) -> HeightMap:
        """A flat terrain at height ``z`` (m) around the lander, ``half_extent`` m each way."""
        n = round(2 * half_extent / resolution) + 1
        return cls(np.full((n, n), float(z)), resolution, centre_x - half_extent, -half_extent)

    @property
    def shape(self) -> tuple[int, int]:
        """(rows, cols) of the grid."""
        rows, cols = self.heights.shape
        return int(rows), int(cols)

    @property
    def x_max(self) -> float:
        """m, x of the centre of the last column."""
        return self.origin_x + (self.shape[1] - 1) * self.resolution

    @property
    def y_max(self) -> float:
        """m, y of the centre of the last row."""
        return self.origin_y + (self.shape[0] - 1) * self.resolution

    def height_at(self, x: npt.ArrayLike, y: npt.ArrayLike) -> FloatArray:
        """Bilinear terrain height at points (x, y) in base_link.

        Args:
            x: m, any shape.
            y: m, same shape as x.

        Returns:
            m, terrain z at each point, same shape as x.
        """
        rows, cols = self.shape
        fc = np.clip(
            (np.asarray(x, dtype=np.float64) - self.origin_x) / self.resolution, 0, cols - 1
        )
        fr = np.clip(
            (np.asarray(y, dtype=np.float64) - self.origin_y) / self.resolution, 0, rows - 1
        )
        c0 = np.minimum(np.floor(fc).astype(np.intp), cols - 2)
        r0 = np.minimum(np.floor(fr).astype(np.intp), rows - 2)
        tc = fc - c0
        tr = fr - r0
        h = self.heights
        return (1 - tr) * ((1 - tc) * h[r0, c0] + tc * h[r0, c0 + 1]) + tr * (
            (1 - tc) * h[r0 + 1, c0] + tc * h[r0 + 1, c0 + 1]
        )

    def cell_centres(self) -> tuple[FloatArray, FloatArray]:
        """(xs, ys): m, the cell-centre coordinates along x (cols,) and along y (rows,)."""
        rows, cols = self.shape
        xs = self.origin_x + self.resolution * np.arange(cols, dtype=np.float64)
        ys = self.origin_y + self.resolution * np.arange(rows, dtype=np.float64)
        return xs, ys
