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

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ow_description.terrain import HeightMap
from ow_regolith.errors import CarvingError
from ow_regolith.materials import UNIT_M3, UNITS_PER_M3, Bulk, LayerColumn, apportion, total

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


@dataclass(frozen=True)
class TerrainMove:
    """What :meth:`CarvingLedger.reshape` moved within the terrain.

    Attributes:
        change: every cell whose height changed, by how much (m; negative: it fell).
        shown_units: undrawn loose regolith the rising cells now show (it lay there unseen).
        moved_units: units taken from the falling cells (their drawn loose regolith and column).
        raised_units: of those, the units laid on the rising cells; the rest lies loose, undrawn,
            in the fallen cells.
    """

    change: HeightChange
    shown_units: int
    moved_units: int
    raised_units: int

    def record(self) -> dict[str, float]:
        """For reports: ``cells`` changed, m^3 ``shown_m3``, ``moved_m3`` and ``raised_m3``,
        the ``largest_m`` change of a cell's height (m, absolute)."""
        raise_m = self.change.raise_m
        return {
            "cells": len(raise_m),
            "shown_m3": self.shown_units * UNIT_M3,
            "moved_m3": self.moved_units * UNIT_M3,
            "raised_m3": self.raised_units * UNIT_M3,
            "largest_m": float(np.abs(raise_m).max()) if len(raise_m) else 0.0,
        }


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
            removed[cell] = self._cut_column(cell, height)
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
        bulk = self._cut_column(cell, float(self._solid_top[cell]) - fall)
        self._heights[cell] -= fall
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

    def reshape(self, cells: Sequence[Cell], target_m: FloatArray, floor_m: float) -> TerrainMove:
        """Bring ``cells`` to the heights ``target_m`` (m, base_link z), moving material within
        the terrain only (nothing is excavated or deposited: the budget is not concerned).

        Cells are taken in row-major order. A cell above its target (raised to ``floor_m`` at
        least) falls to it: the loose regolith its height shows above the target, then its column
        down to the target (composition by layer, as any cut), go into a pool. A cell below its
        target rises: first by showing its own undrawn loose regolith (no material moves), then
        by what it receives from the pool as loose, drawn regolith: the rest of its shortfall in
        units, all of them scaled down alike (:func:`apportion`) when the pool holds less.
        What the pool keeps is split evenly over the fallen cells, loose and undrawn. The
        terrain's own account (cut from the column = :attr:`removed`, loose) stays exact.

        Args:
            cells: distinct cells of the terrain.
            target_m: (len(cells),) m, each cell's target height.
            floor_m: m, no cell falls below this.

        Returns:
            What moved; the simulation must move its height map by ``change``.

        Raises:
            CarvingError: a cell beyond the terrain or twice, a target count that differs, or a
                non-finite target.
        """
        target_m = np.asarray(target_m, dtype=np.float64)
        rows, cols = self.shape
        if len(target_m) != len(cells) or not np.all(np.isfinite(target_m)):
            msg = f"{len(cells)} cells need as many finite target heights, got {target_m!r}"
            raise CarvingError(msg)
        if len(set(cells)) != len(cells) or any(
            not (0 <= r < rows and 0 <= c < cols) for r, c in cells
        ):
            msg = f"cells to reshape must be distinct and within the {rows} x {cols} terrain"
            raise CarvingError(msg)
        order = sorted(range(len(cells)), key=lambda k: cells[k])
        before = {cells[k]: float(self._heights[cells[k]]) for k in order}
        pool = Bulk()
        shown = 0
        fallen: list[Cell] = []
        rising: list[tuple[Cell, int]] = []
        for k in order:
            cell = cells[k]
            height, target = before[cell], max(float(target_m[k]), floor_m)
            if target < height:
                pool += self._fall(cell, target)
                fallen.append(cell)
            elif target > height:
                short = round((target - height) * self.area_m2 * UNITS_PER_M3)
                show = min(max(short, 0), self.undrawn_units(cell))
                self._heights[cell] += show * UNIT_M3 / self.area_m2
                shown += show
                if short > show:
                    rising.append((cell, short - show))
        moved = pool.units
        needs = [short for _, short in rising]
        if sum(needs) > pool.units:
            needs = apportion(pool.units, needs)
        for (cell, _), units in zip(rising, needs, strict=True):
            part, pool = pool.take(units)
            self.add_loose(cell, part)
            self._heights[cell] += part.units * UNIT_M3 / self.area_m2
        raised = moved - pool.units
        if not pool.is_empty:
            for cell, part in zip(fallen, pool.split(len(fallen)), strict=True):
                self.add_loose(cell, part)
        changed = [cell for cell in before if self._heights[cell] != before[cell]]
        return TerrainMove(
            HeightChange(
                np.array([c[0] for c in changed], dtype=np.intp),
                np.array([c[1] for c in changed], dtype=np.intp),
                np.array([self._heights[c] - before[c] for c in changed]),
            ),
            shown,
            moved,
            raised,
        )

    def _cut_column(self, cell: Cell, bottom: float) -> Bulk:
        """Cut ``cell``'s intact column down to ``bottom`` m (below its solid top): the bulk cut,
        by layer (:meth:`LayerColumn.bulk_between`), counted in :attr:`removed`."""
        original, solid = float(self._original[cell]), float(self._solid_top[cell])
        bulk = self.column.bulk_between(original - solid, original - bottom, self.area_m2)
        self._solid_top[cell] = bottom
        self.removed += bulk
        return bulk

    def _fall(self, cell: Cell, target: float) -> Bulk:
        """Lower ``cell`` to ``target`` m (below its height): the loose regolith its height
        shows above the target, then its column down to the target; what it lost."""
        height, solid = float(self._heights[cell]), float(self._solid_top[cell])
        drawn = self.loose(cell).units - self.undrawn_units(cell)
        shown = round((height - max(target, solid)) * self.area_m2 * UNITS_PER_M3)
        taken, rest = self.loose(cell).take(min(max(shown, 0), drawn))
        if rest.is_empty:
            self._loose.pop(cell, None)
        else:
            self._loose[cell] = rest
        if target < solid:
            taken += self._cut_column(cell, target)
        self._heights[cell] = target
        return taken
