"""Headless pictures of the lander arm on its terrain (pybullet's TinyRenderer, no GPU, no ROS).

:func:`render_scene` draws the URDF's visual shapes (primitives coloured per part) with the terrain
height map as a heightfield.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt
import pybullet as pb

from ow_lander.description import URDF_PATH
from ow_lander.terrain import HeightMap


@dataclass(frozen=True)
class Camera:
    """A camera looking at a point of base_link.

    Attributes:
        target: (3,) m, point looked at.
        distance: m, from the target.
        yaw: deg, about base_link z (0 looks along +y... as pybullet's debug camera).
        pitch: deg, negative looks down.
        width: px.
        height: px.
    """

    target: tuple[float, float, float] = (1.2, 0.0, 0.1)
    distance: float = 3.2
    yaw: float = 35.0
    pitch: float = -25.0
    width: int = 640
    height: int = 480


def render_scene(
    joint_positions: Mapping[str, float],
    terrain: HeightMap | None = None,
    camera: Camera | None = None,
    urdf_path: Path = URDF_PATH,
) -> npt.NDArray[np.uint8]:
    """Render the lander at ``joint_positions`` on ``terrain``.

    Args:
        joint_positions: rad, by joint name; joints not named stay at 0.
        terrain: height map drawn under the lander, or None.
        camera: where to look from (default: front-left of the arm's workspace).
        urdf_path: robot description.

    Returns:
        (height, width, 3) RGB image.
    """
    cam = camera or Camera()
    client = pb.connect(pb.DIRECT)
    try:
        body = pb.loadURDF(str(urdf_path), useFixedBase=True, physicsClientId=client)
        for i in range(pb.getNumJoints(body, physicsClientId=client)):
            name = pb.getJointInfo(body, i, physicsClientId=client)[1].decode()
            if name in joint_positions:
                pb.resetJointState(body, i, joint_positions[name], physicsClientId=client)
        if terrain is not None:
            _add_terrain(terrain, client)
        view = pb.computeViewMatrixFromYawPitchRoll(
            cam.target, cam.distance, cam.yaw, cam.pitch, 0.0, 2, physicsClientId=client
        )
        projection = pb.computeProjectionMatrixFOV(
            50.0, cam.width / cam.height, 0.05, 30.0, physicsClientId=client
        )
        _, _, rgba, _, _ = pb.getCameraImage(
            cam.width,
            cam.height,
            view,
            projection,
            renderer=pb.ER_TINY_RENDERER,
            lightDirection=[0.4, -0.6, 1.0],
            shadow=1,
            physicsClientId=client,
        )
    finally:
        pb.disconnect(client)
    image = np.reshape(np.asarray(rgba, dtype=np.uint8), (cam.height, cam.width, 4))
    return np.ascontiguousarray(image[:, :, :3])


def _add_terrain(terrain: HeightMap, client: int) -> None:
    rows, cols = terrain.shape
    heights = terrain.heights
    low, high = float(heights.min()), float(heights.max())
    shape = pb.createCollisionShape(
        pb.GEOM_HEIGHTFIELD,
        meshScale=[terrain.resolution, terrain.resolution, 1.0],
        # Bullet indexes the data x-fastest: row r (y), column c (x) -> r * cols + c.
        heightfieldData=heights.ravel().tolist(),
        numHeightfieldRows=cols,
        numHeightfieldColumns=rows,
        physicsClientId=client,
    )
    # Bullet centres a heightfield on its bounding box.
    centre = (
        (terrain.origin_x + terrain.x_max) / 2,
        (terrain.origin_y + terrain.y_max) / 2,
        (low + high) / 2,
    )
    ground = pb.createMultiBody(0, shape, basePosition=centre, physicsClientId=client)
    pb.changeVisualShape(ground, -1, rgbaColor=[0.82, 0.86, 0.92, 1.0], physicsClientId=client)
