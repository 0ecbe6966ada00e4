"""What the terrain lost and holds: the regolith each carve update removed, cell by cell, with
its composition from the layer column, and the loose regolith lying in each cell.

The terrain is the simulation's height map (:class:`ow_description.terrain.HeightMap`): each cell
(r, c) is a column of area resolution^2 under its height sample. Per cell the ledger keeps

* the *original* height, from which the layer depths are measured;
* the *solid top*: the top of the intact column (the lowest the cell was ever cut to);
* the *loose* regolith lying in it (one well-mixed bulk): grinder cuttings, what a full scoop
  left behind, deposits;
* a copy of the simulation's height.

Loose regolith above the solid top is *drawn* when the height map shows it (a deposit raises the
height) and *undrawn* otherwise (the grinder's cut lowers the height map as OceanWATERS' does,
and its cuttings stay in the trench unseen). A cut lowering a cell below its solid top removes
the column between the two depths; a cut through drawn loose regolith removes none (it is loose
already, and undrawn from then on). A digging scoop collects a cell's undrawn loose regolith.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ow_description.terrain import HeightMap
from ow_regolith.errors import CarvingError
from ow_regolith.materials import UNIT_M3, UNITS_PER_M3, Bulk, LayerColumn, total

FloatArray = npt.NDArray[np.float64]
IndexArray = npt.NDArray[np.intp]
#: (row, column) of a height-map cell.
Cell = tuple[int, int]

#: m, a cut may leave a cell this much above its height before (float noise) without counting
#: as a raise.
RAISE_TOLERANCE = 1e-12


@dataclass(frozen=True)
class HeightChange:
    """Cells the simulation must raise (deposits) or lower (a column cut deeper by
    :meth:`CarvingLedger.deepen`), each by its amount.

    Attributes:
        rows: (k,) row of each cell.
        cols: (k,) column of each cell.
        raise_m: (k,) m, how much each cell rises (negative: falls).
    """

    rows: IndexArray
    cols: IndexArray
    raise_m: FloatArray

    @classmethod
    def none(cls) -> HeightChange:
        """No change."""
        empty = np.zeros(0, dtype=np.intp)
        return cls(empty, empty.copy(), np.zeros(0))

    def __bool__(self) -> bool:
        return bool(len(self.rows))

    def apply(self, heights: FloatArray) -> None:
        """Raise ``heights`` (rows, cols) m in place."""
        np.add.at(heights, (self.rows, self.cols), self.raise_m)


class CarvingLedger:
    """The regolith of one terrain, cell by cell.

    Args:
        heightmap: the terrain as made (its heights are the original surface).
        column: the layers under every cell.
    """

    def __init__(self, heightmap: HeightMap, column: LayerColumn) -> None:
        self.column = column
        self.resolution = heightmap.resolution
        self.origin = (heightmap.origin_x, heightmap.origin_y)
        #: m^2, the area of a cell.
        self.area_m2 = heightmap.resolution**2
        self._original = np.array(heightmap.heights, dtype=np.float64)
        self._solid_top = self._original.copy()
        self._heights = self._original.copy()
        self._loose: dict[Cell, Bulk] = {}
        #: Everything cut from the intact column so far.
        self.removed = Bulk()

    # ------------------------------------------------------------------ reading
    @property
    def shape(self) -> tuple[int, int]:
        """(rows, cols) of the terrain."""
        rows, cols = self._original.shape
        return int(rows), int(cols)

    @property
    def heightmap(self) -> HeightMap:
        """The terrain as the ledger knows it (the simulation's, after the cuts and deposits it
        was told of)."""
        return HeightMap(self._heights.copy(), self.resolution, *self.origin)

    def solid_top(self, cell: Cell) -> float:
        """m, base_link z of the top of the intact column of ``cell``."""
        return float(self._solid_top[cell])

    def loose(self, cell: Cell) -> Bulk:
        """The loose regolith in ``cell``."""
        return self._loose.get(cell, Bulk())

    def loose_total(self) -> Bulk:
        """All the loose regolith on the terrain."""
        return total(self._loose.values())

    def loose_top(self, cell: Cell) -> float:
        """m, base_link z of the top of ``cell``'s loose regolith heaped on its solid top."""
        return self.solid_top(cell) + self.loose(cell).units * UNIT_M3 / self.area_m2

    def undrawn_units(self, cell: Cell) -> int:
        """units of ``cell``'s loose regolith the height map does not show."""
        loose = self.loose(cell).units
        shown = (self._heights[cell] - self._solid_top[cell]) * self.area_m2 * UNITS_PER_M3
        return loose - min(max(round(shown), 0), loose)

    def cell_at(self, x: float, y: float) -> Cell | None:
        """The cell whose centre is nearest (x, y) (m, base_link), None beyond the grid."""
        rows, cols = self.shape
        col = round((x - self.origin[0]) / self.resolution)
        row = round((y - self.origin[1]) / self.resolution)
        return (row, col) if 0 <= row < rows and 0 <= col < cols else None

    # ------------------------------------------------------------------ changes
    def cut(
        self, before: FloatArray, after: FloatArray, offset: tuple[int, int] = (0, 0)
    ) -> dict[Cell, Bulk]:
        """A carve update lowered the terrain from ``before`` to ``after``: the intact column
        each cell lost.

        Args:
            before: (h, w) m, heights of a window of the terrain before the update.
            after: (h, w) m, the same after it.
            offset: (row, col) of the window's first cell in the terrain.

        Returns:
            cell -> the bulk cut from its intact column, for every lowered cell in row-major
            order (empty for a cell cut through loose regolith only).

        Raises:
            CarvingError: windows of different shapes or beyond the terrain, or a raised cell.
        """
        before = np.asarray(before, dtype=np.float64)
        after = np.asarray(after, dtype=np.float64)
        r0, c0 = offset
        rows, cols = self.shape
        if (
            before.shape != after.shape
            or before.ndim != 2
            or not (r0 >= 0 and r0 + before.shape[0] <= rows)
            or not (c0 >= 0 and c0 + before.shape[1] <= cols)
        ):
            msg = (
                f"a cut of {before.shape} -> {after.shape} cells at offset {offset} does not fit "
                f"the terrain of {self.shape} cells"
            )
            raise CarvingError(msg)
        raised = np.argwhere(after > before + RAISE_TOLERANCE)
        if len(raised):
            r, c = raised[0]
            msg = (
                f"a cut raised cell ({r + r0}, {c + c0}) from {before[r, c]:.6f} to "
                f"{after[r, c]:.6f} m; only deposits raise the terrain"
            )
            raise CarvingError(msg)
        removed: dict[Cell, Bulk] = {}
        for r, c in np.argwhere(after < before):
            cell = (int(r + r0), int(c + c0))
            height = float(after[r, c])
            self._heights[cell] = height
            solid = float(self._solid_top[cell])
            if height >= solid:
                removed[cell] = Bulk()  # through loose regolith only
                continue
            original = float(self._original[cell])
            bulk = self.column.bulk_between(original - solid, original - height, self.area_m2)
            self._solid_top[cell] = height
            self.removed += bulk
            removed[cell] = bulk
        return removed

    def add_loose(self, cell: Cell, bulk: Bulk) -> None:
        """Leave ``bulk`` lying loose, undrawn, in ``cell``."""
        if not bulk.is_empty:
            self._loose[cell] = self.loose(cell) + bulk

    def take_undrawn(self, cell: Cell, most_units: int) -> Bulk:
        """Take up to ``most_units`` (>= 0) of ``cell``'s undrawn loose regolith (a well-mixed
        share of its loose bulk)."""
        units = min(most_units, self.undrawn_units(cell))
        if units <= 0:
            return Bulk()
        taken, rest = self.loose(cell).take(units)
        if rest.is_empty:
            del self._loose[cell]
        else:
            self._loose[cell] = rest
        return taken

    def deepen(self, cell: Cell, units: int) -> tuple[Bulk, float]:
        """Cut ``cell``'s intact column ``units`` (>= 0) deeper: its solid top falls by that
        volume over the cell's area, and its height with it (the loose regolith the height map
        shows over the solid top follows it down).

        Returns:
            (the bulk cut from the column, m the cell fell). The bulk's volume is within a unit of
            ``units`` (the one rounding of a cut, :meth:`LayerColumn.bulk_between`).
        """
        if units <= 0:
            return Bulk(), 0.0
        fall = units * UNIT_M3 / self.area_m2
        original, solid = float(self._original[cell]), float(self._solid_top[cell])
        bottom = solid - fall
        bulk = self.column.bulk_between(original - solid, original - bottom, self.area_m2)
        self._solid_top[cell] = bottom
        self._heights[cell] -= fall
        self.removed += bulk
        return bulk, fall

    def deposit(self, x: float, y: float, bulk: Bulk, radius_m: float) -> HeightChange:
        """``bulk`` lands at (x, y) (m, base_link): spread evenly over the cells whose centres
        lie within ``radius_m`` of it (the nearest cell at least), raising each by its share.

        Returns:
            the raise the simulation must apply to its height map (empty beyond the grid, where
            nothing lands: check with :meth:`cell_at` first).
        """
        nearest = self.cell_at(x, y)
        if nearest is None or bulk.is_empty:
            return HeightChange.none()
        rows, cols = self.shape
        reach = int(np.ceil(radius_m / self.resolution))
        r_lo, r_hi = max(nearest[0] - reach, 0), min(nearest[0] + reach + 1, rows)
        c_lo, c_hi = max(nearest[1] - reach, 0), min(nearest[1] + reach + 1, cols)
        rr, cc = np.mgrid[r_lo:r_hi, c_lo:c_hi]
        dx = self.origin[0] + cc * self.resolution - x
        dy = self.origin[1] + rr * self.resolution - y
        inside = dx**2 + dy**2 <= radius_m**2
        cells = [(int(r), int(c)) for r, c in zip(rr[inside], cc[inside], strict=True)] or [nearest]
        parts = bulk.split(len(cells))
        raise_m = np.array([part.units * UNIT_M3 / self.area_m2 for part in parts])
        for cell, part, rise in zip(cells, parts, raise_m, strict=True):
            self.add_loose(cell, part)
            self._heights[cell] += rise
        return HeightChange(
            np.array([c[0] for c in cells], dtype=np.intp),
            np.array([c[1] for c in cells], dtype=np.intp),
            raise_m,
        )
