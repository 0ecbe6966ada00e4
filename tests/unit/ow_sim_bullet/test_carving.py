"""The terrain carver on its own: a plate of points pressed into a flat height map (no pybullet),
and the carving points sampled on the tools' collision shapes."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from ow_description.description import DEFAULT_GROUND_Z, GRINDER_LINK, SCOOP_LINK, URDF_PATH
from ow_description.shapes import link_shapes
from ow_description.terrain import HeightMap
from ow_sim_bullet.carving import EMBEDDED_DEPTH, TerrainCarver, collision_surface_points
from ow_sim_bullet.config import SimConfig
from ow_sim_bullet.errors import ConfigError

CONFIG = SimConfig()
RESOLUTION = 0.04
#: m, base_link x, y of the plate's centre (a cell corner).
AT = (1.0, 0.2)


class FakeSurface:
    """Records what the carver asks of the simulator's surface."""

    def __init__(self, heightmap: HeightMap) -> None:
        self.floor = float(heightmap.heights.min()) - 0.5
        self.refreshed: list[tuple[tuple[int, int], tuple[int, int]]] = []
        self.removed = False

    def refresh(self, heights: np.ndarray, rows: tuple[int, int], cols: tuple[int, int]) -> int:
        self.refreshed.append((rows, cols))
        return 1

    def remove(self) -> None:
        self.removed = True


def plate(half: float = 0.05, spacing: float = 0.01) -> np.ndarray:
    """(3, n) points of a horizontal square plate in its own frame (z = 0)."""
    axis = np.arange(-half, half + 1e-9, spacing)
    x, y = np.meshgrid(axis, axis)
    return np.stack((x.ravel(), y.ravel(), np.zeros(x.size)))


def ground() -> HeightMap:
    return HeightMap(np.full((51, 76), DEFAULT_GROUND_Z), RESOLUTION, -0.5, -0.8)


@pytest.fixture()
def carver() -> tuple[TerrainCarver, list[FakeSurface]]:
    surfaces: list[FakeSurface] = []

    def make(heightmap: HeightMap) -> FakeSurface:
        surfaces.append(FakeSurface(heightmap))
        return surfaces[-1]

    return TerrainCarver(ground(), CONFIG, {"scoop": plate(), "grinder": plate()}, make), surfaces


def press(carver: TerrainCarver, tool: str, z: float, force: float, digging: bool = True) -> None:
    carver.cut(tool, np.eye(3), np.array([AT[0], AT[1], z]), force, digging)


def under_plate(carver: TerrainCarver) -> float:
    return carver.height_at(*AT)


def test_a_tool_pressing_at_full_force_sinks_by_the_carve_step(carver):
    terrain, surfaces = carver
    press(terrain, "scoop", DEFAULT_GROUND_Z, CONFIG.carve_full_force)
    assert terrain.version == 0  # the simulator's surface follows at the commit
    assert terrain.commit()
    assert terrain.version == 1
    assert under_plate(terrain) == pytest.approx(DEFAULT_GROUND_Z - CONFIG.carve_step)
    # Only the cells under the plate (and their corners) changed, and were refreshed.
    changed = np.argwhere(terrain.heightmap.heights != DEFAULT_GROUND_Z)
    ((rows, cols),) = surfaces[0].refreshed
    assert (rows, cols) == (
        (changed[:, 0].min(), changed[:, 0].max()),
        (changed[:, 1].min(), changed[:, 1].max()),
    )
    assert np.ptp(changed[:, 0]) * RESOLUTION <= 0.1 + 2 * RESOLUTION
    assert not terrain.commit()


def test_the_terrain_yields_in_proportion_to_the_force_above_the_yield_force(carver):
    terrain, _ = carver
    half = (CONFIG.terrain_yield_force + CONFIG.carve_full_force) / 2
    press(terrain, "scoop", DEFAULT_GROUND_Z, half)
    terrain.commit()
    assert under_plate(terrain) == pytest.approx(DEFAULT_GROUND_Z - CONFIG.carve_step / 2)


@pytest.mark.parametrize(
    ("below_surface", "carved"), [(0.0, False), (EMBEDDED_DEPTH / 2, False), (0.02, True)]
)
def test_below_the_yield_force_only_material_well_inside_a_tool_goes(carver, below_surface, carved):
    terrain, _ = carver
    z = DEFAULT_GROUND_Z - below_surface
    press(terrain, "scoop", z, CONFIG.terrain_yield_force / 2)
    assert terrain.commit() == carved
    assert under_plate(terrain) == pytest.approx(z if carved else DEFAULT_GROUND_Z)


def test_the_grinder_cuts_whatever_the_force(carver):
    terrain, _ = carver
    press(terrain, "grinder", DEFAULT_GROUND_Z, 0.1)
    terrain.commit()
    assert under_plate(terrain) == pytest.approx(DEFAULT_GROUND_Z - CONFIG.carve_step)
    press(terrain, "scoop", DEFAULT_GROUND_Z - CONFIG.carve_step, 0.1)
    assert not terrain.commit()


def test_the_terrain_is_never_carved_below_the_surfaces_floor(carver):
    terrain, surfaces = carver
    press(terrain, "scoop", DEFAULT_GROUND_Z - 2.0, CONFIG.carve_full_force)
    terrain.commit()
    assert under_plate(terrain) == pytest.approx(surfaces[0].floor + 1e-3)


def test_reaches_only_a_box_over_the_grid_near_the_terrain(carver):
    terrain, _ = carver
    x, y = AT
    assert terrain.reaches((x, y, DEFAULT_GROUND_Z - 0.01), (x + 0.1, y + 0.1, 0.0))
    assert terrain.reaches((x, y, DEFAULT_GROUND_Z + 0.03), (x + 0.1, y + 0.1, 0.0))
    assert not terrain.reaches((x, y, DEFAULT_GROUND_Z + 0.05), (x + 0.1, y + 0.1, 0.2))
    assert not terrain.reaches((5.0, y, -1.0), (5.1, y + 0.1, 0.0))


def test_a_replaced_terrain_starts_afresh(carver):
    terrain, surfaces = carver
    press(terrain, "scoop", DEFAULT_GROUND_Z, CONFIG.carve_full_force)
    terrain.commit()
    terrain.replace(ground())
    assert surfaces[0].removed and len(surfaces) == 2
    assert terrain.version == 2
    assert under_plate(terrain) == DEFAULT_GROUND_Z
    # The carver's copy is its own: carving does not touch the map it was given.
    given = ground()
    terrain.replace(given)
    press(terrain, "scoop", DEFAULT_GROUND_Z, CONFIG.carve_full_force)
    assert np.all(given.heights == DEFAULT_GROUND_Z)


def test_depth_at_rest_and_ahead_of_a_moving_tip():
    heights = np.full((51, 76), DEFAULT_GROUND_Z)
    heights[:, 40:] = DEFAULT_GROUND_Z + 0.02  # a 2 cm step at x >= 1.1 m
    terrain = TerrainCarver(
        HeightMap(heights, RESOLUTION, -0.5, -0.8), CONFIG, {}, lambda hm: FakeSurface(hm)
    )
    tip = np.array([1.0, 0.0, DEFAULT_GROUND_Z - 0.01])
    at_rest = terrain.depth(tip, np.zeros(3))
    assert at_rest == pytest.approx((DEFAULT_GROUND_Z, 0.01))
    # Moving towards the step, which is within the look-ahead (5 cm): it counts.
    near_step = tip + np.array([0.05, 0.0, 0.0])
    terrain_z, depth = terrain.depth(near_step, np.array([0.01, 0.0, 0.0]))
    assert terrain_z == pytest.approx(DEFAULT_GROUND_Z)
    assert depth == pytest.approx(0.03)
    # Moving away from it: only the ground ahead counts.
    assert terrain.depth(near_step, np.array([-0.01, 0.0, 0.0]))[1] == (pytest.approx(0.01))
    # Above all terrain the depth is 0.
    assert terrain.depth(tip + np.array([0.0, 0.0, 0.5]), np.array([0.01, 0.0, 0.0]))[1] == 0.0


@pytest.mark.parametrize("link", [SCOOP_LINK, GRINDER_LINK])
def test_carving_points_lie_on_the_collision_shapes_and_cover_them(link):
    text = URDF_PATH.read_text()
    points = collision_surface_points(text, link, 0.01)
    shapes = link_shapes(link, text)
    on_some_shape = np.zeros(len(points), dtype=bool)
    for shape in shapes:
        local = (points - shape.translation) @ shape.rotation  # into the shape's frame
        if shape.kind == "box":
            half = np.array(shape.size) / 2
            inside = np.all(np.abs(local) <= half + 1e-9, axis=1)
            on_face = np.any(np.isclose(np.abs(local), half), axis=1)
            on_some_shape |= inside & on_face
        else:
            radius, length = shape.size
            r, z = np.hypot(local[:, 0], local[:, 1]), np.abs(local[:, 2])
            inside = (r <= radius + 1e-9) & (z <= length / 2 + 1e-9)
            on_some_shape |= inside & (np.isclose(r, radius) | np.isclose(z, length / 2))
    assert on_some_shape.all()
    # Finer spacing, more points; a box's corners are sampled.
    assert len(collision_surface_points(text, link, 0.005)) > len(points)
    box = next((s for s in shapes if s.kind == "box"), None)
    if box is not None:
        corner = box.rotation @ (np.array(box.size) / 2) + box.translation
        assert np.min(np.linalg.norm(points - corner, axis=1)) < 1e-9


def test_carving_with_a_link_without_shapes_is_a_config_error():
    with pytest.raises(ConfigError, match="cannot carve with l_nowhere"):
        collision_surface_points(URDF_PATH.read_text(), "l_nowhere", 0.01)


def test_the_carve_parameters_come_from_the_config():
    gentle = dataclasses.replace(CONFIG, carve_step=0.001)
    terrain = TerrainCarver(ground(), gentle, {"scoop": plate()}, lambda hm: FakeSurface(hm))
    press(terrain, "scoop", DEFAULT_GROUND_Z, gentle.carve_full_force)
    terrain.commit()
    assert under_plate(terrain) == pytest.approx(DEFAULT_GROUND_Z - 0.001)
