"""What the simulation does when a live DEM dig ends (:class:`LiveDemDigEnds`): the scoop's
content for the dig becomes the DEM's sample, and the terrain takes the DEM's surface: the
height-map cells on the footprint of the DEM's surface grid go towards their target heights (the
height the cell had when the dig phase began plus the DEM's change there,
:func:`dem_surface_targets`) through
:meth:`~ow_sim_bullet.regolith.SimRegolith.reshape_terrain`, which moves the terrain's material,
and the height map follows by what moved. No pybullet, no ROS.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Callable
from typing import Any

import numpy as np
import numpy.typing as npt

from ow_dem_bridge.api import LockstepModel
from ow_dem_bridge.errors import DemRunError
from ow_dem_bridge.live_bed import DemSurface
from ow_description.terrain import HeightMap
from ow_regolith.carving_ledger import Cell
from ow_sim_bullet.carving import TerrainCarver
from ow_sim_bullet.regolith import SimRegolith

FloatArray = npt.NDArray[np.float64]
#: m, how far above the carver's floor the DEM's surface may lower the terrain.
FLOOR_GUARD = 1e-6


class LiveDemDigEnds:
    """The live DEM's digs as the simulation ends them, at its carve updates.

    Not thread-safe: the simulation thread calls every method.

    Args:
        live: the live terrain-force model.
        regolith: the simulation's regolith (the scoop's content, the terrain's material).
        carver: the simulation's height map.
        scoop_box: gives the scoop link's bounding box in base_link now, (low, high) (3,) m.
    """

    def __init__(
        self,
        live: LockstepModel,
        regolith: SimRegolith,
        carver: TerrainCarver,
        scoop_box: Callable[[], tuple[FloatArray, FloatArray]],
    ) -> None:
        self.live = live
        self.regolith = regolith
        self.carver = carver
        self.scoop_box = scoop_box
        #: m, the height map when the scoop's dig phase began (the DEM's surface change is
        #: applied to it when the dig ends), None before any.
        self._start_heights: FloatArray | None = None

    def dig_started(self) -> None:
        """The scoop's dig phase has begun: the terrain now is what the DEM's change applies to."""
        self._start_heights = self.carver.heightmap.heights

    def terrain_replaced(self) -> None:
        """A new terrain: no dig phase's start heights apply to it."""
        self._start_heights = None

    def update(self, dig_phase_ended: bool) -> list[dict[str, Any]]:
        """At a carve update: end the DEM's dig when the dig phase has just ended (the scoop's
        content for that dig becomes the DEM's sample, :meth:`_take_sample`, and the terrain
        takes the DEM's surface, :meth:`_take_surface`); the summaries of every dig the model
        finished since the last update, oldest first, the one ended here with what it changed
        (``regolith``, ``terrain``)."""
        ended = None
        if dig_phase_ended:
            # A failure is logged and reported by the model; the forces were applied, and the
            # scoop keeps the geometric model's content, the terrain its carving.
            with contextlib.suppress(DemRunError):
                ended = self.live.dig_ended()
        records: dict[str, Any] = {}
        if ended:
            change = self._take_sample(ended)
            if change is not None:
                records["regolith"] = change
                terrain = self._take_surface(ended.get("surface"))
                if terrain is not None:
                    records["terrain"] = terrain
        digs = []
        for summary in self.live.take_finished():
            if records and ended and summary["start_time"] == ended["start_time"]:
                summary = {**summary, **records}
            digs.append(summary)
        return digs

    def _take_sample(self, dig: dict[str, Any]) -> dict[str, float] | None:
        """The scoop's content for the dig that just ended becomes the live DEM's sample, in
        bulk (:meth:`SimRegolith.set_dig_content`); a column the scoop had to cut deeper for it
        is lowered in the height map. What changed (m^3 before and after), None without a
        sample."""
        sample = dig.get("sample")
        if not sample:
            return None
        change = self.regolith.set_dig_content(float(sample["sample_bulk_volume_m3"]))
        lowered = change.lowered
        if lowered:
            self.carver.lower_cells(lowered.rows, lowered.cols, -lowered.raise_m)
        return change.record()

    def _take_surface(self, surface: DemSurface | None) -> dict[str, float] | None:
        """The terrain on the footprint of the DEM's surface grid goes to its height when the dig
        phase began plus the DEM's change there (:func:`dem_surface_targets`), as far as the
        material the falling cells give up allows, moved within the terrain
        (:meth:`SimRegolith.reshape_terrain`: the budget does not change); the height map
        follows. What moved (``TerrainMove.record``), None without a surface."""
        start = self._start_heights
        heightmap = self.carver.heightmap
        if surface is None or start is None or start.shape != heightmap.heights.shape:
            return None
        cells, targets = dem_surface_targets(heightmap, start, surface, self.scoop_box())
        # A hair above the carver's floor: its own check must not see float noise below it.
        move = self.regolith.reshape_terrain(cells, targets, self.carver.floor_m + FLOOR_GUARD)
        rows, cols, shift = move.change.rows, move.change.cols, move.change.raise_m
        fall = shift < 0
        self.carver.lower_cells(rows[fall], cols[fall], -shift[fall])
        self.carver.raise_cells(rows[~fall], cols[~fall], shift[~fall])
        return move.record()


def dem_surface_targets(
    heightmap: HeightMap,
    start_heights: FloatArray,
    surface: DemSurface,
    scoop_box: tuple[FloatArray, FloatArray],
) -> tuple[list[Cell], FloatArray]:
    """The cells whose centres lie on ``surface``'s footprint, row-major, and their targets.

    Args:
        heightmap: the terrain now.
        start_heights: (rows, cols) m, its heights when the dig phase began.
        surface: what the DEM's dig did to its bed's surface.
        scoop_box: (low, high) (3,) m, the scoop's bounding box in base_link: a cell under it
            (within a cell of its outline) rises no higher than its lowest point, so the terrain
            never closes over a scoop leaving it.

    Returns:
        (cells, (k,) m targets): ``start_heights + surface.change_at(centre)``.
    """
    res, ox, oy = heightmap.resolution, heightmap.origin_x, heightmap.origin_y
    rows, cols = heightmap.heights.shape
    centres = surface.centres().reshape(-1, 2)
    reach = max(surface.cell_u, surface.cell_v)  # the footprint's edge beyond the centres
    (x_lo, y_lo), (x_hi, y_hi) = centres.min(axis=0) - reach, centres.max(axis=0) + reach
    c_lo, c_hi = max(math.floor((x_lo - ox) / res), 0), min(math.ceil((x_hi - ox) / res), cols - 1)
    r_lo, r_hi = max(math.floor((y_lo - oy) / res), 0), min(math.ceil((y_hi - oy) / res), rows - 1)
    if c_lo > c_hi or r_lo > r_hi:
        return [], np.zeros(0)
    rr, cc = np.mgrid[r_lo : r_hi + 1, c_lo : c_hi + 1]
    x, y = ox + cc * res, oy + rr * res
    inside = surface.covers(x, y)
    target = start_heights[rr, cc] + surface.change_at(x, y)
    low, high = np.asarray(scoop_box[0]), np.asarray(scoop_box[1])
    under = (x >= low[0] - res) & (x <= high[0] + res) & (y >= low[1] - res) & (y <= high[1] + res)
    present = heightmap.heights[rr, cc]
    target = np.where(under, np.minimum(target, np.maximum(present, low[2])), target)
    cells = [(int(r), int(c)) for r, c in zip(rr[inside], cc[inside], strict=True)]
    return cells, target[inside]
