"""What the viz node draws, as numpy arrays (no ROS): the terrain mesh and the planned tool path.

Frames: everything is in ``base_link`` (REP 103: x forward, z up, m).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ow_description.errors import ModelError
from ow_description.model import LanderModel
from ow_description.terrain import HeightMap
from ow_description.trajectory import Spline
from ow_viz.errors import SceneError

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

#: RGBA of the lowest and highest terrain (an ice palette: dark blue-grey to pale blue), chosen
#: apart from every URDF material so that the lander and the terrain are told apart in a picture.
TERRAIN_LOW_RGBA = (0.16, 0.26, 0.46, 1.0)
TERRAIN_HIGH_RGBA = (0.62, 0.80, 0.95, 1.0)


@dataclass(frozen=True)
class TerrainMesh:
    """A triangulated height map.

    Attributes:
        vertices: (N, 3) m, vertex positions in base_link.
        triangles: (M, 3) vertex indices, counter-clockwise seen from above (normals up).
        colours: (N, 4) RGBA in [0, 1] per vertex, by height.
    """

    vertices: FloatArray
    triangles: IntArray
    colours: FloatArray


def _kept(n: int, max_side: int) -> IntArray:
    """Indices of at most ``max_side`` evenly strided rows (or columns) of ``n``, last kept."""
    stride = max(1, -(-(n - 1) // (max_side - 1)))
    kept = np.arange(0, n, stride, dtype=np.int64)
    if kept[-1] != n - 1:
        kept = np.append(kept, n - 1)
    return kept


def height_colours(z: FloatArray) -> FloatArray:
    """(N, 4) RGBA for heights ``z`` (N,) m: the terrain palette from the lowest to the highest."""
    z = np.asarray(z, dtype=np.float64)
    span = float(np.ptp(z)) if z.size else 0.0
    t = (z - z.min()) / span if span > 0.0 else np.full(z.shape, 0.5)
    low, high = np.asarray(TERRAIN_LOW_RGBA), np.asarray(TERRAIN_HIGH_RGBA)
    return low + t[:, None] * (high - low)


def terrain_mesh(height_map: HeightMap, max_side: int = 101) -> TerrainMesh:
    """Two triangles per cell between the cell centres of ``height_map``.

    Args:
        height_map: the terrain in base_link.
        max_side: vertices per side at most (>= 2); a larger map keeps every n-th row and
            column, and always its last ones, so the mesh covers the whole map.

    Raises:
        SceneError: ``max_side`` < 2.
    """
    rows, cols = height_map.shape  # at least 2 x 2: HeightMap checks
    if max_side < 2:
        msg = f"max_side = {max_side} must be at least 2"
        raise SceneError(msg)
    r, c = _kept(rows, max_side), _kept(cols, max_side)
    z = np.asarray(height_map.heights, dtype=np.float64)[np.ix_(r, c)]
    x = height_map.origin_x + c * height_map.resolution
    y = height_map.origin_y + r * height_map.resolution
    gx, gy = np.meshgrid(x, y)
    vertices = np.column_stack((gx.ravel(), gy.ravel(), z.ravel()))
    n_cols = c.size
    v00 = (np.arange(r.size - 1)[:, None] * n_cols + np.arange(n_cols - 1)[None, :]).ravel()
    v01, v10 = v00 + 1, v00 + n_cols  # +x, +y neighbours
    v11 = v10 + 1
    # (v00, v01, v11) and (v00, v11, v10) run counter-clockwise in the x-y plane.
    triangles = np.column_stack((v00, v01, v11, v00, v11, v10)).reshape(-1, 3)
    return TerrainMesh(vertices, triangles.astype(np.int64), height_colours(vertices[:, 2]))


def sample_times(times: npt.ArrayLike, period_s: float, max_samples: int = 5000) -> FloatArray:
    """Times (K,) s covering ``times`` every ``period_s`` (at most ``max_samples``), with every
    row time of the trajectory included so that the drawn path passes through its waypoints."""
    t = np.asarray(times, dtype=np.float64)
    if t.size == 0:
        return t
    span = float(t[-1] - t[0])
    n = min(max_samples, int(np.ceil(span / period_s)) + 1) if span > 0.0 else 1
    return np.unique(np.concatenate((np.linspace(t[0], t[-1], n), t)))


def tool_path(
    model: LanderModel,
    frame: str,
    joints: Sequence[str],
    times: npt.ArrayLike,
    positions: FloatArray,
    velocities: FloatArray | None,
    period_s: float,
    q_rest: FloatArray | None = None,
) -> FloatArray:
    """Positions (K, 3) m in base_link of ``frame`` along a joint trajectory, interpolated as the
    simulation follows it (:class:`ow_description.trajectory.Spline`).

    Args:
        model: the lander model.
        frame: the frame drawn, e.g. ``l_scoop_tip``.
        joints: names of the trajectory's columns (any order, any subset of the model's joints).
        times: (n,) s from the trajectory's start, strictly increasing.
        positions: (n, len(joints)) rad.
        velocities: (n, len(joints)) rad/s, or None (linear interpolation).
        period_s: s of trajectory time between samples.
        q_rest: (nq,) rad for the joints the trajectory does not name (default 0).

    Raises:
        SceneError: no points, sizes that do not match, or a joint or frame the model lacks.
    """
    t = np.asarray(times, dtype=np.float64)
    pos = np.asarray(positions, dtype=np.float64)
    if t.size == 0 or pos.shape != (t.size, len(joints)):
        msg = (
            f"a trajectory of {t.size} points and {len(joints)} joints needs positions of "
            f"shape ({t.size}, {len(joints)}), got {pos.shape}"
        )
        raise SceneError(msg)
    unknown = [j for j in joints if j not in model.joint_names]
    if unknown:
        msg = f"trajectory joints {unknown} are not joints of the lander"
        raise SceneError(msg)
    try:
        model.frame_id(frame)
    except ModelError as exc:
        msg = f"tool frame {frame!r} is not a frame of the lander"
        raise SceneError(msg) from exc
    vel = None if velocities is None else np.asarray(velocities, dtype=np.float64)
    spline = Spline(t, pos, vel)
    columns = [model.index(j) for j in joints]
    q = np.zeros(model.nq) if q_rest is None else np.array(q_rest, dtype=np.float64)
    out = []
    for time_s in sample_times(t, period_s):
        q[columns] = spline.sample(float(time_s))[0]
        out.append(model.position(q, frame))
    return np.asarray(out)
