"""The surface of a DEM bed as a coarse grid of bulk heights, and its change over a dig.

Plain Python (no numpy, nothing of this package): YADE's worker (``yade_live.py``) imports it as
its sibling script, the library and its tests as ``ow_dem_bridge.bed_surface``.

A particle bed has no surface of its own; its *bulk height* over a cell is the solid volume of
the spheres whose centres lie in the cell over (cell area x the bed's solid fraction): how thick
the regolith would be there at the bed's packing. The cells are about :data:`CELL_DIAMETERS`
mean sphere diameters wide: one sphere's volume spread over a cell of one diameter would swing
its height by 0.5 diameter / solid fraction (with 2 cm grains and a 2 cm cell, ~1.7 cm per
sphere); over two diameters a quarter of that. Everything in the bed frame (m): ``u`` along the
dig from the bed's back, ``v`` across it (left positive), the bed spanning
``[0, length] x [-width / 2, width / 2]``.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass

#: Cell side in mean sphere diameters (module docstring).
CELL_DIAMETERS = 2.0


@dataclass(frozen=True)
class SurfaceGrid:
    """Cells tiling a bed exactly: ``nu`` x ``nv`` cells of ``cell_u`` x ``cell_v`` m (the
    bed's length and width each divided into the whole number of cells nearest the wanted side,
    so the cells are square to within half a cell over the bed's length or width).

    Attributes:
        length: m, the bed's extent along u (from 0).
        width: m, its extent across (v from -width / 2).
        nu: cells along u.
        nv: cells along v.
    """

    length: float
    width: float
    nu: int
    nv: int

    @classmethod
    def over_bed(cls, length: float, width: float, particle_radius: float) -> SurfaceGrid:
        """The grid of cells about :data:`CELL_DIAMETERS` mean diameters wide over a bed of
        ``length`` x ``width`` m of spheres of mean radius ``particle_radius`` m.

        Raises:
            ValueError: a non-positive size or radius.
        """
        if not (length > 0 and width > 0 and particle_radius > 0):
            msg = (
                f"a bed of {length!r} x {width!r} m with spheres of {particle_radius!r} m has no "
                "surface grid: every size must be > 0"
            )
            raise ValueError(msg)
        side = CELL_DIAMETERS * 2.0 * particle_radius
        return cls(length, width, max(1, round(length / side)), max(1, round(width / side)))

    @property
    def cell_u(self) -> float:
        """m, a cell's side along u."""
        return self.length / self.nu

    @property
    def cell_v(self) -> float:
        """m, a cell's side along v."""
        return self.width / self.nv

    def cell_of(self, u: float, v: float) -> tuple[int, int] | None:
        """(iv, iu) of the cell holding (u, v) m, None outside the bed."""
        iu = math.floor(u / self.cell_u)
        iv = math.floor((v + self.width / 2) / self.cell_v)
        if 0 <= iu < self.nu and 0 <= iv < self.nv:
            return iv, iu
        return None

    def to_dict(self) -> dict[str, float | int]:
        """The grid's geometry for a JSON reply."""
        return {"length": self.length, "width": self.width, "nu": self.nu, "nv": self.nv}


def bulk_heights(
    grid: SurfaceGrid, spheres: Iterable[tuple[float, float, float]], solid_fraction: float
) -> list[list[float]]:
    """m, the bulk height of every cell, ``[iv][iu]``: the volume of the spheres whose centres
    lie in it (``spheres``: (u, v, radius) m; those outside the bed count nowhere) over (cell
    area x ``solid_fraction``). The sums run in the spheres' order, so the same spheres in the
    same cells give the same heights bit for bit.

    Raises:
        ValueError: ``solid_fraction`` not in (0, 1].
    """
    if not 0.0 < solid_fraction <= 1.0:
        msg = f"a solid fraction must lie in (0, 1], got {solid_fraction!r}"
        raise ValueError(msg)
    volume = [[0.0] * grid.nu for _ in range(grid.nv)]
    for u, v, radius in spheres:
        cell = grid.cell_of(u, v)
        if cell is not None:
            volume[cell[0]][cell[1]] += 4.0 / 3.0 * math.pi * radius**3
    bulk = grid.cell_u * grid.cell_v * solid_fraction
    return [[solid / bulk for solid in row] for row in volume]


def height_change(before: list[list[float]], after: list[list[float]]) -> list[list[float]]:
    """m, ``after - before`` cell by cell (grids of the same shape).

    Raises:
        ValueError: grids of different shapes.
    """
    if len(before) != len(after) or any(
        len(a) != len(b) for a, b in zip(before, after, strict=True)
    ):
        msg = "the two bulk-height grids have different shapes"
        raise ValueError(msg)
    return [
        [b - a for a, b in zip(row0, row1, strict=True)]
        for row0, row1 in zip(before, after, strict=True)
    ]
