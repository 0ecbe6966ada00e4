"""Scenes for the regolith tests: a terrain, scoop poses (imported by the test modules; the
fixtures are in conftest.py)."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from ow_description.terrain import HeightMap
from ow_regolith.scoop import ScoopGeometry

FloatArray = npt.NDArray[np.float64]

#: m, the ground of the test terrains (the project's default ground height).
GROUND_Z = -0.155
#: m, their cells (the simulation's generated terrains use 4 cm).
RESOLUTION = 0.04


def field_terrain() -> HeightMap:
    """A flat field in front of the lander: x 1.0 .. 2.6 m, y -0.6 .. 0.6 m, 4 cm cells."""
    rows, cols = 31, 41
    return HeightMap(np.full((rows, cols), GROUND_Z), RESOLUTION, 1.0, -0.6)


def pose(R: FloatArray, p: FloatArray) -> FloatArray:
    """(4, 4) from a rotation and a translation."""
    X = np.eye(4)
    X[:3, :3] = R
    X[:3, 3] = p
    return X


#: The scoop upright for digging and carrying: bottom down (+z of l_scoop along -z of base_link),
#: the cutting edge towards +x (the lander's carrying pose along base_link x).
BOTTOM_DOWN = np.column_stack([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]])


def scoop_with_tip_at(geometry: ScoopGeometry, R: FloatArray, tip: FloatArray) -> FloatArray:
    """``X_base_scoop`` with orientation ``R`` and the cutting edge's centre at ``tip``."""
    return pose(R, np.asarray(tip) - R @ geometry.tip)


def scoop_pouring_at(geometry: ScoopGeometry, R: FloatArray, point: FloatArray) -> FloatArray:
    """``X_base_scoop`` with orientation ``R`` and its pour point at ``point``."""
    at_origin = geometry.pour_point(pose(R, np.zeros(3)))
    return pose(R, np.asarray(point) - at_origin)
