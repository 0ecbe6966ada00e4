"""The primitive collision shapes of the URDF: the one reader the model, the simulation's carving
and the DEM tool geometry share.

Each consumer samples the shapes its own way (a few points per box for the planner's terrain
check, a surface grid for carving, triangles for the DEM), but what the shapes are is read here
only. Poses are in the frame of the link that owns the shape (URDF ``<collision><origin>``).
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt

from ow_description.description import URDF_PATH
from ow_description.errors import ModelError

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class CollisionShape:
    """One ``<collision>`` primitive of a link.

    Attributes:
        link: name of the owning link.
        name: the element's ``name`` attribute ("" when absent).
        kind: ``"box"`` or ``"cylinder"`` (the only primitives the lander uses).
        size: m; box: (x, y, z) full edge lengths; cylinder: (radius, length), axis along z.
        xyz: (3,) m, origin of the shape in the link frame.
        rpy: (3,) rad, URDF fixed-axis roll, pitch, yaw of the shape in the link frame.
    """

    link: str
    name: str
    kind: str
    size: tuple[float, ...]
    xyz: tuple[float, float, float]
    rpy: tuple[float, float, float]

    @property
    def rotation(self) -> FloatArray:
        """(3, 3) rotation of the shape's frame in the link frame, computed as pinocchio's URDF
        parser (urdfdom) computes it, so that every consumer places the shape exactly where the
        coal collision model does (``pin.rpy.rpyToMatrix`` differs by up to 4e-16)."""
        return urdf_rotation(self.rpy)

    @property
    def translation(self) -> FloatArray:
        """(3,) m, origin of the shape's frame in the link frame."""
        return np.array(self.xyz, dtype=np.float64)


def urdf_rotation(rpy: tuple[float, float, float]) -> FloatArray:
    """(3, 3) rotation of URDF fixed-axis ``rpy`` (rad), computed as pinocchio's URDF parser
    (urdfdom) does it: through a normalised quaternion. ``pin.rpy.rpyToMatrix`` differs from it
    by up to 4e-16, which would move the sample points off the coal model's placements."""
    import pinocchio as pin  # here: readers of the shapes alone (configurations) stay light

    half_roll, half_pitch, half_yaw = rpy[0] / 2.0, rpy[1] / 2.0, rpy[2] / 2.0
    sr, cr = math.sin(half_roll), math.cos(half_roll)
    sp, cp = math.sin(half_pitch), math.cos(half_pitch)
    sy, cy = math.sin(half_yaw), math.cos(half_yaw)
    x = sr * cp * cy - cr * sp * sy
    y = cr * sp * cy + sr * cp * sy
    z = cr * cp * sy - sr * sp * cy
    w = cr * cp * cy + sr * sp * sy
    norm = math.sqrt(x * x + y * y + z * z + w * w)
    return np.asarray(pin.Quaternion(w / norm, x / norm, y / norm, z / norm).matrix())


def _floats(text: str | None, count: int, where: str) -> tuple[float, ...]:
    values = tuple(float(v) for v in (text or " ".join(["0"] * count)).split())
    if len(values) != count:
        msg = f"{where}: expected {count} numbers, got {text!r}"
        raise ModelError(msg)
    return values


def read_collision_shapes(urdf: Path | str = URDF_PATH) -> dict[str, tuple[CollisionShape, ...]]:
    """Every link's box and cylinder collision shapes, by link name.

    Args:
        urdf: a URDF file path, or the URDF document itself (text starting with ``<``).

    Returns:
        link name -> its shapes in document order (links without collision are left out).

    Raises:
        ModelError: a collision element with another geometry (mesh, sphere), or malformed
            numbers.
    """
    text = urdf if isinstance(urdf, str) and urdf.lstrip().startswith("<") else None
    root = ET.fromstring(text) if text is not None else ET.parse(Path(urdf)).getroot()
    shapes: dict[str, tuple[CollisionShape, ...]] = {}
    for link in root.iter("link"):
        link_name = link.get("name", "")
        found = []
        for collision in link.iter("collision"):
            where = f"link {link_name} collision {collision.get('name', '')!r}"
            origin = collision.find("origin")
            xyz = _floats(origin.get("xyz") if origin is not None else None, 3, where)
            rpy = _floats(origin.get("rpy") if origin is not None else None, 3, where)
            box = collision.find("geometry/box")
            cylinder = collision.find("geometry/cylinder")
            if box is not None:
                kind, size = "box", _floats(box.get("size"), 3, where)
            elif cylinder is not None:
                kind = "cylinder"
                size = (float(cylinder.get("radius", "0")), float(cylinder.get("length", "0")))
            else:
                msg = f"{where}: only box and cylinder collision shapes are supported"
                raise ModelError(msg)
            found.append(
                CollisionShape(
                    link_name,
                    collision.get("name", ""),
                    kind,
                    size,
                    (xyz[0], xyz[1], xyz[2]),
                    (rpy[0], rpy[1], rpy[2]),
                )
            )
        if found:
            shapes[link_name] = tuple(found)
    return shapes


def link_shapes(link: str, urdf: Path | str = URDF_PATH) -> tuple[CollisionShape, ...]:
    """The collision shapes of one link.

    Raises:
        ModelError: the link is not in the URDF or has no collision shape.
    """
    shapes = read_collision_shapes(urdf).get(link)
    if not shapes:
        msg = f"link {link!r} has no box or cylinder collision shape in the URDF"
        raise ModelError(msg)
    return shapes
