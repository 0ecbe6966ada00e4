"""The interface between terrain-force models and the simulation (the contract of both packages).

The simulation builds a :class:`ToolState` for the scoop and for the grinder every physics step in
which the tool is below the terrain surface, asks a :class:`TerrainForceModel` for the wrench, and
applies it to the tool link. Lookup tables, the Balovnev model and the ROS bridge to an external
DEM all implement the same protocol.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]

#: Stateless models :func:`ow_dem_bridge.models.make_model` builds in-process (no ROS); the bridge
#: node serves these.
LOCAL_MODEL_NAMES: tuple[str, ...] = ("none", "table", "balovnev")
#: The live DEM (:mod:`ow_dem_bridge.live`): a YADE process in lockstep with the simulation. Also
#: built by ``make_model``, but it needs the simulation's clock, tool poses and terrain
#: (:class:`LockstepModel`), so only the simulation uses it.
LIVE_MODEL_NAME = "yade"
#: The co-simulation model: the latest wrench the bridge node published for the tool. It listens
#: on ROS topics, so the simulation node makes it (``remote_node.make_remote_model``).
REMOTE_MODEL_NAME = "bridge"
#: Every terrain-force model name (the simulation's ``~terrain_forces``).
MODEL_NAMES: tuple[str, ...] = (*LOCAL_MODEL_NAMES, LIVE_MODEL_NAME, REMOTE_MODEL_NAME)


@dataclass(frozen=True)
class ToolState:
    """What a terrain-force model may use about a tool in the ground.

    Attributes:
        tool: "scoop" or "grinder".
        material: material id of the terrain under the tool (table key m).
        depth: m, penetration of the tool tip below the terrain surface (>= 0).
        progress: m, path length the tool tip has travelled below the surface in this dig.
        velocity: (3,) m/s, tool tip velocity expressed in the tool link frame.
        angular_velocity: (3,) rad/s, tool link angular velocity in the tool link frame.
        time: s of simulation time at which the wrench will act (the start of the physics
            step), or None when the caller has no clock (the bridge node's messages).
        pose: (4, 4) pose of the tool link in base_link, or None when unknown.
        digging: the simulation's terrain gives way to the tool now (the scoop in a dig phase,
            the grinder grinding); None when unknown.
    """

    tool: str
    material: int
    depth: float
    progress: float
    velocity: FloatArray
    angular_velocity: FloatArray
    time: float | None = None
    pose: FloatArray | None = None
    digging: bool | None = None


@dataclass(frozen=True)
class Wrench:
    """Force and torque on a tool in the tool link frame, about the link's centre of mass.

    Attributes:
        force: (3,) N.
        torque: (3,) N m.
    """

    force: FloatArray
    torque: FloatArray


class TerrainForceModel(Protocol):
    """Anything that turns a tool state into the wrench the terrain exerts on the tool."""

    def wrench(self, state: ToolState) -> Wrench:
        """The terrain's wrench on the tool for ``state`` (zero when depth is 0)."""
        ...


class TerrainHeights(Protocol):
    """The simulation's terrain as a live model reads it (``ow_sim_bullet``'s carver is one)."""

    def height_at(self, x: float, y: float) -> float:
        """m, the terrain's height (base_link z) at (x, y) m in base_link, as carved now."""
        ...


#: The loose regolith on the terrain as a live model reads it: (x, y) m in base_link -> m, base_link
#: z of the top of the loose material (cuttings, spoil) heaped there on the solid terrain, which the
#: height map does not show (``ow_regolith``'s ledger: ``CarvingLedger.loose_top``); where there is
#: none, any height at or below the terrain's (``-inf`` beyond the terrain).
LooseTop = Callable[[float, float], float]


@runtime_checkable
class LockstepModel(TerrainForceModel, Protocol):
    """A model that runs beside the simulation (the live DEM): before its first wrench, the
    simulation gives it its terrain and its physics step; every ``wrench`` then covers exactly
    one physics step from ``state.time``, and the simulation waits for it.

    Such a model digs the material it holds, the loose layer included: the simulation asks it
    about the scoop in a dig phase wherever the tip is below :meth:`material_top`, also where its
    depth below the height map is 0 (in the grinder's cuttings, on the trench floor), and gives
    it that depth (``ToolState.depth``)."""

    def attach(
        self, terrain: TerrainHeights, step_s: float, loose_top: LooseTop | None = None
    ) -> None:
        """Called once by the simulation: its terrain (read when a dig starts), its physics step
        (s), the simulated time each ``wrench`` call advances, and its loose regolith (None:
        none; read when a dig starts)."""
        ...

    def material_top(self, x: float, y: float) -> float:
        """m, base_link z of the top of the material the model digs at (x, y) m (base_link):
        while a dig is under way its bed's as made (loose layer included), else the terrain's
        with its loose regolith now."""
        ...

    def dig_ended(self) -> dict[str, Any] | None:
        """Called by the simulation when the scoop's dig phase ends (it is not digging any more
        after a dig phase): the dig under way ends there, at the same simulated time in every
        run, and whatever it holds at its end is counted (the DEM: the spheres in the scoop).
        Returns that dig as :meth:`take_finished` will (its ``sample`` with
        ``sample_bulk_volume_m3``, m^3 of regolith in bulk), and besides ``surface``: what the
        dig did to the terrain's surface (``ow_dem_bridge.live_bed.DemSurface``, its
        ``change_at(x, y)`` m) or None; None when no dig was under way.

        Raises:
            DemRunError: the model failed while ending the dig.
        """
        ...

    def take_finished(self) -> list[dict[str, Any]]:
        """The digs that ended or failed since the last call, oldest first, each as
        ``LiveDig.summary()`` (``start_time``, ``exchanges``, ``particles``,
        ``loose_particles``, ``sample`` (None when it failed), ``error`` (None when it did
        not), ...); the simulation publishes them."""
        ...

    def close(self) -> None:
        """Stop whatever runs beside the simulation (idempotent)."""
        ...
