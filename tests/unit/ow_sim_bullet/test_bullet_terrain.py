"""The terrain's Bullet heightfield tiles: what they cost in memory, and that carving reaches the
collision surface."""

from __future__ import annotations

import subprocess
import sys
import textwrap

import numpy as np
import pybullet as pb

from ow_description.terrain import HeightMap
from ow_sim_bullet.bullet_terrain import BulletTerrain


def test_every_tile_has_a_stand_in_visual_shape():
    """The simulation never draws its terrain: a tile body without a visual shape of its own
    gets TinyRenderer's mesh of the heightfield and a 1024 x 1024 checker texture."""
    client = pb.connect(pb.DIRECT)
    try:
        terrain = BulletTerrain(client, HeightMap(np.zeros((60, 60)), 0.04, 0.0, 0.0), 2, 1)
        assert len(terrain.body_ids) == 9
        for body in terrain.body_ids:
            (shape,) = pb.getVisualShapeData(body, physicsClientId=client)
            assert shape[2] == pb.GEOM_SPHERE
    finally:
        pb.disconnect(client)


def test_the_default_terrains_tiles_take_a_few_mb_not_a_texture_each():
    """In a fresh process: the 126 x 126 map's 25 tiles took 94 MB (3.3 MB of texture each)."""
    script = textwrap.dedent(
        """
        import numpy as np, pybullet as pb
        from ow_description.terrain import HeightMap
        from ow_sim_bullet.bullet_terrain import BulletTerrain

        def private_dirty_mb():
            with open("/proc/self/smaps_rollup") as rollup:
                for line in rollup:
                    if line.startswith("Private_Dirty:"):
                        return int(line.split()[1]) / 1024

        client = pb.connect(pb.DIRECT)
        before = private_dirty_mb()
        terrain = BulletTerrain(client, HeightMap(np.zeros((126, 126)), 0.04, 0.0, 0.0), 2, 1)
        print(len(terrain.body_ids), private_dirty_mb() - before)
        """
    )
    out = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, check=True
    ).stdout.split()
    tiles, grown_mb = int(out[-2]), float(out[-1])
    assert tiles == 25
    assert grown_mb < 30.0, f"{tiles} tiles took {grown_mb:.1f} MB"


def test_a_refreshed_tile_is_what_a_ray_meets():
    """Carving replaces the tiles' heights in place: the collision surface follows."""
    client = pb.connect(pb.DIRECT)
    try:
        heights = np.zeros((60, 60))
        terrain = BulletTerrain(client, HeightMap(heights, 0.04, 0.0, 0.0), 2, 1)
        heights[20:30, 20:30] = -0.1
        assert terrain.refresh(heights, (20, 29), (20, 29)) >= 1
        x = y = 0.04 * 25
        hit = pb.rayTest([x, y, 1.0], [x, y, -1.0], physicsClientId=client)[0]
        assert hit[0] in terrain.body_ids
        assert abs(hit[3][2] - -0.1) < 1e-6
    finally:
        pb.disconnect(client)


def _touches(client: int, terrain: BulletTerrain, x: float, y: float, z: float) -> list[float]:
    """Contact distances (m) of a 1 cm sphere at (x, y, z) with the terrain."""
    shape = pb.createCollisionShape(pb.GEOM_SPHERE, radius=0.01, physicsClientId=client)
    ball = pb.createMultiBody(1.0, shape, basePosition=[x, y, z], physicsClientId=client)
    pb.setCollisionFilterGroupMask(ball, -1, 1, 2, physicsClientId=client)
    pb.performCollisionDetection(physicsClientId=client)
    distances = [p[8] for p in pb.getContactPoints(bodyA=ball, physicsClientId=client)]
    pb.removeBody(ball, physicsClientId=client)
    return distances


def test_a_tile_raised_above_its_box_is_made_anew_and_collides():
    """Regolith deposited on flat ground raises it above the tiles' boxes, which Bullet's
    broadphase culls by: a 5 cm heap was passed through (no contact) until the tile was made
    anew with a box reaching above it, with the old tile's friction."""
    client = pb.connect(pb.DIRECT)
    try:
        heights = np.zeros((51, 51))
        terrain = BulletTerrain(client, HeightMap(heights, 0.04, 0.0, -1.0), 2, 1)
        for body in terrain.body_ids:
            pb.changeDynamics(body, -1, lateralFriction=0.7, physicsClientId=client)
        count = len(terrain.body_ids)
        heights[15:24, 15:24] = 0.05
        assert terrain.refresh(heights, (15, 23), (15, 23)) == 1
        assert len(terrain.body_ids) == count == pb.getNumBodies(physicsClientId=client)
        x, y = 0.04 * 20, -1.0 + 0.04 * 20
        hit = pb.rayTest([x, y, 1.0], [x, y, -1.0], physicsClientId=client)[0]
        tile = hit[0]
        assert tile in terrain.body_ids and abs(hit[3][2] - 0.05) < 1e-6
        top = pb.getAABB(tile, physicsClientId=client)[1][2]
        assert top > 0.05 + 0.04
        assert pb.getDynamicsInfo(tile, -1, physicsClientId=client)[1] == 0.7
        # The ball 5 mm into the heap touches it, as it touches unraised ground.
        assert np.allclose(_touches(client, terrain, x, y, 0.055), -0.005, atol=1e-4)
        assert np.allclose(_touches(client, terrain, 1.8, -0.2, 0.005), -0.005, atol=1e-4)
        # A second raise within the new box's headroom keeps the box.
        heights[16, 16] = 0.08
        terrain.refresh(heights, (16, 16), (16, 16))
        assert pb.getAABB(tile, physicsClientId=client)[1][2] == top
        assert np.allclose(_touches(client, terrain, 0.64, -0.36, 0.085), -0.005, atol=1e-3)
    finally:
        pb.disconnect(client)
