"""Tool geometry for the DEM, read from the lander URDF (the one source of truth).

The collision shapes come from the workspace's one reader, :mod:`ow_description.shapes`; this module
only triangulates them. The scoop is a set of thin boxes (plates); the DEM sees each plate as a
rectangle of two triangles on its mid-plane (the plates are 1-2 mm thick, far thinner than a
particle). The grinder is a set of coaxial cylinders along the link x axis; the DEM sees the
surface of revolution of their union.
"""

from __future__ import annotations

import itertools
import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ow_dem_bridge.api import FloatArray
from ow_dem_bridge.errors import GeometryError
from ow_description.errors import ModelError
from ow_description.shapes import link_shapes

Triangle = tuple[tuple[float, float, float], tuple[float, float, float], tuple[float, float, float]]


@dataclass(frozen=True)
class ToolGeometry:
    """A tool as the DEM sees it, in its link frame.

    Attributes:
        link: URDF link name, e.g. ``l_scoop``.
        facets: triangles, vertices in m.
        com: (3,) m, link centre of mass.
        tip: (3,) m, the tool tip (origin of the fixed ``<link>_tip`` child link).
    """

    link: str
    facets: tuple[Triangle, ...]
    com: FloatArray
    tip: FloatArray


def _xyz(elem: ET.Element | None) -> FloatArray:
    """(3,) m, the ``xyz`` of a URDF ``<origin>`` (zero when absent)."""
    text = elem.get("xyz") if elem is not None else None
    return np.array([float(v) for v in (text or "0 0 0").split()], dtype=np.float64)


def _find_link(root: ET.Element, link: str, urdf: Path) -> ET.Element:
    for elem in root.iter("link"):
        if elem.get("name") == link:
            return elem
    msg = f"{urdf}: no link named {link!r}"
    raise GeometryError(msg)


def _tip(root: ET.Element, link: str, urdf: Path) -> FloatArray:
    for joint in root.iter("joint"):
        parent, child = joint.find("parent"), joint.find("child")
        if (
            parent is not None
            and child is not None
            and parent.get("link") == link
            and child.get("link") == f"{link}_tip"
        ):
            return _xyz(joint.find("origin"))
    msg = f"{urdf}: no fixed joint from {link!r} to {link + '_tip'!r} (the tool tip)"
    raise GeometryError(msg)


def _plate(xyz: FloatArray, rot: FloatArray, size: FloatArray) -> tuple[Triangle, Triangle]:
    """Two triangles on the mid-plane of a box, spanned by its two largest dimensions."""
    thin = int(np.argmin(size))
    a, b = (i for i in range(3) if i != thin)
    ea = rot[:, a] * size[a] / 2
    eb = rot[:, b] * size[b] / 2
    corners = [xyz - ea - eb, xyz + ea - eb, xyz + ea + eb, xyz - ea + eb]
    c = [tuple(float(v) for v in p) for p in corners]
    return (c[0], c[1], c[2]), (c[0], c[2], c[3])  # type: ignore[return-value]


def _revolve(profile: list[tuple[float, float]], segments: int) -> list[Triangle]:
    """Triangles of the surface of revolution about link x of a profile of (x m, radius m)."""
    tris: list[Triangle] = []
    angles = [2 * math.pi * k / segments for k in range(segments + 1)]
    for (x0, r0), (x1, r1) in itertools.pairwise(profile):
        if x0 == x1 and r0 == r1:
            continue
        for a0, a1 in itertools.pairwise(angles):
            p00 = (x0, r0 * math.cos(a0), r0 * math.sin(a0))
            p01 = (x0, r0 * math.cos(a1), r0 * math.sin(a1))
            p10 = (x1, r1 * math.cos(a0), r1 * math.sin(a0))
            p11 = (x1, r1 * math.cos(a1), r1 * math.sin(a1))
            if r0 > 0:
                tris.append((p00, p10, p01))
            if r1 > 0:
                tris.append((p01, p10, p11))
    return tris


def load_tool(urdf: Path, link: str, segments: int = 12) -> ToolGeometry:
    """Read a tool link's collision primitives, centre of mass and tip from a URDF.

    Args:
        urdf: path of the URDF file.
        link: ``l_scoop`` (boxes) or ``l_grinder`` (coaxial cylinders along link x).
        segments: facets around a cylinder.

    Returns:
        The tool in its link frame.

    Raises:
        GeometryError: the link, its tip joint or its box and cylinder primitives are missing, a
            grinder cylinder is off the link x axis, or the URDF has a collision shape
            :mod:`ow_description.shapes` cannot read (a mesh, a sphere, malformed numbers).
    """
    root = ET.parse(urdf).getroot()
    elem = _find_link(root, link, urdf)
    inertial = elem.find("inertial")
    com = _xyz(inertial.find("origin") if inertial is not None else None)
    try:
        shapes = link_shapes(link, urdf)
    except ModelError as exc:
        msg = f"{urdf}: {exc}"
        raise GeometryError(msg) from exc
    tris: list[Triangle] = []
    cylinders: list[tuple[float, float, float]] = []  # (x_min, x_max, radius)
    for shape in shapes:
        xyz, rot = shape.translation, shape.rotation
        if shape.kind == "box":
            tris.extend(_plate(xyz, rot, np.asarray(shape.size, dtype=np.float64)))
        else:
            axis = rot[:, 2]
            if abs(abs(axis[0]) - 1) > 1e-3 or abs(xyz[1]) > 1e-9 or abs(xyz[2]) > 1e-9:
                msg = f"{urdf}: {link} cylinder {shape.name!r} is not on the link x axis"
                raise GeometryError(msg)
            radius, length = shape.size
            cylinders.append((xyz[0] - length / 2, xyz[0] + length / 2, radius))
    if cylinders:
        tris.extend(_revolve(_union_profile(cylinders), segments))
    return ToolGeometry(link, tuple(tris), com, _tip(root, link, urdf))


def _union_profile(cylinders: list[tuple[float, float, float]]) -> list[tuple[float, float]]:
    """Outline (x, radius) of the union of coaxial cylinders, closed on the axis at both ends."""
    xs = sorted({x for c in cylinders for x in c[:2]})
    profile: list[tuple[float, float]] = [(xs[0], 0.0)]
    for x0, x1 in itertools.pairwise(xs):
        mid = 0.5 * (x0 + x1)
        radius = max((c[2] for c in cylinders if c[0] <= mid <= c[1]), default=0.0)
        profile.extend([(x0, radius), (x1, radius)])
    profile.append((xs[-1], 0.0))
    return profile
