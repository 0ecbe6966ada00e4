"""Bounded convex polytopes as intersections of half-spaces: their vertices and volume.

The scoop's cavity is one (:mod:`ow_regolith.scoop`): a handful of planes, so the vertices are
found by intersecting every three planes and keeping the points inside all the others, and the
volume is the sum of the pyramids from an interior point to each face. Lengths in m.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ow_regolith.errors import GeometryError

FloatArray = npt.NDArray[np.float64]

#: m, how far outside a plane a point may lie and still count as on or inside it.
TOLERANCE = 1e-10


@dataclass(frozen=True)
class Halfspace:
    """The points p with ``normal . p <= offset``.

    Attributes:
        normal: (3,) unit vector pointing out of the half-space.
        offset: m.
    """

    normal: tuple[float, float, float]
    offset: float

    @classmethod
    def through(cls, point: FloatArray, outward: FloatArray) -> Halfspace:
        """The half-space bounded by the plane through ``point`` (3,) m, ``outward`` (3,)
        pointing away from it.

        Raises:
            GeometryError: a zero ``outward``.
        """
        norm = float(np.linalg.norm(outward))
        if not norm > 0.0:
            msg = f"a half-space needs a non-zero normal, got {outward!r}"
            raise GeometryError(msg)
        n = np.asarray(outward, dtype=np.float64) / norm
        return cls((float(n[0]), float(n[1]), float(n[2])), float(n @ point))

    def signed_distance(self, points: FloatArray) -> FloatArray:
        """m, (n,) distance of each of ``points`` (n, 3) outside the plane (< 0 inside)."""
        return np.asarray(points, dtype=np.float64) @ np.asarray(self.normal) - self.offset


def vertices(halfspaces: Sequence[Halfspace]) -> FloatArray:
    """(n, 3) m, the vertices of the intersection of ``halfspaces`` (none when it is empty or
    has no vertex), sorted, each once."""
    normals = np.array([h.normal for h in halfspaces], dtype=np.float64).reshape(-1, 3)
    offsets = np.array([h.offset for h in halfspaces], dtype=np.float64)
    if len(normals) < 3:
        return np.zeros((0, 3))
    triples = np.array(list(itertools.combinations(range(len(normals)), 3)), dtype=np.intp)
    systems = normals[triples]
    solvable = np.abs(np.linalg.det(systems)) > 1e-12
    if not np.any(solvable):
        return np.zeros((0, 3))
    candidates = np.linalg.solve(systems[solvable], offsets[triples[solvable]][..., None])[..., 0]
    inside = np.all(candidates @ normals.T - offsets <= TOLERANCE, axis=1)
    found = candidates[inside]
    if not len(found):
        return np.zeros((0, 3))
    points = found[np.lexsort(found.T[::-1])]
    # Corners where more than three planes meet are found once per triple: keep one.
    apart = np.linalg.norm(np.diff(points, axis=0), axis=1) > 1e3 * TOLERANCE
    return np.asarray(points[np.concatenate(([True], apart))])


def _distinct(halfspaces: Sequence[Halfspace]) -> list[int]:
    """Indices of ``halfspaces`` without the repeats of a plane (within 1e-9)."""
    kept: list[int] = []
    for i, plane in enumerate(halfspaces):
        if not any(
            abs(plane.offset - halfspaces[j].offset) <= 1e-9
            and all(
                abs(a - b) <= 1e-9 for a, b in zip(plane.normal, halfspaces[j].normal, strict=True)
            )
            for j in kept
        ):
            kept.append(i)
    return kept


def _face_area(face: FloatArray, normal: FloatArray) -> float:
    """m^2, area of the convex polygon with corners ``face`` (k, 3) in a plane of ``normal``."""
    offsets = face - face.mean(axis=0)
    u = offsets[np.argmax(np.einsum("ij,ij->i", offsets, offsets))]
    u = u / math.sqrt(float(u @ u))
    w = np.array(
        (
            normal[1] * u[2] - normal[2] * u[1],
            normal[2] * u[0] - normal[0] * u[2],
            normal[0] * u[1] - normal[1] * u[0],
        )
    )
    a, b = offsets @ u, offsets @ w
    order = np.argsort(np.arctan2(b, a))
    a, b = a[order], b[order]
    # The shoelace formula in the face's own (u, w) coordinates, counter-clockwise about normal.
    return float(0.5 * (a @ np.append(b[1:], b[0]) - b @ np.append(a[1:], a[0])))


def volume(halfspaces: Sequence[Halfspace]) -> float:
    """m^3, volume of the intersection of ``halfspaces``, which must be bounded (0 when it is
    empty or flat).

    Planes given twice (within 1e-9) count once.
    """
    points = vertices(halfspaces)
    if len(points) < 4:
        return 0.0
    centre = points.mean(axis=0)
    result = 0.0
    for index in _distinct(halfspaces):
        plane = halfspaces[index]
        on_face = points[np.abs(plane.signed_distance(points)) <= 1e3 * TOLERANCE]
        if len(on_face) < 3:
            continue
        normal = np.asarray(plane.normal)
        height = -float(plane.signed_distance(centre[None, :])[0])
        result += _face_area(on_face, normal) * height / 3.0
    return result


def faces(halfspaces: Sequence[Halfspace]) -> list[Halfspace]:
    """The half-spaces whose planes bound the intersection in a face (three or more vertices),
    each once: the same polytope, with the planes that only touch it or lie beyond it left out.
    """
    points = vertices(halfspaces)
    kept = []
    for index in _distinct(halfspaces):
        on_face = np.abs(halfspaces[index].signed_distance(points)) <= 1e3 * TOLERANCE
        if np.count_nonzero(on_face) >= 3:
            kept.append(halfspaces[index])
    return kept


def ordered_faces(halfspaces: Sequence[Halfspace]) -> list[FloatArray]:
    """The faces of the intersection of ``halfspaces``, each (k, 3) m with its corners in
    counter-clockwise order seen from outside."""
    points = vertices(halfspaces)
    result = []
    for index in _distinct(halfspaces):
        plane = halfspaces[index]
        face = points[np.abs(plane.signed_distance(points)) <= 1e3 * TOLERANCE]
        if len(face) < 3:
            continue
        normal = np.asarray(plane.normal)
        offsets = face - face.mean(axis=0)
        u = offsets[np.argmax(np.einsum("ij,ij->i", offsets, offsets))]
        w = np.cross(normal, u)
        result.append(face[np.argsort(np.arctan2(offsets @ w, offsets @ u))])
    return result


def volume_below(faces: Sequence[FloatArray], up: FloatArray, level: float) -> float:
    """m^3, the volume of the convex polytope with ``faces`` (:func:`ordered_faces`) below the
    plane ``up . p = level`` (``up`` (3,) a unit vector, ``level`` m).

    The divergence theorem with the origin on the cutting plane: the volume is a third of the
    sum over the polytope's faces, each clipped to below the plane, of (a corner - origin) .
    (its area vector); the cut face itself lies in the plane and adds nothing. Plain floats: a
    few faces of a few corners, where numpy's per-call cost would dominate.
    """
    ux, uy, uz = (float(v) for v in up)
    ox, oy, oz = ux * level, uy * level, uz * level
    total = 0.0
    for face in faces:
        corners = [(x - ox, y - oy, z - oz) for x, y, z in face.tolist()]
        heights = [ux * x + uy * y + uz * z for x, y, z in corners]
        clipped = []
        count = len(corners)
        for i in range(count):
            a, b = corners[i], corners[(i + 1) % count]
            ha, hb = heights[i], heights[(i + 1) % count]
            if ha <= 0.0:
                clipped.append(a)
            if (ha < 0.0 < hb) or (hb < 0.0 < ha):
                t = ha / (ha - hb)
                clipped.append(tuple(pa + t * (pb - pa) for pa, pb in zip(a, b, strict=True)))
        if len(clipped) < 3:
            continue
        # Newell's area vector of the clipped polygon.
        nx = ny = nz = 0.0
        for i in range(len(clipped)):
            (x1, y1, z1), (x2, y2, z2) = clipped[i], clipped[(i + 1) % len(clipped)]
            nx += y1 * z2 - z1 * y2
            ny += z1 * x2 - x1 * z2
            nz += x1 * y2 - y1 * x2
        x0, y0, z0 = clipped[0]
        total += (x0 * nx + y0 * ny + z0 * nz) / 6.0
    return total
