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

DockIngestSample calls :meth:`RegolithTracker.ingest`. Cells are visited in row-major order and the
budget changes only through its transfers, so runs are deterministic and the budget exact.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from ow_description.terrain import HeightMap
from ow_regolith.budget import Account, RegolithBudget
from ow_regolith.carving_ledger import CarvingLedger, Cell, HeightChange
from ow_regolith.config import RegolithConfig
from ow_regolith.landing import Landing, PourTargets
from ow_regolith.materials import Bulk, LayerColumn, MaterialDatabase
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
                self._collect(cell)
                taken, bulk = bulk.take(min(self.free_units, bulk.units))
                self.budget.excavate(taken)
            self.ledger.add_loose(cell, bulk)

    def ingest(self) -> Bulk:
        """DockIngestSample: the dock's content is ingested. Returns it (empty: no sample)."""
        return self.budget.ingest()

    # ------------------------------------------------------------------ inside
    def _collect(self, cell: Cell) -> None:
        """The scoop takes ``cell``'s undrawn loose regolith, as much as fits."""
        free = self.free_units
        if free:
            self.budget.excavate(self.ledger.take_undrawn(cell, free))

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
