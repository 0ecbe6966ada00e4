"""Terrain-force models behind one factory, :func:`make_model`, for the simulation and the bridge.

Names and parameters (``params`` keys; units in the docs of each model):

* ``"none"``: no terrain force.
* ``"table"``: lookup table (:mod:`ow_dem_bridge.table`). ``path`` (CSV; default: the shipped
  YADE table), ``material`` (int; forces one material id instead of the state's, as the original
  plugin always used m=1; 0 or absent: use the state's), ``pass_number`` and ``table_tool`` (for
  OceanWATERS-format tables: which pass, which tool they describe; defaults 1 and "scoop").
* ``"balovnev"``: analytic model for the scoop (:mod:`ow_dem_bridge.balovnev`); any
  :class:`~ow_dem_bridge.balovnev.BalovnevParams` field as a key, plus ``grinder_table`` (CSV used
  for the grinder; default the shipped table; "" for no grinder force).

* ``"yade"``: the live DEM (:mod:`ow_dem_bridge.live`), a YADE process in lockstep with the
  simulation for the scoop's digs; every :class:`~ow_dem_bridge.live_config.LiveConfig` field as
  a key, ``fallback`` and ``fallback_params`` the model for everything else (default the table).
  Only the simulation can drive it (it calls ``attach`` with its terrain and step).

The last name, ``"bridge"`` (the co-simulation path: the latest wrench the bridge node published
for the tool), listens on ROS topics; the simulation node makes it with
:func:`ow_dem_bridge.remote_node.make_remote_model`, and :func:`make_model` refuses it.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from ow_dem_bridge.api import (
    LIVE_MODEL_NAME,
    MODEL_NAMES,
    REMOTE_MODEL_NAME,
    FloatArray,
    TerrainForceModel,
    ToolState,
    Wrench,
)
from ow_dem_bridge.balovnev import BalovnevModel, BalovnevParams
from ow_dem_bridge.errors import ConfigError
from ow_dem_bridge.live import LiveDemModel
from ow_dem_bridge.live_config import LiveConfig
from ow_dem_bridge.table import ForceTable, load_table

#: The table shipped with the package (made by ``make dem-tables``).
DEFAULT_TABLE_PATH = Path(__file__).resolve().parents[2] / "data" / "default_table.csv"
#: m/s, below this lateral speed the grinder's lateral table forces fade out (direction unknown).
GRINDER_MIN_LATERAL_SPEED = 1e-3
#: m, l_grinder centre of mass in its link frame (the URDF's), the torque reference point.
GRINDER_COM = (0.0, 0.0, 0.06)


class ZeroModel:
    """No terrain force at all."""

    def wrench(self, state: ToolState) -> Wrench:
        """A zero wrench."""
        return Wrench(np.zeros(3), np.zeros(3))


class TableModel:
    """Wrench from a force table.

    Scoop rows are in the ``l_scoop`` frame for a dig along the scoop's +x (cutting edge first),
    as every dig motion moves it. The grinder is axisymmetric about its link x axis; its rows are
    for a drag along link +y, so the model turns their lateral part (Fy, Fz and the torque) about
    the axis to the actual lateral velocity, fading it out below 1 mm/s.

    Args:
        table: the table.
        material: material id to use for every query (None: the state's).
        grinder_com: (3,) m, grinder COM in its link frame (the table's torque reference).
    """

    def __init__(
        self,
        table: ForceTable,
        material: int | None = None,
        grinder_com: tuple[float, float, float] = GRINDER_COM,
    ) -> None:
        self.table = table
        self.material = material
        self._grinder_com = np.asarray(grinder_com, dtype=np.float64)

    def wrench(self, state: ToolState) -> Wrench:
        """The interpolated wrench; zero above the surface.

        Raises:
            QueryError: the table has no data for the state's tool and material.
        """
        if state.depth <= 0.0:
            return Wrench(np.zeros(3), np.zeros(3))
        material = state.material if self.material is None else self.material
        w = self.table.lookup(state.tool, material, state.depth, state.progress)
        if state.tool == "grinder":
            return self._orient_grinder(w, np.asarray(state.velocity, dtype=np.float64))
        return Wrench(w[:3], w[3:])

    def _orient_grinder(self, w: FloatArray, velocity: FloatArray) -> Wrench:
        force, torque = w[:3], w[3:]
        com = self._grinder_com
        torque_axis = torque + np.cross(com, force)  # about the link origin, on the axis
        lateral = math.hypot(velocity[1], velocity[2])
        angle = math.atan2(velocity[2], velocity[1]) if lateral > 0 else 0.0
        fade = min(1.0, lateral / GRINDER_MIN_LATERAL_SPEED)
        c, s = math.cos(angle), math.sin(angle)
        turn = np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])
        keep = np.array([1.0, fade, fade])
        force_out = turn @ (force * keep)
        torque_out = turn @ (torque_axis * np.array([fade, fade, fade]))
        return Wrench(force_out, torque_out - np.cross(com, force_out))


def _table_from(params: Mapping[str, Any], key: str, default: Path) -> ForceTable:
    path = params.get(key, "") or default
    tool = params.get("table_tool", "scoop")
    pass_number = params.get("pass_number", 1)
    if not isinstance(pass_number, int) or isinstance(pass_number, bool):
        msg = f"model parameter 'pass_number' must be an integer, got {pass_number!r}"
        raise ConfigError(msg)
    return load_table(Path(str(path)), tool=str(tool), pass_number=pass_number)


def make_model(name: str, params: Mapping[str, Any] | None = None) -> TerrainForceModel:
    """Build a terrain-force model by name (see the module docstring).

    Args:
        name: "none", "table", "balovnev" or "yade".
        params: the model's parameters.

    Returns:
        A model with ``wrench(state) -> Wrench``.

    Raises:
        ConfigError: unknown name, the ROS-backed "bridge" model, or a bad parameter.
        TableError: a table cannot be loaded.
        DemRunError: "yade" without YADE installed (the message names the Debian package).
    """
    params = dict(params or {})
    if name == "none":
        return ZeroModel()
    if name == "table":
        unknown = set(params) - {"path", "material", "pass_number", "table_tool"}
        if unknown:
            msg = f"unknown 'table' model parameter(s): {', '.join(sorted(unknown))}"
            raise ConfigError(msg)
        material = params.get("material") or None
        if material is not None and (not isinstance(material, int) or isinstance(material, bool)):
            msg = f"model parameter 'material' must be an integer id, got {material!r}"
            raise ConfigError(msg)
        return TableModel(_table_from(params, "path", DEFAULT_TABLE_PATH), material)
    if name == "balovnev":
        grinder_path = params.pop("grinder_table", None)
        grinder: TerrainForceModel | None = None
        if grinder_path != "":
            table = _table_from({"path": grinder_path or ""}, "path", DEFAULT_TABLE_PATH)
            grinder = TableModel(table)
        return BalovnevModel(BalovnevParams.from_dict(params), grinder)
    if name == LIVE_MODEL_NAME:
        config = LiveConfig.from_dict(params)
        return LiveDemModel(config, make_model(config.fallback, config.fallback_params))
    if name == REMOTE_MODEL_NAME:
        msg = (
            f"terrain-force model {name!r} listens on ROS topics: the simulation node creates it "
            "(ow_dem_bridge.remote_node.make_remote_model), make_model does not"
        )
        raise ConfigError(msg)
    msg = f"unknown terrain-force model {name!r}; choose one of {', '.join(MODEL_NAMES)}"
    raise ConfigError(msg)
