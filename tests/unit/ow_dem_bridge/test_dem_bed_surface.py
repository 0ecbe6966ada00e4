"""The live DEM's surface: a bed's bulk heights on a coarse grid (the solid volume of the spheres
centred in a cell over cell area x solid fraction), their change over a dig, and that change in
base_link (bilinear between the cells' centres, held to the footprint's edge, zero outside)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ow_dem_bridge.bed_surface import CELL_DIAMETERS, SurfaceGrid, bulk_heights, height_change
from ow_dem_bridge.live_bed import BedFrame, DemSurface

#: The default bed (0.5 x 0.2 m) of 1 cm grains: cells of ~4 cm.
GRID = SurfaceGrid.over_bed(0.5, 0.2, 0.01)
SOLID_FRACTION = 0.6


def spheres_on_a_lattice(step: float = 0.013) -> list[tuple[float, float, float]]:
    """Spheres over the whole bed, two layers, radii varying from 8 to 12 mm."""
    spheres = []
    for k, u in enumerate(np.arange(step / 2, GRID.length, step)):
        for m, v in enumerate(np.arange(-GRID.width / 2 + step / 2, GRID.width / 2, step)):
            for layer in range(2):
                spheres.append((float(u), float(v), 0.008 + 0.004 * ((k + m + layer) % 3) / 2))
    return spheres


def test_the_cells_are_about_two_diameters_and_tile_the_bed():
    assert (GRID.nu, GRID.nv) == (12, 5)
    side = CELL_DIAMETERS * 2 * 0.01
    assert GRID.cell_u * GRID.nu == pytest.approx(0.5) and GRID.cell_v * GRID.nv == 0.2
    assert abs(GRID.cell_u - side) <= side / 2 and abs(GRID.cell_v - side) <= side / 2
    assert GRID.cell_of(0.0, -0.1) == (0, 0)
    assert GRID.cell_of(0.499, 0.099) == (4, 11)
    assert GRID.cell_of(0.5, 0.0) is None and GRID.cell_of(0.1, -0.1001) is None


def test_an_untouched_bed_changes_by_exactly_zero():
    spheres = spheres_on_a_lattice()
    before = bulk_heights(GRID, spheres, SOLID_FRACTION)
    after = bulk_heights(GRID, list(spheres), SOLID_FRACTION)
    assert all(value == 0.0 for row in height_change(before, after) for value in row)
    # The heights add up to the spheres' volume over the bed's bulk: a bulk height.
    solid = sum(4 / 3 * math.pi * r**3 for _, _, r in spheres)
    mean = sum(map(sum, before)) / (GRID.nu * GRID.nv)
    assert mean == pytest.approx(solid / (0.5 * 0.2 * SOLID_FRACTION))


def test_moving_one_sphere_changes_exactly_its_two_cells_by_its_bulk_height():
    spheres = spheres_on_a_lattice()
    before = bulk_heights(GRID, spheres, SOLID_FRACTION)
    u, v, radius = spheres[100]
    source = GRID.cell_of(u, v)
    moved = list(spheres)
    moved[100] = (0.48, 0.09, radius)  # into the far corner cell
    target = GRID.cell_of(0.48, 0.09)
    assert source != target
    change = height_change(before, bulk_heights(GRID, moved, SOLID_FRACTION))
    step = 4 / 3 * math.pi * radius**3 / (GRID.cell_u * GRID.cell_v * SOLID_FRACTION)
    for iv in range(GRID.nv):
        for iu in range(GRID.nu):
            expected = {source: -step, target: step}.get((iv, iu), 0.0)
            assert change[iv][iu] == pytest.approx(expected, abs=1e-15)


def test_spheres_outside_the_bed_count_nowhere():
    heights = bulk_heights(GRID, [(-0.01, 0.0, 0.01), (0.2, 0.15, 0.01)], SOLID_FRACTION)
    assert all(value == 0.0 for row in heights for value in row)


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda: SurfaceGrid.over_bed(0.5, 0.0, 0.01), "every size must be > 0"),
        (lambda: bulk_heights(GRID, [], 0.0), r"solid fraction must lie in \(0, 1\]"),
        (lambda: height_change([[0.0]], [[0.0, 1.0]]), "different shapes"),
    ],
)
def test_bad_grids_are_refused(call, message):
    with pytest.raises(ValueError, match=message):
        call()


def surface(change: np.ndarray, heading: float = 0.0) -> DemSurface:
    reply = {"length": 0.5, "width": 0.2, "nu": 12, "nv": 5, "change": change.tolist()}
    return DemSurface.from_reply(reply, BedFrame((1.4, 0.05, -0.3), heading))


def test_the_change_in_base_link_is_bilinear_between_centres_and_zero_outside():
    change = np.zeros((5, 12))
    change[2, 3] = -0.02  # one cell of the middle row fell 2 cm
    dem = surface(change, heading=math.pi / 2)  # the bed along base_link +y
    centres = dem.centres()
    x, y = centres[2, 3]
    # Bed u along +y, v along -x: the cell's centre is 3.5 cells up y and in the middle in x.
    assert (x, y) == pytest.approx((1.4, 0.05 + 3.5 * dem.cell_u))
    assert dem.change_at(np.array(x), np.array(y)) == pytest.approx(-0.02)
    # Half-way to the next centre along the dig: half the change.
    halfway = dem.change_at(np.array(x), np.array(y + dem.cell_u / 2))
    assert halfway == pytest.approx(-0.01)
    # Beyond the footprint (behind the bed's back edge): zero, whatever the grid holds.
    assert dem.change_at(np.array(x), np.array(0.05 - 0.01)) == 0.0
    assert not dem.covers(np.array(x), np.array(0.04)) and dem.covers(np.array(x), np.array(y))


def test_the_edge_cells_hold_to_the_footprints_edge():
    dem = surface(np.full((5, 12), 0.005))
    x = np.array([1.4, 1.4 + 0.499, 1.4 + 0.25])
    y = np.array([0.05 - 0.099, 0.05 + 0.099, 0.05])
    assert np.allclose(dem.change_at(x, y), 0.005)
