"""The interface between terrain-force models and the simulation (the contract of both packages).

The simulation builds a :class:`ToolState` for the scoop and for the grinder every physics step in
which the tool is below the terrain surface, asks a :class:`TerrainForceModel` for the wrench, and
applies it to the tool link. Lookup tables, the Balovnev model and the ROS bridge to an external
DEM all implement the same protocol.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]

#: Models :func:`ow_dem_bridge.models.make_model` builds in-process (no ROS).
LOCAL_MODEL_NAMES: tuple[str, ...] = ("none", "table", "balovnev")
#: The co-simulation model: the latest wrench the bridge node published for the tool. It listens
#: on ROS topics, so the simulation node makes it (``remote_node.make_remote_model``).
REMOTE_MODEL_NAME = "bridge"
#: Every terrain-force model name (the simulation's ``~terrain_forces``).
MODEL_NAMES: tuple[str, ...] = (*LOCAL_MODEL_NAMES, REMOTE_MODEL_NAME)


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
    """

    tool: str
    material: int
    depth: float
    progress: float
    velocity: FloatArray
    angular_velocity: FloatArray


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
