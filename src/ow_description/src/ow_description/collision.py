"""Collision checks of the lander (coal through pinocchio, and terrain height maps), no ROS.

Self-collision and contacts with the lander body and the sample dock are checked on the coal
primitives pinocchio builds from the URDF. The terrain is checked at sample points on the surface
of the same primitives, read from the URDF by :func:`ow_description.shapes.read_collision_shapes`: a
link is below the terrain when one of its points is below the height map's surface.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ow_description.shapes import CollisionShape, read_collision_shapes
from ow_description.terrain import HeightMap

FloatArray = npt.NDArray[np.float64]

#: Link pairs never checked: OceanWATERS' SRDF list (spec section 15.1), adjacent links and pairs
#: that cannot touch, less the pairs of its camera head and lights, which have no collision
#: shapes here. Every other pair of links with shapes is checked: the arm's links against each
#: other, the body, the mast, the antenna panel and the dock; the antenna panel against the body
#: and the dock.
DISABLED_COLLISION_PAIRS: frozenset[frozenset[str]] = frozenset(
    frozenset(pair)
    for pair in (
        # Adjacent.
        ("base_link", "l_ant_foot"),
        ("base_link", "l_shou"),
        ("base_link", "lander_sample_dock0"),
        ("l_ant_foot", "l_ant_panel"),
        ("l_dist", "l_prox"),
        ("l_dist", "l_wrist"),
        ("l_grinder", "l_hand"),
        ("l_hand", "l_scoop"),
        ("l_hand", "l_wrist"),
        ("l_prox", "l_shou"),
        # Never in contact.
        ("l_ant_foot", "l_dist"),
        ("l_ant_foot", "l_prox"),
        ("l_ant_foot", "l_shou"),
        ("l_ant_foot", "lander_sample_dock0"),
        ("l_grinder", "l_scoop"),
        ("l_grinder", "l_wrist"),
        ("l_scoop", "l_wrist"),
        ("l_shou", "lander_sample_dock0"),
    )
)

#: m, side of the square blocks over which the terrain's highest point is pooled for the per-link
#: bounding-sphere test (a link whose sphere is above the highest point under it is skipped).
TERRAIN_BLOCK_M = 0.25

#: Largest square of blocks (per side) whose maxima :meth:`TerrainBlocks.highest_many` looks up;
#: a larger square is bounded by the map's highest point.
WINDOW_BLOCKS = 6

#: Links of the arm that can hit the terrain, base to tool.
ARM_LINKS: tuple[str, ...] = (
    "l_shou",
    "l_prox",
    "l_dist",
    "l_wrist",
    "l_hand",
    "l_scoop",
    "l_grinder",
)


@dataclass(frozen=True)
class CollisionReport:
    """Why a configuration is (not) valid.

    Attributes:
        pairs: (link, link) pairs in contact, empty when none.
        terrain_link: the link reaching deepest below the terrain, or None.
        terrain_penetration: m, how far that link's lowest sample point is below the terrain
            (<= 0 when no link is below it).
    """

    pairs: tuple[tuple[str, str], ...]
    terrain_link: str | None
    terrain_penetration: float

    @property
    def in_collision(self) -> bool:
        """True when any pair touches or any checked link is below the terrain."""
        return bool(self.pairs) or self.terrain_link is not None

    def describe(self) -> str:
        """A sentence for a person: what touches what."""
        parts = [f"{a} touches {b}" for a, b in self.pairs]
        if self.terrain_link is not None:
            parts.append(
                f"{self.terrain_link} is {self.terrain_penetration * 1000:.0f} mm below the terrain"
            )
        return "; ".join(parts) if parts else "collision-free"


class LinkSamples(NamedTuple):
    """Terrain sample points of one link: ``points`` (n, 3) m and their bounding sphere
    (``centre`` (3,) m, ``radius`` m), in the frame of ``joint``, the joint moving the link."""

    link: str
    joint: int
    points: FloatArray
    centre: FloatArray
    radius: float


def _sample_points(shape: CollisionShape) -> FloatArray:
    """(n, 3) m, points on a primitive's surface in its own frame, for terrain checks."""
    if shape.kind == "box":
        half = np.asarray(shape.size, dtype=np.float64) / 2
        signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
        # Corners plus the centres of the faces.
        return np.vstack([signs * half, np.diag(half), -np.diag(half)])
    radius, half_length = shape.size[0], shape.size[1] / 2
    angles = np.linspace(0.0, 2 * np.pi, 12, endpoint=False)
    rim = np.stack([radius * np.cos(angles), radius * np.sin(angles)], axis=1)
    return np.vstack(
        [np.column_stack([rim, np.full(len(rim), z)]) for z in (-half_length, half_length)]
    )


def _terrain_samples(
    model: pin.Model, shapes: Mapping[str, tuple[CollisionShape, ...]]
) -> dict[str, LinkSamples]:
    """Each link's terrain sample points, in the frame of the joint that moves the link."""
    samples = {}
    for link, link_shapes in shapes.items():
        frame = model.frames[model.getFrameId(link, pin.FrameType.BODY)]
        # The link frame in its joint's frame, composed with each shape's origin in the link
        # frame, as pinocchio places the coal objects.
        placements = [
            frame.placement * pin.SE3(shape.rotation, shape.translation) for shape in link_shapes
        ]
        points = np.vstack(
            [
                _sample_points(shape) @ placement.rotation.T + placement.translation
                for shape, placement in zip(link_shapes, placements, strict=True)
            ]
        )
        centre = 0.5 * (points.min(axis=0) + points.max(axis=0))
        radius = float(np.max(np.linalg.norm(points - centre, axis=1)))
        samples[link] = LinkSamples(link, int(frame.parentJoint), points, centre, radius)
    return samples


class TerrainBlocks:
    """The highest terrain point per square block of a height map (max-pooled), for fast
    conservative tests: no bilinear height inside a block exceeds the block's maximum.

    Args:
        terrain: the height map.
        block: m, requested block side (rounded to whole cells).
    """

    def __init__(self, terrain: HeightMap, block: float = TERRAIN_BLOCK_M) -> None:
        self.terrain = terrain
        self.top = float(np.max(terrain.heights))
        self._cells = max(1, round(block / terrain.resolution))
        rows, cols = terrain.shape
        k = self._cells
        # Block (i, j) spans node rows i*k..(i+1)*k and columns j*k..(j+1)*k, both ends included:
        # bilinear heights between cell centres are bounded by the surrounding nodes.
        row_starts = range(0, rows - 1, k)
        col_starts = range(0, cols - 1, k)
        self.maxima = np.array(
            [
                [float(terrain.heights[r : r + k + 1, c : c + k + 1].max()) for c in col_starts]
                for r in row_starts
            ]
        )
        self._windows: FloatArray | None = None

    def highest(self, x: float, y: float, radius: float) -> float:
        """m, an upper bound of the terrain height over the square of half-side ``radius`` m
        around (x, y) m (beyond the grid the terrain continues as its edge)."""
        terrain, k = self.terrain, self._cells
        scale = 1.0 / (terrain.resolution * k)
        last_r, last_c = self.maxima.shape[0] - 1, self.maxima.shape[1] - 1
        c0 = min(max(int((x - radius - terrain.origin_x) * scale), 0), last_c)
        c1 = min(max(int((x + radius - terrain.origin_x) * scale), 0), last_c)
        r0 = min(max(int((y - radius - terrain.origin_y) * scale), 0), last_r)
        r1 = min(max(int((y + radius - terrain.origin_y) * scale), 0), last_r)
        return float(self.maxima[r0 : r1 + 1, c0 : c1 + 1].max())

    def highest_many(self, x: FloatArray, y: FloatArray, radius: float | FloatArray) -> FloatArray:
        """m, :meth:`highest` for many squares at once: ``x``, ``y``, ``radius`` (n,) m (or one
        radius); squares over more than :data:`WINDOW_BLOCKS` blocks a side get the map's
        highest point."""
        terrain, k = self.terrain, self._cells
        scale = 1.0 / (terrain.resolution * k)
        last_r, last_c = self.maxima.shape[0] - 1, self.maxima.shape[1] - 1

        def block(v: FloatArray, origin: float, last: int) -> npt.NDArray[np.intp]:
            return np.clip(np.floor((v - origin) * scale), 0, last).astype(np.intp)

        c0 = block(x - radius, terrain.origin_x, last_c)
        w = block(x + radius, terrain.origin_x, last_c) - c0
        r0 = block(y - radius, terrain.origin_y, last_r)
        h = block(y + radius, terrain.origin_y, last_r) - r0
        out = np.full(len(c0), self.top)
        small = (h < WINDOW_BLOCKS) & (w < WINDOW_BLOCKS)
        out[small] = self._window_maxima()[h[small], w[small], r0[small], c0[small]]
        return out

    def _window_maxima(self) -> FloatArray:
        """(K, K, rows, cols) m: [h, w, r, c] is the maximum of blocks r..r+h, c..c+w (K =
        :data:`WINDOW_BLOCKS`; positions past the grid hold the map's highest point)."""
        if self._windows is not None:
            return self._windows
        m = self.maxima
        rows, cols = m.shape
        windows = np.full((WINDOW_BLOCKS, WINDOW_BLOCKS, rows, cols), self.top)
        over_rows = m
        for h in range(min(WINDOW_BLOCKS, rows)):
            if h:
                over_rows = np.maximum(over_rows[:-1], m[h:])
            over_both = over_rows
            for w in range(min(WINDOW_BLOCKS, cols)):
                if w:
                    over_both = np.maximum(over_both[:, :-1], over_rows[:, w:])
                windows[h, w, : rows - h, : cols - w] = over_both
        self._windows = windows
        return windows


class CollisionChecker:
    """Checks configurations against self-collision, the lander body, the dock and the terrain.

    Not thread-safe: it runs the forward kinematics into the ``data`` it is given.

    Args:
        model: pinocchio model of the lander (its kinematics place the collision geometry).
        data: data of ``model``, shared with the caller (each check overwrites it).
        urdf_path: the robot description ``model`` was built from (its collision shapes).
    """

    def __init__(self, model: pin.Model, data: pin.Data, urdf_path: Path) -> None:
        self.model = model
        self.data = data
        self.geom_model = pin.buildGeomFromUrdf(model, str(urdf_path), pin.GeometryType.COLLISION)
        self._geom_link = [
            model.frames[g.parentFrame].name for g in self.geom_model.geometryObjects
        ]
        self._setup_collision_pairs()
        self.geom_data = pin.GeometryData(self.geom_model)
        # Axis-aligned boxes before the narrow phase: same answers as computeCollisions over all
        # pairs, ~6x faster for a yes/no query (the planner's validity checks).
        self._broadphase = pin.BroadPhaseManager_NaiveCollisionManager(
            model, self.geom_model, self.geom_data
        )
        self._terrain_blocks: TerrainBlocks | None = None
        self._terrain_samples = _terrain_samples(model, read_collision_shapes(urdf_path))
        self._terrain_link_sets: dict[tuple[str, ...], tuple[LinkSamples, ...]] = {}

    def _setup_collision_pairs(self) -> None:
        gm = self.geom_model
        objects = gm.geometryObjects
        for i in range(len(objects)):
            for j in range(i + 1, len(objects)):
                a, b = self._geom_link[i], self._geom_link[j]
                same_body = objects[i].parentJoint == objects[j].parentJoint
                if same_body or frozenset((a, b)) in DISABLED_COLLISION_PAIRS:
                    continue
                gm.addCollisionPair(pin.CollisionPair(i, j))

    def report(
        self,
        q: FloatArray,
        terrain: HeightMap | None = None,
        terrain_links: Iterable[str] = ARM_LINKS,
        terrain_margin: float = 0.0,
        stop_at_first: bool = False,
    ) -> CollisionReport:
        """Check ``q`` against self-collision, the lander body, the dock and the terrain.

        Args:
            q: (9,) rad configuration.
            terrain: height map to check against, or None for no terrain.
            terrain_links: links that must stay above the terrain (e.g. leave out the scoop while
                it digs).
            terrain_margin: m, clearance required above the terrain.
            stop_at_first: return at the first contact found (faster, incomplete report).
        """
        pin.updateGeometryPlacements(self.model, self.data, self.geom_model, self.geom_data, q)
        pairs: list[tuple[str, str]] = []
        if pin.computeCollisions(self.geom_model, self.geom_data, stop_at_first):
            for k, result in enumerate(self.geom_data.collisionResults):
                if result.isCollision():
                    cp = self.geom_model.collisionPairs[k]
                    pair = (self._geom_link[cp.first], self._geom_link[cp.second])
                    if pair not in pairs:
                        pairs.append(pair)
                    if stop_at_first:
                        break
        terrain_link: str | None = None
        depth = 0.0
        if terrain is not None and not (stop_at_first and pairs):
            terrain_link, depth = self._terrain_penetration(terrain, terrain_links, terrain_margin)
        return CollisionReport(tuple(pairs), terrain_link, depth)

    def touches(self, q: FloatArray) -> bool:
        """True when links of ``q`` (9,) rad touch each other, the lander body or the dock (the
        terrain is not looked at); stops at the first contact."""
        return bool(pin.computeCollisions(self.model, self.data, self._broadphase, q, True))

    def terrain_contact(
        self,
        q: FloatArray,
        terrain: HeightMap,
        terrain_links: Iterable[str] = ARM_LINKS,
        terrain_margin: float = 0.0,
    ) -> tuple[str | None, float]:
        """The terrain part of :meth:`report` alone: (the link reaching deepest below
        ``terrain`` + ``terrain_margin`` at ``q`` (9,) rad, or None; m below)."""
        pin.forwardKinematics(self.model, self.data, q)
        return self._terrain_penetration(terrain, terrain_links, terrain_margin)

    def in_collision(
        self,
        q: FloatArray,
        terrain: HeightMap | None = None,
        terrain_links: Iterable[str] = ARM_LINKS,
        terrain_margin: float = 0.0,
    ) -> bool:
        """True when ``q`` collides (see :meth:`report`); stops at the first contact."""
        if self.touches(q):
            return True
        if terrain is None:
            return False
        hit = self._terrain_penetration(terrain, terrain_links, terrain_margin, first_only=True)
        return hit[0] is not None

    def _terrain_penetration(
        self,
        terrain: HeightMap,
        terrain_links: Iterable[str],
        terrain_margin: float,
        first_only: bool = False,
    ) -> tuple[str | None, float]:
        """(deepest link or None, m below the terrain) at the configuration last placed in
        ``self.data`` (joint placements ``oMi`` must be up to date); with ``first_only`` the
        first link found below the terrain instead of the deepest."""
        # Most configurations are well clear of the ground: a link whose bounding sphere lies
        # above the highest terrain point (of the whole map, then of the blocks under the
        # sphere) is skipped, and heights are interpolated only under the sample points that
        # could be below the terrain.
        blocks = self.blocks(terrain)
        top_everywhere = blocks.top + terrain_margin
        oMi = self.data.oMi
        deepest: str | None = None
        depth = 0.0
        for link, joint, local, centre, radius in self.link_samples(terrain_links):
            placement = oMi[joint]
            world = placement.act(centre)
            lowest = world[2] - radius
            if lowest > top_everywhere:
                continue
            top = blocks.highest(world[0], world[1], radius) + terrain_margin
            if lowest > top:
                continue
            pts = local @ placement.rotation.T + placement.translation
            near = pts[pts[:, 2] < top]
            if near.size == 0:
                continue
            below = float(
                np.max(terrain.height_at(near[:, 0], near[:, 1]) + terrain_margin - near[:, 2])
            )
            if below > depth:
                deepest, depth = link, below
                if first_only:
                    break
        return deepest, depth

    def link_samples(self, links: Iterable[str]) -> tuple[LinkSamples, ...]:
        """The sample points of those of ``links`` that have collision geometry (cached)."""
        key = tuple(links)
        found = self._terrain_link_sets.get(key)
        if found is None:
            found = tuple(self._terrain_samples[k] for k in key if k in self._terrain_samples)
            self._terrain_link_sets[key] = found
        return found

    def blocks(self, terrain: HeightMap) -> TerrainBlocks:
        """The max-pooled blocks of ``terrain`` (cached for the last map seen)."""
        if self._terrain_blocks is None or self._terrain_blocks.terrain is not terrain:
            self._terrain_blocks = TerrainBlocks(terrain)
        return self._terrain_blocks
