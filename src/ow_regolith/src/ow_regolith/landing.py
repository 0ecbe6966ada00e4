"""Where regolith poured from the scoop lands: in the sample dock, on the lander, on the terrain,
or nowhere the simulation keeps.

The rule: regolith falls straight down (-z of base_link; the lander stands level) from the pour
point and lands on the first thing below it. The sample dock is an open box, its collision box
(``lander_sample_dock0``, OceanWATERS' ingest box, spec 14.6): a pour point above it, or inside
it, puts the regolith in the dock. The lander's catching shapes (the box and cylinder collision
shapes of ``base_link``: body, legs, footpads) keep what falls on them; the terrain (its height
map) takes what falls on it; beyond the height map the regolith is lost.
"""

from __future__ import annotations

import enum
import math
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt

from ow_description.description import BASE_FRAME, DOCK_FRAME, URDF_PATH
from ow_description.errors import ModelError
from ow_description.model import LanderModel
from ow_description.shapes import CollisionShape, link_shapes
from ow_description.terrain import HeightMap
from ow_regolith.errors import GeometryError

FloatArray = npt.NDArray[np.float64]


class Landing(enum.Enum):
    """Where poured regolith lands."""

    DOCK = "dock"
    LANDER = "lander"
    TERRAIN = "terrain"
    BEYOND_TERRAIN = "beyond_terrain"


@dataclass(frozen=True)
class Solid:
    """A box or cylinder collision shape placed in base_link.

    Attributes:
        kind: ``"box"`` or ``"cylinder"``.
        size: m; box: (x, y, z) edge lengths; cylinder: (radius, length), axis along its z.
        rotation: (3, 3) of the shape's frame in base_link.
        translation: (3,) m, its centre in base_link.
    """

    kind: str
    size: tuple[float, ...]
    rotation: FloatArray
    translation: FloatArray

    @classmethod
    def placed(cls, shape: CollisionShape, X_base_link: FloatArray) -> Solid:
        """``shape`` of a link at ``X_base_link`` (4, 4)."""
        R = X_base_link[:3, :3]
        return cls(
            shape.kind,
            shape.size,
            R @ shape.rotation,
            R @ shape.translation + X_base_link[:3, 3],
        )

    def vertical_span(self, x: float, y: float) -> tuple[float, float] | None:
        """(lowest, highest) m, the z where the vertical line through (x, y) (m, base_link)
        is inside the shape, or None when it misses it."""
        # The line in the shape's frame: start + z * direction.
        start = self.rotation.T @ (np.array([x, y, 0.0]) - self.translation)
        direction = self.rotation.T[:, 2]
        low, high = -math.inf, math.inf
        if self.kind == "box":
            slabs = [(start[i], direction[i], self.size[i] / 2.0) for i in range(3)]
        else:
            slabs = [(start[2], direction[2], self.size[1] / 2.0)]
            # Within the radius: a quadratic in z, a z^2 + b z + c <= 0.
            a = direction[0] ** 2 + direction[1] ** 2
            b = 2.0 * (start[0] * direction[0] + start[1] * direction[1])
            c = start[0] ** 2 + start[1] ** 2 - self.size[0] ** 2
            if a < 1e-12:
                if c > 0.0:
                    return None
            else:
                discriminant = b * b - 4.0 * a * c
                if discriminant < 0.0:
                    return None
                root = math.sqrt(discriminant)
                low, high = (-b - root) / (2.0 * a), (-b + root) / (2.0 * a)
        for offset, slope, half in slabs:
            if abs(slope) < 1e-12:
                if abs(offset) > half:
                    return None
                continue
            ends = sorted(((-half - offset) / slope, (half - offset) / slope))
            low, high = max(low, ends[0]), min(high, ends[1])
        return (low, high) if low < high else None


class PourTargets:
    """The sample dock and the lander's catching boxes, in base_link.

    Args:
        dock: the dock's ingest box.
        lander: the shapes of the lander that catch regolith.
    """

    def __init__(self, dock: Solid, lander: Iterable[Solid]) -> None:
        self.dock = dock
        self.lander = tuple(lander)

    @classmethod
    def from_urdf(
        cls,
        dock_link: str = DOCK_FRAME,
        catch_links: Iterable[str] = (BASE_FRAME,),
        urdf_path: Path = URDF_PATH,
    ) -> PourTargets:
        """The dock box (``dock_link``'s one box) and every box and cylinder of
        ``catch_links``, placed by the URDF's joints at the zero configuration (the dock and the
        body are fixed).

        Raises:
            GeometryError: a link missing or without shapes, or a dock of other than one box.
        """
        try:
            model = LanderModel(urdf_path)
            q = model.q_from({})
            dock_shapes = link_shapes(dock_link, urdf_path)
            if len(dock_shapes) != 1 or dock_shapes[0].kind != "box":
                msg = f"the dock {dock_link} must have one box collision shape"
                raise GeometryError(msg)
            dock = Solid.placed(dock_shapes[0], model.fk(q, dock_link))
            lander = [
                Solid.placed(shape, model.fk(q, link))
                for link in catch_links
                for shape in link_shapes(link, urdf_path)
            ]
        except ModelError as error:
            msg = f"cannot read the pour targets from {urdf_path}: {error}"
            raise GeometryError(msg) from error
        return cls(dock, lander)

    def landing(self, point: FloatArray, terrain: HeightMap) -> Landing:
        """Where regolith falling from ``point`` (3,) m in base_link lands.

        The surfaces below the point (or holding it): the dock's floor, the top of each lander
        box, the terrain under it; the highest wins, the dock on a tie.
        """
        x, y, z = (float(v) for v in point)
        below: list[tuple[float, int, Landing]] = []
        span = self.dock.vertical_span(x, y)
        if span is not None and z > span[0]:
            below.append((span[0], 1, Landing.DOCK))
        for solid in self.lander:
            span = solid.vertical_span(x, y)
            if span is not None and z > span[0]:
                below.append((min(span[1], z), 0, Landing.LANDER))
        within_x = terrain.origin_x <= x <= terrain.x_max
        if within_x and terrain.origin_y <= y <= terrain.y_max:
            below.append((min(float(terrain.height_at(x, y)), z), 0, Landing.TERRAIN))
        if not below:
            return Landing.BEYOND_TERRAIN
        return max(below, key=lambda entry: (entry[0], entry[1]))[2]
