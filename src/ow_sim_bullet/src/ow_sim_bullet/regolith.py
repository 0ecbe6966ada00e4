"""The simulation's regolith: :class:`ow_regolith.tracker.RegolithTracker` told of the scoop and
of every cut at each carve update, and the version of its budget the node publishes on change.

:meth:`BulletSim._carve <ow_sim_bullet.sim_core.BulletSim>` calls, once per carve update and in
this order, :meth:`SimRegolith.scoop_moved` (only while the scoop digs or holds regolith: nothing
else can change then) and :meth:`SimRegolith.terrain_cut` for each tool's cut
(:class:`~ow_sim_bullet.carving.CutWindow`). When the scoop's dig phase begins it calls
:meth:`SimRegolith.start_dig`; when a live DEM dig ends with a sample,
:meth:`SimRegolith.set_dig_content` makes the dig's content the sample's bulk volume and
:meth:`SimRegolith.reshape_terrain` moves the terrain to the DEM's surface. The model
and its budget: docs/regolith.md. No pybullet, no ROS.
"""

from __future__ import annotations

import functools

import numpy as np
import numpy.typing as npt

from ow_description.terrain import HeightMap
from ow_regolith.budget import BudgetSnapshot
from ow_regolith.carving_ledger import Cell, HeightChange, TerrainMove
from ow_regolith.config import RegolithConfig
from ow_regolith.landing import PourTargets
from ow_regolith.materials import Bulk, LayerColumn, MaterialDatabase, units_from_m3
from ow_regolith.scoop import ScoopGeometry, ScoopShapes
from ow_regolith.tracker import DigContentChange, RegolithTracker
from ow_sim_bullet.carving import CutWindow

FloatArray = npt.NDArray[np.float64]


@functools.lru_cache(maxsize=4)
def scoop_geometry(shapes: ScoopShapes) -> ScoopGeometry:
    """The scoop's cavity from the URDF (read once per process: 0.1 s)."""
    return ScoopGeometry.from_urdf(shapes)


@functools.lru_cache(maxsize=4)
def pour_targets(dock_link: str, catch_links: tuple[str, ...]) -> PourTargets:
    """The dock and the lander's boxes from the URDF (read once per process: 0.1 s)."""
    return PourTargets.from_urdf(dock_link, catch_links)


class SimRegolith:
    """The regolith of one simulation: what the tools cut, what the scoop holds and pours, the
    dock, and the budget.

    Not thread-safe: the simulation thread calls every method.

    Args:
        config: the regolith parameters (``regolith`` of the simulation's).
        heightmap: the terrain as made.
        terrain: its specification (``europa:7``; selects its layer column).

    Raises:
        GeometryError: the URDF's scoop or dock shapes do not describe a container.
    """

    def __init__(self, config: RegolithConfig, heightmap: HeightMap, terrain: str) -> None:
        self.config = config
        self.tracker = RegolithTracker(
            config,
            heightmap,
            terrain,
            scoop_geometry(config.scoop),
            pour_targets(config.dock_link, config.catch_links),
        )
        #: incremented whenever an account of the budget changes.
        self.version = 0
        self._accounts = self.tracker.budget.snapshot().accounts

    @property
    def database(self) -> MaterialDatabase:
        """The materials."""
        return self.tracker.database

    @property
    def column(self) -> LayerColumn:
        """The layer column of the present terrain."""
        return self.tracker.column

    def snapshot(self) -> BudgetSnapshot:
        """The budget's accounts now."""
        return self.tracker.budget.snapshot()

    def scoop_active(self, digging: bool) -> bool:
        """Whether :meth:`scoop_moved` can change anything: the scoop digs or holds regolith."""
        return digging or not self.tracker.budget.in_scoop.is_empty

    # ------------------------------------------------------------------ hooks
    def scoop_moved(self, X_base_scoop: FloatArray, digging: bool) -> HeightChange:
        """The scoop link is at ``X_base_scoop`` (4, 4) in base_link: it collects (``digging``)
        or spills (:meth:`RegolithTracker.scoop_moved`).

        Returns:
            The raise of the terrain under regolith poured on it, for the height map.
        """
        change = self.tracker.scoop_moved(X_base_scoop, digging)
        self._note_change()
        return change

    def terrain_cut(self, tool: str, cut: CutWindow, scoop_digging: bool) -> None:
        """``tool`` lowered the terrain as ``cut`` says; ``scoop_digging``: the scoop is in a dig
        phase (:meth:`RegolithTracker.terrain_cut`).

        Raises:
            CarvingError: the window does not fit the terrain, or a cell rose.
        """
        self.tracker.terrain_cut(tool, cut.before, cut.after, scoop_digging, cut.offset)
        self._note_change()

    def start_dig(self) -> None:
        """The scoop's dig phase begins (:meth:`RegolithTracker.start_dig`)."""
        self.tracker.start_dig()

    def set_dig_content(self, volume_m3: float) -> DigContentChange:
        """The dig that has just ended holds ``volume_m3`` (m^3 of regolith in bulk, >= 0): what
        the scoop took in it becomes that, to the unit, within its capacity
        (:meth:`RegolithTracker.set_dig_content`). The caller applies the returned change's
        ``lowered`` to its height map.

        Raises:
            MaterialError: a negative or non-finite volume.
            BudgetError: the scoop no longer holds what the dig took (nothing changes).
        """
        change = self.tracker.set_dig_content(units_from_m3(volume_m3))
        self._note_change()
        return change

    def reshape_terrain(
        self, cells: list[Cell], target_m: FloatArray, floor_m: float
    ) -> TerrainMove:
        """Move the terrain's material within it towards the heights ``target_m`` (m) of
        ``cells``, none below ``floor_m`` (:meth:`RegolithTracker.reshape_terrain`); the budget
        does not change. The caller moves its height map by the returned ``change``.

        Raises:
            CarvingError: a cell beyond the terrain or twice, or a bad target.
        """
        return self.tracker.reshape_terrain(cells, target_m, floor_m)

    def ingest(self) -> Bulk:
        """DockIngestSample: the dock's content is ingested. Returns it (empty: no sample)."""
        bulk = self.tracker.ingest()
        self._note_change()
        return bulk

    def set_terrain(self, heightmap: HeightMap, terrain: str) -> None:
        """A new terrain, with its own column and no loose regolith; the budget goes on."""
        self.tracker.set_terrain(heightmap, terrain)
        self.version += 1  # the column, and so the budget's layers, may have changed

    def _note_change(self) -> None:
        accounts = self.tracker.budget.snapshot().accounts
        if accounts != self._accounts:
            self._accounts = accounts
            self.version += 1
