"""Regolith from trench to dock: the hooks a simulation calls, tying the terrain's ledger, the
scoop, the pour targets and the budget together.

At each carve update the simulation calls, in this order:

1. :meth:`RegolithTracker.scoop_moved` with the scoop's pose and whether it is in a dig phase. In
   a dig the scoop collects the undrawn loose regolith of the cells under its cutting edge (where
   the edge is below the top of that regolith) up to its capacity. Outside a dig the spill rule
   applies (:mod:`ow_regolith.scoop`): the excess pours from the mouth's lowest corner and lands
   (:mod:`ow_regolith.landing`) in the dock, on the lander (spilled), on the terrain (deposited:
   the returned :class:`~ow_regolith.carving_ledger.HeightChange` must be applied to the height
   map) or beyond it (spilled).
2. :meth:`RegolithTracker.terrain_cut` for each tool's cut, with the heights before and after it.
   A digging scoop takes each cut cell's undrawn loose regolith first, then what it cut from the
   cell's column, up to its capacity; what does not fit stays loose in the cell. Any other cut (the
   grinder's; a scoop outside a dig) leaves what it cut loose in the cell.

DockIngestSample calls :meth:`RegolithTracker.ingest`. When a dig phase begins the simulation calls
:meth:`RegolithTracker.start_dig`; when an outside model of the dig (the live DEM) says what the
scoop holds at its end, :meth:`RegolithTracker.set_dig_content` makes the dig's content that much,
and what the terrain's surface became, :meth:`RegolithTracker.reshape_terrain` moves the terrain's
material to it.
Cells are visited in row-major order and the budget changes only through its transfers, so runs
are deterministic and the budget exact.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ow_description.terrain import HeightMap
from ow_regolith.budget import Account, RegolithBudget
from ow_regolith.carving_ledger import CarvingLedger, Cell, HeightChange, TerrainMove
from ow_regolith.config import RegolithConfig
from ow_regolith.landing import Landing, PourTargets
from ow_regolith.materials import UNIT_M3, Bulk, LayerColumn, MaterialDatabase, apportion
from ow_regolith.scoop import ScoopGeometry

FloatArray = npt.NDArray[np.float64]

#: Where poured regolith is accounted, by where it lands.
LANDING_ACCOUNTS = {
    Landing.DOCK: Account.IN_DOCK,
    Landing.TERRAIN: Account.DEPOSITED,
    Landing.LANDER: Account.SPILLED,
    Landing.BEYOND_TERRAIN: Account.SPILLED,
}
#: Tool names (as the simulation's carver calls them) whose cuts can go into the scoop.
SCOOP_TOOL = "scoop"


@dataclass(frozen=True)
class DigContentChange:
    """What :meth:`RegolithTracker.set_dig_content` changed.

    Attributes:
        before_units: units the dig had put in the scoop (the geometric model's cut).
        after_units: units it holds now: those asked for, or fewer when the scoop is full.
        lowered: the cells whose column was cut deeper (negative ``raise_m``): the simulation
            must lower its height map so.
    """

    before_units: int
    after_units: int
    lowered: HeightChange

    def record(self) -> dict[str, float]:
        """The change in m^3 (``before_m3``, ``after_m3``), for reports."""
        return {"before_m3": self.before_units * UNIT_M3, "after_m3": self.after_units * UNIT_M3}


class RegolithTracker:
    """The regolith of one simulation: terrain ledger, scoop, dock and budget.

    Not thread-safe: the simulation thread calls every method.

    Args:
        config: the parameters.
        heightmap: the terrain as made.
        terrain: its specification (``europa:7``), which selects its layer column.
        scoop: the scoop's geometry (default: from the URDF, as ``config.scoop`` names it).
        targets: the dock and the lander's boxes (default: from the URDF).

    Raises:
        GeometryError: the URDF's scoop or dock shapes do not describe a container.
    """

    def __init__(
        self,
        config: RegolithConfig,
        heightmap: HeightMap,
        terrain: str,
        scoop: ScoopGeometry | None = None,
        targets: PourTargets | None = None,
    ) -> None:
        self.config = config
        self.database: MaterialDatabase = config.database
        self.scoop = scoop or ScoopGeometry.from_urdf(config.scoop)
        self.targets = targets or PourTargets.from_urdf(config.dock_link, config.catch_links)
        self.budget = RegolithBudget()
        self.ledger = CarvingLedger(heightmap, config.column_for(terrain))
        #: Where the last pour landed, None before any.
        self.last_landing: Landing | None = None
        #: What the scoop took in the dig under way (or the last one), and the cells its cut
        #: lowered or it collected from then.
        self._dig_taken = Bulk()
        self._dig_cells: set[Cell] = set()

    @property
    def column(self) -> LayerColumn:
        """The layer column of the present terrain."""
        return self.ledger.column

    @property
    def free_units(self) -> int:
        """units, what the scoop can still take in a dig."""
        return max(self.scoop.capacity_units - self.budget.in_scoop.units, 0)

    def set_terrain(self, heightmap: HeightMap, terrain: str) -> None:
        """A new terrain replaces the old one, with its trenches and loose regolith. The budget
        goes on: what was deposited on the old terrain stays counted as deposited."""
        self.ledger = CarvingLedger(heightmap, self.config.column_for(terrain))

    # ------------------------------------------------------------------ hooks
    def scoop_moved(self, X_base_scoop: FloatArray, digging: bool) -> HeightChange:
        """The scoop is at ``X_base_scoop`` (4, 4) in base_link: collect (``digging``) or spill.

        Returns:
            the raise of the terrain under regolith poured on it (empty otherwise).
        """
        if digging:
            self._collect_under_edge(X_base_scoop)
            return HeightChange.none()
        return self._spill(X_base_scoop)

    def terrain_cut(
        self,
        tool: str,
        before: FloatArray,
        after: FloatArray,
        scoop_digging: bool,
        offset: tuple[int, int] = (0, 0),
    ) -> None:
        """``tool`` lowered the terrain from ``before`` to ``after`` (a window at ``offset``,
        see :meth:`CarvingLedger.cut`); ``scoop_digging``: the scoop is in a dig phase.

        Raises:
            CarvingError: the heights do not fit the terrain, or a cell rose.
        """
        removed = self.ledger.cut(before, after, offset)
        into_scoop = tool == SCOOP_TOOL and scoop_digging
        for cell, bulk in removed.items():
            if into_scoop:
                self._dig_cells.add(cell)
                self._collect(cell)
                taken, bulk = bulk.take(min(self.free_units, bulk.units))
                self._excavate(cell, taken)
            self.ledger.add_loose(cell, bulk)

    def start_dig(self) -> None:
        """A dig phase begins: what the scoop takes from now on is this dig's (for
        :meth:`set_dig_content`)."""
        self._dig_taken = Bulk()
        self._dig_cells = set()

    def set_dig_content(self, units: int) -> DigContentChange:
        """The dig that has just ended holds ``units`` (>= 0): an outside model of the dig (the
        live DEM's sample) says so. What the scoop took since :meth:`start_dig` becomes that.

        * Fewer: the excess goes back to the ground, a well-mixed share of what the dig took,
          split evenly over the cells the dig cut or collected from (row-major), loose and
          undrawn (as what a full scoop leaves); ``excavated`` and ``in_scoop`` both fall by it.
        * More: the scoop takes the difference, up to its capacity, from those cells' undrawn
          loose regolith (row-major, as it collects), then from their columns, each cut evenly
          deeper (:meth:`CarvingLedger.deepen`; the height map must follow,
          :attr:`DigContentChange.lowered`). A dig that took from no cell takes nothing more.

        Call it when the dig phase has ended, before the scoop pours: it still holds what the
        dig took.

        Raises:
            BudgetError: the scoop no longer holds what the dig took (nothing changes).
        """
        before = self._dig_taken.units
        cells = sorted(self._dig_cells)
        lowered = HeightChange.none()
        if units < before:
            back, kept = self._dig_taken.take(before - units)
            self.budget.return_to_ground(back)
            self._dig_taken = kept
            for cell, part in zip(cells, back.split(len(cells)), strict=True):
                self.ledger.add_loose(cell, part)
        elif units > before and cells:
            need = min(units - before, self.free_units)
            for cell in cells:
                taken = self.ledger.take_undrawn(cell, need)
                self._excavate(cell, taken)
                need -= taken.units
            lowered = self._cut_deeper(cells, need)
        return DigContentChange(before, self._dig_taken.units, lowered)

    def reshape_terrain(
        self, cells: list[Cell], target_m: FloatArray, floor_m: float
    ) -> TerrainMove:
        """An outside model of a dig (the live DEM) says what the terrain's surface became:
        ``cells`` go to the heights ``target_m`` (m) as far as the material the falling ones give
        up allows, moved within the terrain (:meth:`CarvingLedger.reshape`); the budget does not
        change. The simulation must move its height map by the returned ``change``.

        Raises:
            CarvingError: a cell beyond the terrain or twice, or a bad target.
        """
        return self.ledger.reshape(cells, target_m, floor_m)

    def ingest(self) -> Bulk:
        """DockIngestSample: the dock's content is ingested. Returns it (empty: no sample)."""
        return self.budget.ingest()

    # ------------------------------------------------------------------ inside
    def _excavate(self, cell: Cell, bulk: Bulk) -> None:
        """The scoop takes ``bulk`` from ``cell`` in the dig under way."""
        self.budget.excavate(bulk)
        if not bulk.is_empty:
            self._dig_taken += bulk
            self._dig_cells.add(cell)

    def _collect(self, cell: Cell) -> None:
        """The scoop takes ``cell``'s undrawn loose regolith, as much as fits."""
        free = self.free_units
        if free:
            self._excavate(cell, self.ledger.take_undrawn(cell, free))

    def _cut_deeper(self, cells: list[Cell], units: int) -> HeightChange:
        """The scoop takes ``units`` more from the columns of ``cells``, split evenly, each cut
        a unit deeper than its share (so that the cut's rounding never leaves it short) and the
        surplus left loose in the cell; the cells' fall."""
        if units <= 0:
            return HeightChange.none()
        fallen: list[tuple[Cell, float]] = []
        for cell, share in zip(cells, apportion(units, [1] * len(cells)), strict=True):
            if not share:
                continue
            cut, fall = self.ledger.deepen(cell, share + 1)
            taken, rest = cut.take(min(share, cut.units))
            self._excavate(cell, taken)
            self.ledger.add_loose(cell, rest)
            fallen.append((cell, fall))
        return HeightChange(
            np.array([cell[0] for cell, _ in fallen], dtype=np.intp),
            np.array([cell[1] for cell, _ in fallen], dtype=np.intp),
            -np.array([fall for _, fall in fallen]),
        )

    def _collect_under_edge(self, X_base_scoop: FloatArray) -> None:
        cells: list[Cell] = []
        for x, y, z in self.scoop.blade_points(X_base_scoop):
            cell = self.ledger.cell_at(float(x), float(y))
            if cell is not None and cell not in cells and z <= self.ledger.loose_top(cell):
                cells.append(cell)
        for cell in sorted(cells):
            self._collect(cell)

    def _spill(self, X_base_scoop: FloatArray) -> HeightChange:
        content = self.budget.in_scoop
        if content.is_empty:
            return HeightChange.none()
        kept = self.scoop.retained_units(np.asarray(X_base_scoop)[:3, :3])
        if content.units <= kept:
            return HeightChange.none()
        poured, _ = content.take(content.units - kept)
        point = self.scoop.pour_point(X_base_scoop)
        landing = self.targets.landing(point, self.ledger.heightmap)
        self.last_landing = landing
        self.budget.pour(poured, LANDING_ACCOUNTS[landing])
        if landing is not Landing.TERRAIN:
            return HeightChange.none()
        return self.ledger.deposit(
            float(point[0]), float(point[1]), poured, self.config.deposit_radius
        )
