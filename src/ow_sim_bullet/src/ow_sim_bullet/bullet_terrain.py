"""The terrain height map as Bullet heightfield tiles that can be carved cheaply.

Bullet's heightfield is replaced in place with ``replaceHeightfieldIndex``, which costs about
0.2 us per cell: a whole 251 x 251 map would cost 14 ms per carve, so the map is cut into tiles of
``TILE_CELLS`` cells (neighbouring tiles share their border row and column, so the surface is
continuous) and only the tiles a carve touched are refreshed.

Bullet fixes a heightfield's vertical extent (its bounding box and origin) when the shape is
created. Each tile is therefore created once with one cell at ``floor`` and immediately refreshed
with the true heights: its bounding box then reaches down to ``floor`` and contacts stay correct
however deep the terrain is carved (never below ``floor``). Above its box Bullet would miss the
contacts (its broadphase culls by the box): a tile raised above its box's top (regolith deposited
on it) is made anew, its box reaching :data:`RAISE_HEADROOM` above its new top.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
import pybullet as pb

from ow_description.terrain import HeightMap

FloatArray = npt.NDArray[np.float64]

#: cells per tile side (plus the shared border).
TILE_CELLS = 25
#: m, how far below the lowest initial height the terrain can be carved.
FLOOR_DEPTH = 0.5
#: m, how far above its highest cell a tile made anew after a raise reaches (room for more
#: deposits before it must be made again).
RAISE_HEADROOM = 0.05
#: m, radius of the sphere that stands in for each tile's visual shape. The simulation never
#: draws; without a visual shape of its own, pybullet gives TinyRenderer a mesh of the heightfield
#: and a 1024 x 1024 checker texture for every tile body (3.3 MB each, 90 MB for 25 tiles).
_VISUAL_STAND_IN_RADIUS = 1e-3


class BulletTerrain:
    """A HeightMap as static Bullet heightfield bodies.

    Args:
        client: pybullet physics client id.
        heightmap: the terrain.
        collision_group: Bullet collision filter group of the terrain bodies.
        collision_mask: Bullet collision filter mask of the terrain bodies.
    """

    def __init__(
        self, client: int, heightmap: HeightMap, collision_group: int, collision_mask: int
    ) -> None:
        self._client = client
        self._res = heightmap.resolution
        self._origin = (heightmap.origin_x, heightmap.origin_y)
        self.floor = float(heightmap.heights.min()) - FLOOR_DEPTH
        rows, cols = heightmap.shape
        self._row_starts = list(range(0, max(rows - 1, 1), TILE_CELLS))
        self._col_starts = list(range(0, max(cols - 1, 1), TILE_CELLS))
        self._group, self._mask = collision_group, collision_mask
        self._shapes: dict[tuple[int, int], int] = {}
        self._bodies: dict[tuple[int, int], int] = {}
        #: m, the top of each tile's box (higher cells would not collide).
        self._ceilings: dict[tuple[int, int], float] = {}
        self.body_ids: list[int] = []
        self._visual = pb.createVisualShape(
            pb.GEOM_SPHERE, radius=_VISUAL_STAND_IN_RADIUS, physicsClientId=client
        )
        for r0 in self._row_starts:
            for c0 in self._col_starts:
                tile = self._tile(heightmap.heights, r0, c0)
                self.body_ids.append(self._make_tile(tile, r0, c0, float(tile.max())))

    def _make_tile(self, tile: FloatArray, r0: int, c0: int, ceiling: float) -> int:
        """Make the body of the tile at (r0, c0) with heights ``tile``, its box reaching from
        :attr:`floor` to ``ceiling`` (m, >= the tile's highest cell); returns the body."""
        guarded = tile.copy()
        guarded[0, 0] = self.floor
        guarded[-1, -1] = max(float(guarded[-1, -1]), ceiling)
        shape = self._shape(guarded)
        z_centre = (self.floor + float(guarded.max())) / 2.0
        x = self._origin[0] + (c0 + (tile.shape[1] - 1) / 2.0) * self._res
        y = self._origin[1] + (r0 + (tile.shape[0] - 1) / 2.0) * self._res
        body = pb.createMultiBody(
            baseMass=0.0,
            baseCollisionShapeIndex=shape,
            baseVisualShapeIndex=self._visual,
            basePosition=[x, y, z_centre],
            physicsClientId=self._client,
        )
        pb.setCollisionFilterGroupMask(
            body, -1, self._group, self._mask, physicsClientId=self._client
        )
        self._shape(tile, replace=shape)
        self._shapes[(r0, c0)] = shape
        self._bodies[(r0, c0)] = body
        self._ceilings[(r0, c0)] = float(guarded.max())
        return body

    @staticmethod
    def _tile(heights: FloatArray, r0: int, c0: int) -> FloatArray:
        return heights[r0 : r0 + TILE_CELLS + 1, c0 : c0 + TILE_CELLS + 1]

    def _shape(self, tile: FloatArray, replace: int = -1) -> int:
        rows, cols = tile.shape
        kwargs = {}
        if replace >= 0:
            kwargs["replaceHeightfieldIndex"] = replace
        # Bullet's "rows" run along x: numHeightfieldRows is our column count.
        return int(
            pb.createCollisionShape(
                shapeType=pb.GEOM_HEIGHTFIELD,
                meshScale=[self._res, self._res, 1.0],
                heightfieldData=tile.ravel().tolist(),
                numHeightfieldRows=cols,
                numHeightfieldColumns=rows,
                physicsClientId=self._client,
                **kwargs,
            )
        )

    def refresh(self, heights: FloatArray, rows: tuple[int, int], cols: tuple[int, int]) -> int:
        """Copy changed heights into the tiles that overlap cells rows x cols (inclusive bounds).

        A tile raised above the top of its box is made anew (:data:`RAISE_HEADROOM`), with
        the lateral friction of the body it replaces; :attr:`body_ids` then names the new body.

        Args:
            heights: (rows, cols) m, the whole current height map (never below :attr:`floor`).
            rows: first and last changed row.
            cols: first and last changed column.

        Returns:
            Number of tiles refreshed.
        """
        refreshed = 0
        for r0 in self._row_starts:
            if r0 > rows[1] or r0 + TILE_CELLS < rows[0]:
                continue
            for c0 in self._col_starts:
                if c0 > cols[1] or c0 + TILE_CELLS < cols[0]:
                    continue
                tile = self._tile(heights, r0, c0)
                top = float(tile.max())
                if top > self._ceilings[(r0, c0)]:
                    self._remake(tile, r0, c0, top + RAISE_HEADROOM)
                    refreshed += 1
                    continue
                self._shape(tile, replace=self._shapes[(r0, c0)])
                # Bullet keeps contact points cached between a tool and the old surface for as
                # long as the two bodies do not move apart. Re-adding the tile to the collision
                # world (what a filter change does) drops them.
                pb.setCollisionFilterGroupMask(
                    self._bodies[(r0, c0)],
                    -1,
                    self._group,
                    self._mask,
                    physicsClientId=self._client,
                )
                refreshed += 1
        return refreshed

    def _remake(self, tile: FloatArray, r0: int, c0: int, ceiling: float) -> None:
        """Replace the tile's body by one whose box reaches ``ceiling`` (m)."""
        old = self._bodies[(r0, c0)]
        friction = pb.getDynamicsInfo(old, -1, physicsClientId=self._client)[1]
        pb.removeBody(old, physicsClientId=self._client)
        body = self._make_tile(tile, r0, c0, ceiling)
        pb.changeDynamics(body, -1, lateralFriction=friction, physicsClientId=self._client)
        self.body_ids[self.body_ids.index(old)] = body

    def remove(self) -> None:
        """Delete the terrain bodies from the simulation.

        Their heightfield shapes stay in the client: pybullet (3.2.x) keeps a shape marked used
        once a body was made with it and refuses to remove it (a warning per shape, ~3 kB each).
        """
        for body in self.body_ids:
            pb.removeBody(body, physicsClientId=self._client)
        self.body_ids.clear()
        self._shapes.clear()
        self._bodies.clear()
        self._ceilings.clear()
