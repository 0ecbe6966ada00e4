"""The scoop as a container: its capacity and what it keeps at any orientation, from its
collision shapes in the URDF (read through :mod:`ow_description.shapes`).

The cavity. The scoop is a set of thin boxes. Its two *side walls* bound the cavity across (their
inner faces) and in profile (the cavity lies within their outline); the *plates* (bottom, back)
bound it with their inner faces; the *rim plate* (the partial top) gives the **lip plane**, the
plane of its inner face, which closes the cavity at the top. "Inner" is the side facing the
middle of the side walls. The cavity is the convex region inside all these planes; its volume is
the scoop's capacity (m^3; the walls' thickness is outside it).

The mouth is the part of the cavity's face on the lip plane that the rim plate does not cover,
on the side of the cutting edge (the tip frame, ``l_scoop_tip``).

The spill rule. Outside a dig, the regolith in the scoop settles with a level surface (a liquid's
rule: no angle of repose, no cohesion); whatever would lie above the mouth's lowest point spills
over it. So the scoop keeps at most the volume of the cavity below the horizontal plane through
the mouth's lowest point, and the excess pours out there (:meth:`ScoopGeometry.pour_point`).
With the mouth straight up (tilt 0) it keeps its capacity, with the mouth straight down (tilt
180 degrees) nothing. In a dig the scoop is filled up to its capacity whatever its orientation:
the dig's motion holds the regolith in.

Frames: the scoop link frame (``l_scoop``), and base_link for poses; z of base_link is up.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt

from ow_description.description import URDF_PATH
from ow_description.errors import ModelError
from ow_description.shapes import CollisionShape, link_shapes
from ow_regolith.errors import GeometryError
from ow_regolith.materials import units_from_m3
from ow_regolith.polytope import Halfspace, faces, ordered_faces, vertices, volume, volume_below

FloatArray = npt.NDArray[np.float64]

#: m, mouth corners within this height of the lowest one pour together (their mean is the pour
#: point): the two corners of a level lip edge.
LEVEL_EDGE = 1e-6
#: Points along the cutting edge that collect loose regolith in a dig.
BLADE_POINTS = 5


@dataclass(frozen=True)
class ScoopShapes:
    """Which collision shapes of the scoop link play which part (by ``<collision name>``).

    Attributes:
        link: the scoop link.
        side_walls: the two side walls (boxes).
        plates: the other walls bounding the cavity by their inner faces (bottom, back).
        rim: the partial top plate whose inner face is the lip plane.
        tip_frame: the frame at the cutting edge (it tells the mouth's side of the rim plate).
    """

    link: str = "l_scoop"
    side_walls: tuple[str, str] = ("left", "right")
    plates: tuple[str, ...] = ("bottom", "back")
    rim: str = "top"
    tip_frame: str = "l_scoop_tip"


@dataclass(frozen=True)
class _Plate:
    """A thin box: its centre, axes (columns) and half sizes, the thin axis first known."""

    centre: FloatArray
    axes: FloatArray
    half: FloatArray
    thin: int

    @classmethod
    def of(cls, shape: CollisionShape) -> _Plate:
        if shape.kind != "box":
            msg = f"scoop shape {shape.name!r} is a {shape.kind}; the scoop's walls must be boxes"
            raise GeometryError(msg)
        half = np.asarray(shape.size, dtype=np.float64) / 2.0
        return cls(shape.translation, shape.rotation, half, int(np.argmin(half)))

    def inner_halfspace(self, reference: FloatArray) -> Halfspace:
        """The side of the plate's face towards ``reference``."""
        normal = self.axes[:, self.thin]
        side = 1.0 if normal @ (reference - self.centre) >= 0.0 else -1.0
        face = self.centre + side * self.half[self.thin] * normal
        return Halfspace.through(face, -side * normal)

    def outline(self) -> list[Halfspace]:
        """The four planes through the plate's edges, across its face."""
        planes = []
        for axis in range(3):
            if axis == self.thin:
                continue
            direction = self.axes[:, axis]
            for side in (1.0, -1.0):
                end = self.centre + side * self.half[axis] * direction
                planes.append(Halfspace.through(end, side * direction))
        return planes


class ScoopGeometry:
    """The scoop's cavity, mouth and cutting edge, in the scoop link frame.

    Args:
        cavity: the half-spaces whose intersection is the cavity (bounded).
        lip: the half-space of the lip plane (one of ``cavity``).
        mouth: (k, 3) m, the corners of the mouth (on the lip plane).
        tip: (3,) m, the cutting edge's centre (the tip frame's origin).
        width_axis: (3,) unit vector across the scoop (normal of the side walls).
        width: m, the cavity's width between the side walls.

    Raises:
        GeometryError: an empty cavity or a mouth of fewer than three corners.
    """

    def __init__(
        self,
        cavity: list[Halfspace],
        lip: Halfspace,
        mouth: FloatArray,
        tip: FloatArray,
        width_axis: FloatArray,
        width: float,
    ) -> None:
        self.cavity = faces(cavity)
        self.lip = lip
        self.mouth = np.asarray(mouth, dtype=np.float64)
        self.tip = np.asarray(tip, dtype=np.float64)
        self.width_axis = np.asarray(width_axis, dtype=np.float64)
        self.width = float(width)
        self.corners = vertices(self.cavity)
        self._faces = ordered_faces(self.cavity)
        self.capacity_m3 = volume(self.cavity)
        if not self.capacity_m3 > 0.0:
            msg = "the scoop's shapes enclose no cavity: check its side walls, plates and rim"
            raise GeometryError(msg)
        if len(self.mouth) < 3:
            msg = f"the scoop's mouth has {len(self.mouth)} corners; it needs 3 or more"
            raise GeometryError(msg)
        #: units, the capacity as the budget counts it.
        self.capacity_units = units_from_m3(self.capacity_m3)

    @classmethod
    def from_urdf(
        cls, shapes: ScoopShapes | None = None, urdf_path: Path = URDF_PATH
    ) -> ScoopGeometry:
        """The scoop of the URDF at ``urdf_path``, its walls named by ``shapes``.

        Raises:
            GeometryError: a named shape or frame missing, a wall that is not a box, a tip frame
                over the rim plate, or no cavity.
        """
        # The model (pinocchio) only here: the configuration imports this module, and the
        # mission's configuration must stay light (tests/unit/ow_mission/test_mission_imports.py).
        from ow_description.model import LanderModel

        roles = shapes or ScoopShapes()
        try:
            by_name = {s.name: s for s in link_shapes(roles.link, urdf_path)}
            model = LanderModel(urdf_path)
            q = model.q_from({})
            X_scoop_tip = np.linalg.inv(model.fk(q, roles.link)) @ model.fk(q, roles.tip_frame)
        except ModelError as error:
            msg = f"cannot read the scoop from {urdf_path}: {error}"
            raise GeometryError(msg) from error

        def plate(name: str) -> _Plate:
            if name not in by_name:
                msg = f"{roles.link} has no collision shape {name!r}; it has {sorted(by_name)}"
                raise GeometryError(msg)
            return _Plate.of(by_name[name])

        sides = [plate(name) for name in roles.side_walls]
        reference = (sides[0].centre + sides[1].centre) / 2.0
        rim = plate(roles.rim)
        lip = rim.inner_halfspace(reference)
        cavity = [lip]
        for side in sides:
            cavity += [side.inner_halfspace(reference), *side.outline()]
        cavity += [plate(name).inner_halfspace(reference) for name in roles.plates]
        tip = X_scoop_tip[:3, 3]
        mouth = _mouth(cavity, lip, rim, tip, roles.rim)
        width_axis = sides[0].axes[:, sides[0].thin]
        inner = [side.inner_halfspace(reference) for side in sides]
        # The inner faces' outward normals are opposite: the planes are offset + offset apart.
        width = inner[0].offset + inner[1].offset
        return cls(cavity, lip, mouth, tip, width_axis, width)

    # ------------------------------------------------------------------ keeping and pouring
    def retained_m3(self, R_base_scoop: FloatArray) -> float:
        """m^3, the most the scoop keeps with the orientation ``R_base_scoop`` (3, 3): the
        cavity below the level of the mouth's lowest corner."""
        up = np.asarray(R_base_scoop, dtype=np.float64).T @ np.array([0.0, 0.0, 1.0])
        level = float(np.min(self.mouth @ up))
        heights = self.corners @ up
        if level >= heights.max() - 1e-12:
            return self.capacity_m3
        if level <= heights.min() + 1e-12:
            return 0.0
        return min(volume_below(self._faces, up, level), self.capacity_m3)

    def retained_units(self, R_base_scoop: FloatArray) -> int:
        """:meth:`retained_m3` in units, never above :attr:`capacity_units`."""
        return min(units_from_m3(self.retained_m3(R_base_scoop)), self.capacity_units)

    def pour_point(self, X_base_scoop: FloatArray) -> FloatArray:
        """(3,) m in base_link, where the excess pours out: the mouth's lowest corner (the
        middle of its lowest edge when that edge is level)."""
        X = np.asarray(X_base_scoop, dtype=np.float64)
        corners = self.mouth @ X[:3, :3].T + X[:3, 3]
        lowest = corners[corners[:, 2] <= corners[:, 2].min() + LEVEL_EDGE]
        return np.asarray(lowest.mean(axis=0))

    def blade_points(self, X_base_scoop: FloatArray) -> FloatArray:
        """(:data:`BLADE_POINTS`, 3) m in base_link, along the cutting edge across the cavity's
        width: where a digging scoop collects loose regolith."""
        X = np.asarray(X_base_scoop, dtype=np.float64)
        offsets = np.linspace(-self.width / 2.0, self.width / 2.0, BLADE_POINTS)
        local = self.tip + offsets[:, None] * self.width_axis
        return np.asarray(local @ X[:3, :3].T + X[:3, 3])

    # ------------------------------------------------------------------ tilt
    def upright(self) -> FloatArray:
        """(3, 3) ``R_base_scoop`` with the lip plane level, the mouth up, the cutting edge
        towards +x of base_link and the scoop's width along y: tilt 0."""
        n = np.asarray(self.lip.normal)
        across = self.width_axis - (self.width_axis @ n) * n
        across /= np.linalg.norm(across)
        forward = np.cross(across, n)
        if forward @ (self.tip - self.mouth.mean(axis=0)) < 0.0:
            forward, across = -forward, -across
        S = np.column_stack([forward, across, n])
        return np.asarray(S.T)

    def tilted(self, tilt: float) -> FloatArray:
        """(3, 3) ``R_base_scoop`` tipped by ``tilt`` rad from :meth:`upright` about base_link's
        y axis, the cutting edge going down for ``tilt`` > 0 (pouring over the edge) and up for
        ``tilt`` < 0."""
        c, s = math.cos(tilt), math.sin(tilt)
        about_y = np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])
        return np.asarray(about_y @ self.upright())


def _mouth(
    cavity: list[Halfspace], lip: Halfspace, rim: _Plate, tip: FloatArray, rim_name: str
) -> FloatArray:
    """(k, 3) m, the corners of the part of the cavity's lip face that ``rim`` leaves open on
    the side of ``tip``."""
    best_axis, best_excess = -1, 0.0
    for axis in range(3):
        if axis == rim.thin:
            continue
        excess = abs((tip - rim.centre) @ rim.axes[:, axis]) - rim.half[axis]
        if excess > best_excess:
            best_axis, best_excess = axis, excess
    if best_axis < 0:
        msg = f"the cutting edge lies over the rim plate {rim_name!r}: the scoop has no mouth"
        raise GeometryError(msg)
    direction = rim.axes[:, best_axis]
    side = 1.0 if (tip - rim.centre) @ direction >= 0.0 else -1.0
    edge = rim.centre + side * rim.half[best_axis] * direction
    beyond_rim = Halfspace.through(edge, -side * direction)
    corners = vertices([*cavity, beyond_rim])
    on_lip = np.abs(lip.signed_distance(corners)) <= 1e-7
    return np.asarray(corners[on_lip])
