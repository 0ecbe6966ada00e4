"""HeightMap: bilinear heights, edges, and clear errors."""

import numpy as np
import pytest

from ow_description.description import DEFAULT_GROUND_Z
from ow_description.errors import TerrainError
from ow_description.terrain import HeightMap


def test_bilinear_interpolation_is_exact_for_a_plane():
    xs = np.arange(5) * 0.1 + 1.0
    ys = np.arange(4) * 0.1 - 0.2
    plane = 0.3 * xs[None, :] - 0.2 * ys[:, None] + 0.05
    hm = HeightMap(plane, 0.1, 1.0, -0.2)
    px = np.array([1.0, 1.13, 1.37, 1.4])
    py = np.array([-0.2, 0.01, 0.05, 0.1])
    assert np.allclose(hm.height_at(px, py), 0.3 * px - 0.2 * py + 0.05)


def test_outside_the_grid_the_edge_continues():
    hm = HeightMap(np.array([[0.0, 1.0], [2.0, 3.0]]), 1.0, 0.0, 0.0)
    assert hm.height_at(-5.0, -5.0) == pytest.approx(0.0)
    assert hm.height_at(9.0, 9.0) == pytest.approx(3.0)
    assert hm.height_at(0.5, 0.5) == pytest.approx(1.5)


def test_flat():
    hm = HeightMap.flat(DEFAULT_GROUND_Z)
    assert np.all(hm.height_at(np.linspace(-3, 3, 7), np.zeros(7)) == DEFAULT_GROUND_Z)


@pytest.mark.parametrize(
    ("heights", "resolution", "match"),
    [
        (np.zeros(4), 0.1, "2-D grid"),
        (np.zeros((1, 5)), 0.1, "at least 2x2"),
        (np.array([[0.0, np.nan], [0.0, 0.0]]), 0.1, r"non-finite height at cell \(row 0, col 1\)"),
        (np.zeros((3, 3)), 0.0, "resolution 0.0 m"),
        (np.zeros((3, 3)), float("nan"), "resolution nan m"),
    ],
)
def test_bad_height_maps_are_rejected(heights, resolution, match):
    with pytest.raises(TerrainError, match=match):
        HeightMap(heights, resolution, 0.0, 0.0)
