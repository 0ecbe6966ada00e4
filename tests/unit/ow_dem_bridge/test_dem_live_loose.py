"""The loose regolith the simulation hands the live DEM (``terrain_forces: yade``): the bed's grid
carries, besides the solid heights, the loose layer's top (the grinder's cuttings in its trench),
and the model reports the material's top the simulation measures the scoop's depth against. No
YADE runs here."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ow_dem_bridge.live import LiveDemModel
from ow_dem_bridge.live_bed import BedGrid, sample_bed
from ow_dem_bridge.live_config import LiveConfig

GROUND = -0.155
TRENCH_FLOOR = -0.255
LOOSE_TOP = -0.17


class Trench:
    """Flat ground with a 10 cm deep trench for |y| < 0.05 m, x > 1.6 m (the height map)."""

    def height_at(self, x: float, y: float) -> float:
        return TRENCH_FLOOR if abs(y) < 0.05 and x > 1.6 else GROUND


def cuttings(x: float, y: float) -> float:
    """The loose layer's top: the grinder's cuttings fill the trench up to ``LOOSE_TOP``; none
    elsewhere (the solid top, here below the height map)."""
    return LOOSE_TOP if abs(y) < 0.05 and x > 1.6 else GROUND - 0.5


US = np.linspace(0.0, 0.5, 51)
VS = np.linspace(-0.1, 0.1, 21)


def test_the_bed_grid_holds_the_loose_layer_above_the_solid_surface():
    grid = sample_bed(Trench(), cuttings, (1.55, 0.0), 0.0, US, VS)
    assert grid.solid.shape == grid.top.shape == (len(VS), len(US))
    x = 1.55 + US[None, :] + 0 * VS[:, None]
    in_trench = (np.abs(VS)[:, None] < 0.05) & (x > 1.6)
    assert np.all(grid.solid[in_trench] == TRENCH_FLOOR)
    assert np.all(grid.top[in_trench] == LOOSE_TOP)  # the cuttings' top, above the floor
    # Outside the trench the loose top is below the height map: the material's top is the solid.
    assert np.all(grid.top[~in_trench] == GROUND) and np.all(grid.solid[~in_trench] == GROUND)


def test_without_loose_regolith_the_top_is_the_solid_surface():
    grid = sample_bed(Trench(), None, (1.55, 0.0), 0.3, US, VS)
    assert np.array_equal(grid.top, grid.solid)


def test_the_grid_is_laid_along_the_heading_and_read_back_where_it_was_sampled():
    heading = math.radians(35.0)
    grid = sample_bed(Trench(), cuttings, (1.5, -0.02), heading, US, VS)
    c, s = math.cos(heading), math.sin(heading)
    for j, i in ((3, 7), (10, 20), (14, 44)):
        u, v = US[i], VS[j]
        x, y = 1.5 + c * u - s * v, -0.02 + s * u + c * v
        assert grid.top_at(x, y) == pytest.approx(grid.top[j, i], abs=1e-12)
        assert grid.top[j, i] == max(Trench().height_at(x, y), cuttings(x, y))
    assert grid.top_at(1.5 - 0.05, -0.02) == -math.inf  # behind the bed
    assert grid.top_at(1.5, 0.5) == -math.inf  # beside it


def test_between_grid_points_the_top_is_bilinear():
    top = np.array([[0.0, 1.0], [2.0, 3.0]])
    grid = BedGrid((0.0, 0.0), 0.0, np.array([0.0, 1.0]), np.array([0.0, 1.0]), top, top)
    assert grid.top_at(0.5, 0.5) == pytest.approx(1.5)
    assert grid.top_at(0.25, 1.0) == pytest.approx(2.25)


def test_between_digs_the_model_reports_the_terrain_with_its_loose_layer_now(tmp_path):
    # material 0: no YADE process is started; "true" stands in for the launcher on PATH.
    model = LiveDemModel(LiveConfig(material=0, yade="true", cache_dir=str(tmp_path)), None)
    assert model.material_top(1.7, 0.0) == -math.inf  # not attached yet
    model.attach(Trench(), 0.01, cuttings)
    assert model.material_top(1.7, 0.0) == LOOSE_TOP
    assert model.material_top(1.7, 0.2) == GROUND
    model.attach(Trench(), 0.01)
    assert model.material_top(1.7, 0.0) == TRENCH_FLOOR
    model.close()
