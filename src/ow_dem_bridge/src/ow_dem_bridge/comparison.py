"""Terrain-force models against a reference series: the seed paper's Table 6 metric.

The normalized RMS deviation of a model's force component from the reference's over a dig,
``RMS(model - reference) / (max(reference) - min(reference))``, with the live DEM as the
reference (``bench/cosim.py`` and the mission report, :mod:`ow_mission.live_dem_report`, both use
it). No ROS.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import numpy.typing as npt

from ow_dem_bridge.api import FloatArray, TerrainForceModel, ToolState

#: The compared force components (tool link frame), the columns 0-2 of a wrench row.
COMPONENTS: tuple[str, ...] = ("Fx", "Fy", "Fz")


def nrmsd(model: npt.ArrayLike, reference: npt.ArrayLike) -> float:
    """RMS(model - reference) / (max(reference) - min(reference)), over two series of the same
    length (N); NaN when the reference does not vary (or is empty).

    Raises:
        ValueError: the series differ in length.
    """
    m = np.asarray(model, dtype=np.float64)
    r = np.asarray(reference, dtype=np.float64)
    if m.shape != r.shape:
        msg = f"a model series of {m.shape} values against a reference of {r.shape}"
        raise ValueError(msg)
    if r.size == 0:
        return float("nan")
    spread = float(r.max() - r.min())
    rms = float(np.sqrt(np.mean((m - r) ** 2)))
    return rms / spread if spread > 0 else float("nan")


def model_wrenches(model: TerrainForceModel, states: Sequence[ToolState]) -> FloatArray:
    """(N, 6) the wrench rows (Fx, Fy, Fz N, Tx, Ty, Tz N m) ``model`` gives for ``states``."""
    rows = []
    for state in states:
        wrench = model.wrench(state)
        rows.append([*map(float, wrench.force), *map(float, wrench.torque)])
    return np.asarray(rows, dtype=np.float64).reshape(len(rows), 6)


def compare_forces(
    reference: npt.ArrayLike, others: Mapping[str, npt.ArrayLike]
) -> dict[str, dict[str, float]]:
    """For each model of ``others`` ((N, >=3) wrench rows, like ``reference``'s), the NRMSD of each
    force component (:data:`COMPONENTS`) against ``reference``: {model: {"Fx": ..., ...}}."""
    ref = np.asarray(reference, dtype=np.float64)
    result: dict[str, dict[str, float]] = {}
    for name, rows in others.items():
        series = np.asarray(rows, dtype=np.float64)
        result[name] = {
            component: nrmsd(series[:, k], ref[:, k]) for k, component in enumerate(COMPONENTS)
        }
    return result
