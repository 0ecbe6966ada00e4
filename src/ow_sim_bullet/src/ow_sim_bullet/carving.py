"""The carvable terrain: the height map, its simulator surface, and the carving under the tools.

The tools carve with points sampled on their collision shapes (:func:`collision_surface_points`,
from the URDF's primitives as :mod:`ow_description.shapes` reads them). :class:`TerrainCarver` owns
the height map every part of the simulation reads (tool depth, ``/sim/terrain``) and keeps the
simulator's surface (a :class:`CarvableSurface`, in the simulation Bullet heightfield tiles) in
step with it. No pybullet here: the caller gives the tools' poses and forces.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Protocol

import numpy as np
import numpy.typing as npt

from ow_description.errors import ModelError
from ow_description.shapes import link_shapes
from ow_description.terrain import HeightMap
from ow_sim_bullet.config import SimConfig
from ow_sim_bullet.errors import ConfigError

FloatArray = npt.NDArray[np.float64]
IndexArray = npt.NDArray[np.intp]

#: m, depth below the surface at which a tool removes material anyway, digging or not, pressing
#: or not (a terrain replaced around a tool; a tool without contacts, ``tool_contact`` false).
EMBEDDED_DEPTH = 0.01
#: m, how far above the floor of the surface the terrain may be carved.
FLOOR_MARGIN = 1e-3
#: Powered cutters: digging, they remove what they touch at the full ``carve_step`` whatever the
#: force.
POWERED_TOOLS = frozenset({"grinder"})
#: m, how far ahead of a moving tool tip the terrain counts for the tool's depth.
DEPTH_LOOKAHEAD = 0.05
#: m/s, tip speeds below this count as not moving (depth is taken at the tip only).
MOVING_SPEED = 1e-3
#: m, distances ahead of a moving tip at which the terrain counts for its depth.
_LOOKAHEAD_STEPS: tuple[float, ...] = tuple(np.linspace(0.0, DEPTH_LOOKAHEAD, 6).tolist())


def collision_surface_points(urdf_text: str, link_name: str, spacing: float) -> FloatArray:
    """Points on the surface of a link's box and cylinder collision shapes, in the link frame.

    Each shape is sampled on a grid of its faces (boxes) or of its side and caps (cylinders),
    shapes in document order.

    Args:
        urdf_text: the URDF document.
        link_name: the link.
        spacing: m, largest distance between neighbouring points.

    Returns:
        (n, 3) m.

    Raises:
        ConfigError: the link is missing or has no collision shape, or the URDF has a collision
            shape other than a box or cylinder.
    """
    try:
        shapes = link_shapes(link_name, urdf_text)
    except ModelError as error:
        msg = f"cannot carve with {link_name}: {error}"
        raise ConfigError(msg) from error
    clouds = []
    for shape in shapes:
        if shape.kind == "box":
            size = list(shape.size)
            axes = [np.linspace(-s / 2, s / 2, max(2, math.ceil(s / spacing) + 1)) for s in size]
            grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
            on_face = np.any(np.isclose(np.abs(grid), np.array(size) / 2), axis=1)
            local = grid[on_face]
        else:
            radius, length = shape.size
            angles = np.linspace(
                0, 2 * math.pi, max(8, math.ceil(2 * math.pi * radius / spacing)), endpoint=False
            )
            heights = np.linspace(-length / 2, length / 2, max(2, math.ceil(length / spacing) + 1))
            a, h = np.meshgrid(angles, heights)
            side = np.stack((radius * np.cos(a), radius * np.sin(a), h), axis=-1).reshape(-1, 3)
            radii = np.linspace(0, radius, max(2, math.ceil(radius / spacing) + 1))
            rr, aa = np.meshgrid(radii, angles)
            disc = np.stack((rr * np.cos(aa), rr * np.sin(aa)), axis=-1).reshape(-1, 2)
            caps = [
                np.column_stack((disc, np.full(len(disc), z))) for z in (-length / 2, length / 2)
            ]
            local = np.vstack((side, *caps))
        clouds.append(local @ shape.rotation.T + shape.translation)
    return np.vstack(clouds)


@dataclass(frozen=True)
class CutWindow:
    """The heights of the window of cells one cut changed, before and after it (what the
    regolith's ledger is told, :meth:`ow_regolith.tracker.RegolithTracker.terrain_cut`).

    Attributes:
        before: (h, w) m, the window's heights before the cut.
        after: (h, w) m, the same after it (never higher).
        offset: (row, col) of the window's first cell in the height map.
    """

    before: FloatArray
    after: FloatArray
    offset: tuple[int, int]


class CarvableSurface(Protocol):
    """The simulator's copy of the terrain (:class:`ow_sim_bullet.bullet_terrain.BulletTerrain`)."""

    @property
    def floor(self) -> float:
        """m, the lowest height the surface can take."""
        ...

    def refresh(self, heights: FloatArray, rows: tuple[int, int], cols: tuple[int, int]) -> int:
        """Copy the heights of cells rows x cols (inclusive bounds) into the surface."""
        ...

    def remove(self) -> None:
        """Delete the surface from the simulator."""
        ...


class TerrainCarver:
    """The terrain's height map, lowered under the tools; the simulator's surface follows it.

    Deposits (regolith poured on the terrain) raise cells (:meth:`raise_cells`); nothing else
    does.

    Carving: the terrain gives way only to a tool that digs (the caller decides: the scoop in a
    dig phase, the grinder grinding; :class:`~ow_sim_bullet.tool_tracking.ToolTracker`);
    elsewhere it is solid. A digging tool pressing with a total normal force F above
    ``terrain_yield_force`` F_y lowers the terrain under its surface points by up to
    ``carve_step`` x min(1, (F - F_y) / (``carve_full_force`` - F_y)) (a viscoplastic terrain);
    a digging powered cutter (:data:`POWERED_TOOLS`) touching the terrain lowers it by the full
    ``carve_step``. Material any tool is more than :data:`EMBEDDED_DEPTH` inside is removed,
    digging or not. Each point lowers the four corners of its grid cell, never below the
    surface's floor.

    Args:
        heightmap: the initial terrain (copied).
        config: the carving parameters (``terrain_yield_force``, ``carve_step``,
            ``carve_full_force``).
        cutters: tool name -> (3, n) m, points on its collision surface in its link frame.
        make_surface: builds the simulator's surface of a height map (given the carver's own
            map, which it must only read).
    """

    def __init__(
        self,
        heightmap: HeightMap,
        config: SimConfig,
        cutters: Mapping[str, FloatArray],
        make_surface: Callable[[HeightMap], CarvableSurface],
    ) -> None:
        self._config = config
        self._cutters = dict(cutters)
        self._make_surface = make_surface
        #: incremented whenever the terrain changes (carving or replacement).
        self.version = 0
        self._changed_rows: list[int] = []
        self._changed_cols: list[int] = []
        self._install(heightmap)

    def _install(self, heightmap: HeightMap) -> None:
        """Take a copy of ``heightmap`` and make its simulator surface."""
        # C order: carving indexes it through its flat view.
        self._heights = np.array(heightmap.heights, dtype=np.float64, order="C")
        self._heightmap = HeightMap(
            self._heights, heightmap.resolution, heightmap.origin_x, heightmap.origin_y
        )
        self._surface = self._make_surface(self._heightmap)
        #: m, a bound above every interpolated terrain height (raised with the terrain).
        self._height_bound = float(self._heights.max()) + 1e-9

    def replace(self, heightmap: HeightMap) -> None:
        """Replace the terrain (the old one, with its trenches, is discarded)."""
        self._surface.remove()
        self._install(heightmap)
        self.version += 1

    # ------------------------------------------------------------------ reading
    @property
    def heightmap(self) -> HeightMap:
        """A copy of the current (carved) terrain."""
        hm = self._heightmap
        return HeightMap(self._heights.copy(), hm.resolution, hm.origin_x, hm.origin_y)

    @property
    def floor_m(self) -> float:
        """m, the lowest height the terrain may be carved or lowered to."""
        return self._surface.floor + FLOOR_MARGIN

    def height_at(self, x: float, y: float) -> float:
        """m, current terrain height at (x, y) in base_link (bilinear in the height map)."""
        return float(self._heightmap.height_at(x, y))

    def above(self, point: FloatArray) -> bool:
        """Whether ``point`` (m, base_link) is above every part of the terrain: its
        :meth:`depth` is 0 whatever its velocity."""
        return bool(point[2] > self._height_bound)

    def depth(self, point: FloatArray, velocity: FloatArray) -> tuple[float, float]:
        """(terrain z at a tool tip, depth of the tip below the terrain at and ahead of it), m.

        Args:
            point: (3,) m, the tip in base_link.
            velocity: (3,) m/s, its velocity: the terrain up to :data:`DEPTH_LOOKAHEAD` ahead
                of a tip moving faster than :data:`MOVING_SPEED` counts.
        """
        terrain_z, surface = self.surface_ahead(point, velocity)
        return terrain_z, max(0.0, surface - float(point[2]))

    def surface_ahead(self, point: FloatArray, velocity: FloatArray) -> tuple[float, float]:
        """(terrain z at a tool tip, highest terrain z at and ahead of it), m: the terrain of
        :meth:`depth` (above all terrain, at the tip only).

        Args:
            point: (3,) m, the tip in base_link.
            velocity: (3,) m/s, its velocity (see :meth:`depth`).
        """
        x, y, z = point.tolist()
        vx, vy, _ = velocity.tolist()
        # Above all terrain the depth is 0 whatever lies ahead: look at the tip only, as at rest.
        horizontal = 0.0 if z > self._height_bound else float(np.hypot(vx, vy))
        if horizontal < MOVING_SPEED:
            terrain_z = self._heights_along(x, y, 0.0, 0.0, (0.0,))[0]
            return terrain_z, terrain_z
        # The first distance is 0: the tip itself.
        ahead = self._heights_along(x, y, vx / horizontal, vy / horizontal, _LOOKAHEAD_STEPS)
        return ahead[0], max(ahead)

    def _heights_along(
        self, x: float, y: float, dx: float, dy: float, distances: tuple[float, ...]
    ) -> list[float]:
        """m, terrain heights at (x + a dx, y + a dy) for each a in ``distances`` (m, base_link).

        ``HeightMap.height_at``'s arithmetic for scalars: the same operations in the same order
        on the same doubles, so bit-identical, at a twentieth of the cost of numpy on one point.
        """
        hm = self._heightmap
        origin_x, origin_y, resolution = hm.origin_x, hm.origin_y, hm.resolution
        rows, cols = self._heights.shape
        h = self._heights.item
        heights = []
        for a in distances:
            fc = min(max((x + a * dx - origin_x) / resolution, 0.0), cols - 1.0)
            fr = min(max((y + a * dy - origin_y) / resolution, 0.0), rows - 1.0)
            c0 = min(math.floor(fc), cols - 2)
            r0 = min(math.floor(fr), rows - 2)
            tc = fc - c0
            tr = fr - r0
            heights.append(
                (1 - tr) * ((1 - tc) * h(r0, c0) + tc * h(r0, c0 + 1))
                + tr * ((1 - tc) * h(r0 + 1, c0) + tc * h(r0 + 1, c0 + 1))
            )
        return heights

    # ------------------------------------------------------------------ carving
    def reaches(self, low: tuple[float, ...], high: tuple[float, ...]) -> bool:
        """Whether a tool within the box ``low``-``high`` (m, base_link) may cut the terrain:
        the box is over the grid and its bottom within one cell of the terrain under it."""
        hm = self._heightmap
        rows, cols = self._heights.shape
        c0 = max(int((low[0] - hm.origin_x) / hm.resolution), 0)
        c1 = min(int((high[0] - hm.origin_x) / hm.resolution) + 2, cols)
        r0 = max(int((low[1] - hm.origin_y) / hm.resolution), 0)
        r1 = min(int((high[1] - hm.origin_y) / hm.resolution) + 2, rows)
        return not (
            r0 >= r1 or c0 >= c1 or low[2] > self._heights[r0:r1, c0:c1].max() + hm.resolution
        )

    def cut(
        self,
        tool: str,
        rotation: FloatArray,
        position: FloatArray,
        normal_force: float,
        digging: bool,
    ) -> CutWindow | None:
        """Lower the terrain under one tool (the surface follows at :meth:`commit`).

        Args:
            tool: a tool of ``cutters``.
            rotation: (3, 3) of its link frame in base_link.
            position: (3,) m, its link origin in base_link.
            normal_force: N, total normal contact force on it in the last step.
            digging: the tool digs (the terrain gives way to it); else only material it is
                more than :data:`EMBEDDED_DEPTH` inside goes.

        Returns:
            The window of cells the cut lowered, before and after it; None when it cut nothing.
        """
        config = self._config
        hm = self._heightmap
        rows, cols = self._heights.shape
        heights = self._heights.reshape(-1)  # a view: cell (r, c) is r * cols + c
        #: flat offsets of the four corners of a cell from its lower-left corner.
        corner_offsets = np.array((0, 1, cols, cols + 1))
        floor = self.floor_m
        x, y, z = rotation @ self._cutters[tool] + position[:, None]
        col = np.floor((x - hm.origin_x) / hm.resolution).astype(np.intp)
        row = np.floor((y - hm.origin_y) / hm.resolution).astype(np.intp)
        # Usually every point is over the grid: a slice then spares the fancy indexing.
        inside: slice | IndexArray = slice(None)
        if not (row.min() >= 0 and row.max() < rows - 1) or not (
            col.min() >= 0 and col.max() < cols - 1
        ):
            inside = np.flatnonzero((row >= 0) & (row < rows - 1) & (col >= 0) & (col < cols - 1))
        excess = normal_force - config.terrain_yield_force
        if not digging:
            # Solid ground: a tool pressed into it meets the contact forces. Only material it
            # is well inside (a terrain replaced around it) goes, so that it is not trapped.
            target, slack = z, EMBEDDED_DEPTH
        elif tool in POWERED_TOOLS and normal_force > 0.0:
            # A powered cutter removes what it touches at the full rate (OceanWATERS lowers the
            # terrain under the grinder whatever the force).
            target, slack = z - config.carve_step, 0.0
        elif excess > 0.0:
            # Viscoplastic: the harder the tool presses, the faster the terrain yields (a tool
            # resting just above the yield force does not sink at full speed).
            full = config.carve_full_force - config.terrain_yield_force
            step = config.carve_step * min(excess / full, 1.0)
            target, slack = z - step, 0.0
        else:
            # Not pressing: only material a tool is well inside (e.g. after a terrain change) is
            # removed; the simulator's own contact penetration must not make the tool creep down.
            target, slack = z, EMBEDDED_DEPTH
        cell = row[inside] * cols + col[inside]
        target = target[inside]
        near = np.flatnonzero(target + slack < heights[cell] + hm.resolution)
        if not len(near):
            return None
        # Each point lowers the four corners of its grid cell (the vertices of the simulator's
        # triangles under it).
        cell = cell[near]
        target = np.maximum(target[near], floor)
        highest = np.maximum(
            np.maximum(heights[cell], heights[cell + 1]),
            np.maximum(heights[cell + cols], heights[cell + cols + 1]),
        )
        if not np.count_nonzero(highest > target + slack):
            return None  # the usual case: nothing above the tool, nothing to cut
        corners = (cell[:, None] + corner_offsets).ravel()
        target = np.repeat(target, len(corner_offsets))
        cut = heights[corners] > target + slack
        if not np.count_nonzero(cut):
            return None
        corners = corners[cut]
        corner_rows, corner_cols = np.divmod(corners, cols)
        r0, r1 = int(corner_rows.min()), int(corner_rows.max())
        c0, c1 = int(corner_cols.min()), int(corner_cols.max())
        window = (slice(r0, r1 + 1), slice(c0, c1 + 1))
        before = self._heights[window].copy()
        np.minimum.at(heights, corners, target[cut])
        self._changed_rows += [r0, r1]
        self._changed_cols += [c0, c1]
        return CutWindow(before, self._heights[window].copy(), (r0, c0))

    def raise_cells(self, rows: IndexArray, cols: IndexArray, raise_m: FloatArray) -> None:
        """Raise cells (rows[k], cols[k]) by raise_m[k] (m, >= 0): regolith deposited on the
        terrain (the surface follows at :meth:`commit`).

        Raises:
            ValueError: arrays of different lengths, a cell beyond the height map, or a negative
                or non-finite raise.
        """
        self._shift_cells(rows, cols, raise_m, 1.0, "raise")

    def lower_cells(self, rows: IndexArray, cols: IndexArray, lower_m: FloatArray) -> None:
        """Lower cells (rows[k], cols[k]) by lower_m[k] (m, >= 0): a column the regolith model
        cut deeper (the surface follows at :meth:`commit`).

        Raises:
            ValueError: arrays of different lengths, a cell beyond the height map, a negative or
                non-finite lowering, or one below the surface's floor.
        """
        self._shift_cells(rows, cols, lower_m, -1.0, "lowering")

    def _shift_cells(
        self, rows: IndexArray, cols: IndexArray, amount_m: FloatArray, sign: float, what: str
    ) -> None:
        """Move cells up (``sign`` 1) or down (-1) by ``amount_m`` (m, >= 0)."""
        rows = np.asarray(rows, dtype=np.intp)
        cols = np.asarray(cols, dtype=np.intp)
        amount_m = np.asarray(amount_m, dtype=np.float64)
        if not len(rows):
            return
        n_rows, n_cols = self._heights.shape
        if not (len(rows) == len(cols) == len(amount_m)):
            msg = f"{len(rows)} rows, {len(cols)} columns and {len(amount_m)} {what}s differ"
            raise ValueError(msg)
        if rows.min() < 0 or rows.max() >= n_rows or cols.min() < 0 or cols.max() >= n_cols:
            msg = (
                f"cells rows {int(rows.min())}..{int(rows.max())}, columns {int(cols.min())}.."
                f"{int(cols.max())} are not all within the {n_rows} x {n_cols} height map"
            )
            raise ValueError(msg)
        if not (np.all(np.isfinite(amount_m)) and amount_m.min() >= 0.0):
            bad = float(amount_m[~(np.isfinite(amount_m) & (amount_m >= 0.0))][0])
            msg = f"a {what} must be finite and >= 0 m, got {bad!r} m"
            raise ValueError(msg)
        floor = self.floor_m
        if sign < 0 and float((self._heights[rows, cols] - amount_m).min()) < floor:
            msg = f"a {what} of up to {float(amount_m.max())!r} m goes below the floor {floor} m"
            raise ValueError(msg)
        np.add.at(self._heights, (rows, cols), sign * amount_m)
        self._changed_rows += [int(rows.min()), int(rows.max())]
        self._changed_cols += [int(cols.min()), int(cols.max())]
        self._height_bound = max(self._height_bound, float(self._heights.max()) + 1e-9)

    def commit(self) -> bool:
        """Bring the simulator's surface up to date with the cuts since the last commit.

        Returns:
            Whether the terrain changed (then :attr:`version` was incremented).
        """
        rows, cols = self._changed_rows, self._changed_cols
        if not rows:
            return False
        self._surface.refresh(self._heights, (min(rows), max(rows)), (min(cols), max(cols)))
        self._changed_rows, self._changed_cols = [], []
        self.version += 1
        return True
