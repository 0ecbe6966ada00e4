"""The live DEM's bed in the simulation's frame: the terrain sampled over a bed's footprint
(:class:`BedGrid`, :func:`sample_bed`), the bed's frame (:class:`BedFrame`), the dig's heading,
and what a dig did to the bed's surface (:class:`DemSurface`).
No YADE, no ROS: :mod:`ow_dem_bridge.live` uses these to make a dig's bed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from ow_dem_bridge.api import FloatArray, LooseTop, TerrainHeights


def quaternion(rotation: FloatArray) -> list[float]:
    """(w, x, y, z) of a rotation matrix (Shepperd's method, w >= 0)."""
    m = rotation
    trace = m[0, 0] + m[1, 1] + m[2, 2]
    if trace > 0:
        s = 2.0 * math.sqrt(trace + 1.0)
        q = [0.25 * s, (m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s]
    elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
        s = 2.0 * math.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2])
        q = [(m[2, 1] - m[1, 2]) / s, 0.25 * s, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s]
    elif m[1, 1] > m[2, 2]:
        s = 2.0 * math.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2])
        q = [(m[0, 2] - m[2, 0]) / s, (m[0, 1] + m[1, 0]) / s, 0.25 * s, (m[1, 2] + m[2, 1]) / s]
    else:
        s = 2.0 * math.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1])
        q = [(m[1, 0] - m[0, 1]) / s, (m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, 0.25 * s]
    if q[0] < 0:
        q = [-v for v in q]
    norm = math.sqrt(sum(v * v for v in q))
    return [float(v / norm) for v in q]


@dataclass(frozen=True)
class BedFrame:
    """The DEM's frame: origin (m, base_link) at the back of the bed on its floor, x along the
    dig (``heading`` rad from base_link x), z up."""

    origin: tuple[float, float, float]
    heading: float

    @property
    def rotation(self) -> FloatArray:
        """(3, 3) the bed frame's axes in base_link."""
        c, s = math.cos(self.heading), math.sin(self.heading)
        return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])

    def pose(self, rotation: FloatArray, origin: FloatArray) -> tuple[list[float], list[float]]:
        """A link pose in base_link as (position m, quaternion w, x, y, z) in the bed frame."""
        turn = self.rotation.T
        position = turn @ (origin - np.asarray(self.origin))
        return position.tolist(), quaternion(turn @ rotation)


@dataclass(frozen=True)
class BedGrid:
    """The terrain over a bed's footprint, sampled on its grid when the dig starts.

    Attributes:
        back: (x, y) m in base_link of the bed's back edge centre (the grid's u = v = 0).
        heading: rad, the bed's x axis (u) from base_link x.
        us: (nu,) m, grid positions along the dig.
        vs: (nv,) m, grid positions across it (left positive).
        solid: (nv, nu) m, base_link z of the terrain's height map (the solid surface).
        top: (nv, nu) m, base_link z of the material's top: the loose layer's where loose
            regolith lies on the solid surface, else the solid surface (``top >= solid``).
    """

    back: tuple[float, float]
    heading: float
    us: FloatArray
    vs: FloatArray
    solid: FloatArray
    top: FloatArray

    def top_at(self, x: float, y: float) -> float:
        """m, the material's top at (x, y) m in base_link, bilinear on the grid; ``-inf``
        outside the footprint."""
        dx, dy = x - self.back[0], y - self.back[1]
        c, s = math.cos(self.heading), math.sin(self.heading)
        u, v = c * dx + s * dy, -s * dx + c * dy
        us, vs = self.us, self.vs
        if not (us[0] <= u <= us[-1] and vs[0] <= v <= vs[-1]):
            return -math.inf
        i = min(int((u - us[0]) / (us[1] - us[0])), len(us) - 2)
        j = min(int((v - vs[0]) / (vs[1] - vs[0])), len(vs) - 2)
        a = (u - us[i]) / (us[i + 1] - us[i])
        b = (v - vs[j]) / (vs[j + 1] - vs[j])
        h = self.top
        return float(
            (1 - a) * (1 - b) * h[j, i]
            + a * (1 - b) * h[j, i + 1]
            + (1 - a) * b * h[j + 1, i]
            + a * b * h[j + 1, i + 1]
        )


def sample_bed(
    terrain: TerrainHeights,
    loose_top: LooseTop | None,
    back: tuple[float, float],
    heading: float,
    us: FloatArray,
    vs: FloatArray,
) -> BedGrid:
    """The solid heights and the material's top (the loose layer's where there is one) on a
    bed's grid: point (u, v) lies at ``back + u * (cos h, sin h) + v * (-sin h, cos h)``."""
    cos_h, sin_h = math.cos(heading), math.sin(heading)
    solid = np.empty((len(vs), len(us)))
    top = np.empty_like(solid)
    for j, v in enumerate(vs):
        for i, u in enumerate(us):
            x = float(back[0] + cos_h * u - sin_h * v)
            y = float(back[1] + sin_h * u + cos_h * v)
            solid[j, i] = terrain.height_at(x, y)
            top[j, i] = solid[j, i] if loose_top is None else max(solid[j, i], loose_top(x, y))
    return BedGrid(back, heading, np.asarray(us), np.asarray(vs), solid, top)


def dig_heading(rotation: FloatArray, velocity: FloatArray, tip: FloatArray) -> float:
    """rad, the dig's direction in base_link's xy plane: the scoop's +x (cutting edge first)
    projected, or else its tip velocity, or else away from the lander."""
    for vector in (rotation[:, 0], velocity, tip):
        horizontal = np.asarray(vector[:2], dtype=np.float64)
        if math.hypot(horizontal[0], horizontal[1]) > 0.2 * math.sqrt(float(vector @ vector)):
            return math.atan2(horizontal[1], horizontal[0])
    return 0.0


@dataclass(frozen=True)
class DemSurface:
    """What a DEM dig did to its bed's surface: the change of its bulk heights
    (:mod:`ow_dem_bridge.bed_surface`) from when the bed was made to when the dig ended, the
    sample's spheres left out, on a coarse grid of cells in the bed frame.

    Attributes:
        frame: the bed's frame (origin at the back of the bed, on its floor; heading).
        cell_u: m, a cell's side along the dig.
        cell_v: m, its side across (cells from v = -width / 2, left positive).
        change_m: (nv, nu) m, each cell's change (negative: the bed fell there).
    """

    frame: BedFrame
    cell_u: float
    cell_v: float
    change_m: FloatArray

    @classmethod
    def from_reply(cls, reply: dict[str, Any], frame: BedFrame) -> DemSurface:
        """The ``surface`` of YADE's ``finish`` reply (``length``, ``width``, ``nu``, ``nv``,
        ``change``) in the bed ``frame``."""
        change = np.array(reply["change"], dtype=np.float64).reshape(reply["nv"], reply["nu"])
        return cls(
            frame, float(reply["length"]) / reply["nu"], float(reply["width"]) / reply["nv"], change
        )

    def _to_bed(self, x: FloatArray, y: FloatArray) -> tuple[FloatArray, FloatArray]:
        """(u, v) m in the grid's frame (u from the back edge, v from the right edge)."""
        c, s = math.cos(self.frame.heading), math.sin(self.frame.heading)
        dx, dy = x - self.frame.origin[0], y - self.frame.origin[1]
        nv = self.change_m.shape[0]
        return c * dx + s * dy, -s * dx + c * dy + nv * self.cell_v / 2

    def centres(self) -> FloatArray:
        """(nv, nu, 2) m, each cell's centre (x, y) in base_link."""
        nv, nu = self.change_m.shape
        u = (np.arange(nu) + 0.5) * self.cell_u
        v = (np.arange(nv) + 0.5) * self.cell_v - nv * self.cell_v / 2
        uu, vv = np.meshgrid(u, v)
        c, s = math.cos(self.frame.heading), math.sin(self.frame.heading)
        x = self.frame.origin[0] + c * uu - s * vv
        y = self.frame.origin[1] + s * uu + c * vv
        return np.stack([x, y], axis=-1)

    def covers(self, x: FloatArray, y: FloatArray) -> npt.NDArray[np.bool_]:
        """Whether each point (x, y) m (base_link, any shape) lies on the grid's footprint."""
        u, v = self._to_bed(np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64))
        nv, nu = self.change_m.shape
        return (u >= 0) & (u <= nu * self.cell_u) & (v >= 0) & (v <= nv * self.cell_v)

    def change_at(self, x: FloatArray, y: FloatArray) -> FloatArray:
        """m, the change at each point (x, y) m (base_link, any shape): bilinear between the
        cells' centres, held from the outermost centres to the footprint's edge, 0 outside it."""
        x, y = np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)
        u, v = self._to_bed(x, y)
        nv, nu = self.change_m.shape
        # In the grid padded by a copy of its edge cells, cell k's centre is at k + 1: the change
        # holds from the outermost centres to the footprint's edge.
        padded = np.pad(self.change_m, 1, mode="edge")
        fu = np.clip(u / self.cell_u + 0.5, 0.0, nu + 1.0)
        fv = np.clip(v / self.cell_v + 0.5, 0.0, nv + 1.0)
        i = np.minimum(fu.astype(np.intp), nu)
        j = np.minimum(fv.astype(np.intp), nv)
        a, b = fu - i, fv - j
        value = (
            (1 - a) * (1 - b) * padded[j, i]
            + a * (1 - b) * padded[j, i + 1]
            + (1 - a) * b * padded[j + 1, i]
            + a * b * padded[j + 1, i + 1]
        )
        return np.where(self.covers(x, y), value, 0.0)
