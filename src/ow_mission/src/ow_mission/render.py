"""Headless pictures of the lander arm on its terrain (pybullet's TinyRenderer, no GPU, no ROS).

:class:`SceneRenderer` keeps a pybullet client with the URDF's visual shapes (primitives coloured
per part) and the terrain height map as a heightfield, so a sequence of frames (a replay) loads the
robot once and rebuilds the terrain only when it changes (drawn once per terrain without shadows);
:func:`render_scene` renders one picture.
:func:`fit_camera` places the camera from the extents of what must be seen, so nothing is cut off.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt
import pybullet as pb

from ow_description.description import URDF_PATH
from ow_description.terrain import HeightMap

#: Colour of the terrain (RGBA): a plain pale ice; the heightfield's own checker texture is
#: removed (TinyRenderer drew it as a hard-edged blue half-plane across the terrain).
TERRAIN_RGBA = (0.80, 0.82, 0.86, 1.0)
FloatArray = npt.NDArray[np.float64]
DepthArray = npt.NDArray[np.float32]

#: deg, vertical field of view of every camera.
FOV_DEG = 50.0


@dataclass(frozen=True)
class Camera:
    """A camera looking at a point of base_link.

    Attributes:
        target: (3,) m, point looked at.
        distance: m, from the target.
        yaw: deg, about base_link z (pybullet's debug-camera convention).
        pitch: deg, negative looks down.
        width: px.
        height: px.
    """

    target: tuple[float, float, float] = (1.2, 0.0, 0.1)
    distance: float = 3.2
    yaw: float = 35.0
    pitch: float = -25.0
    width: int = 1024
    height: int = 768


def camera_axes(yaw: float, pitch: float) -> tuple[FloatArray, FloatArray, FloatArray]:
    """(right, up, forward) unit vectors in base_link of a camera at ``yaw``/``pitch`` (deg),
    as pybullet's ``computeViewMatrixFromYawPitchRoll`` (z up) orients it."""
    view = np.reshape(
        pb.computeViewMatrixFromYawPitchRoll((0.0, 0.0, 0.0), 1.0, yaw, pitch, 0.0, 2), (4, 4)
    )
    # Column-major OpenGL: the rotation's rows are the camera axes; the camera looks along -z.
    rotation = view[:3, :3].T
    return rotation[0], rotation[1], -rotation[2]


def fit_camera(
    points: npt.ArrayLike,
    yaw: float = 35.0,
    pitch: float = -25.0,
    width: int = 1024,
    height: int = 768,
    margin: float = 0.04,
) -> Camera:
    """A camera at ``yaw``/``pitch`` (deg) that sees every one of ``points`` ((N, 3) m, base_link)
    and no more than it must: the points fill the image but for ``margin`` (a fraction of the
    image size) on each side.

    The perspective projection is solved point by point: the target is moved until the points'
    extent is centred, and the distance is the smallest that keeps each inside the frame.
    """
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    right, up, forward = camera_axes(yaw, pitch)
    tan_v = math.tan(math.radians(FOV_DEG) / 2) * (1.0 - 2.0 * margin)
    tan_h = math.tan(math.radians(FOV_DEG) / 2) * width / height * (1.0 - 2.0 * margin)
    target = (pts.min(axis=0) + pts.max(axis=0)) / 2

    def solve(target: FloatArray) -> tuple[float, FloatArray, FloatArray]:
        rel = pts - target
        x, y, depth = rel @ right, rel @ up, rel @ forward
        # A point at (x, y) is inside when |x| <= (distance + depth) tan_h, and so for y.
        distance = float(max(np.max(np.abs(x) / tan_h - depth), np.max(np.abs(y) / tan_v - depth)))
        z = distance + depth
        return distance, x / (z * tan_h), y / (z * tan_v)

    for _ in range(8):
        # Move the target to the middle of the points' projected extent, then solve again.
        distance, u, v = solve(target)
        shift_u = (u.max() + u.min()) / 2 * distance * tan_h
        shift_v = (v.max() + v.min()) / 2 * distance * tan_v
        target = target + right * shift_u + up * shift_v
    distance, _, _ = solve(target)
    return Camera(
        (float(target[0]), float(target[1]), float(target[2])),
        max(distance, 0.1),
        yaw,
        pitch,
        width,
        height,
    )


def _link_colours(
    body: int, client: int
) -> tuple[dict[int, tuple[float, ...]], dict[int, tuple[float, ...]]]:
    """The colour (RGBA) of each link of ``body`` with visual shapes (the URDF gives each link
    one): (the links no joint moves: the base and what is fixed to it, the lander's body and
    the sample dock; the others)."""
    static = {-1}
    for i in range(pb.getNumJoints(body, physicsClientId=client)):
        info = pb.getJointInfo(body, i, physicsClientId=client)
        if info[2] == pb.JOINT_FIXED and info[16] in static:
            static.add(i)
    fixed: dict[int, tuple[float, ...]] = {}
    moving: dict[int, tuple[float, ...]] = {}
    for shape in pb.getVisualShapeData(body, physicsClientId=client):
        (fixed if shape[1] in static else moving).setdefault(shape[1], tuple(shape[7]))
    return fixed, moving


def _show_links(body: int, client: int, colours: Mapping[int, tuple[float, ...]], on: bool) -> None:
    """Show or hide (alpha 0: TinyRenderer skips them) the links of ``colours``."""
    for link, rgba in colours.items():
        colour = list(rgba) if on else [*rgba[:3], 0.0]
        pb.changeVisualShape(body, link, rgbaColor=colour, physicsClientId=client)


class SceneRenderer:
    """The lander (and a terrain) in a pybullet DIRECT client, rendered on demand.

    Without shadows nothing in the picture depends on two bodies at once, so what does not move
    is drawn once and each frame draws only the moving links, laid over the rest by depth: the
    same pixels as drawing everything together. The terrain is drawn once per terrain and camera
    (it was two thirds of TinyRenderer's work in a replay frame), the lander's body and the dock
    once per camera (a third of the robot's), each with everything else hidden. Shadowed
    pictures draw everything together. One client holds it all: each pybullet client costs
    about 28 MB, and a report runs three renderers at once.

    Args:
        urdf_path: robot description.

    Use as a context manager, or call :meth:`close`.
    """

    def __init__(self, urdf_path: Path = URDF_PATH) -> None:
        self._urdf_path = urdf_path
        self._client = pb.connect(pb.DIRECT)
        self._body = -1
        self._joints: dict[str, int] = {}
        #: rad by joint index: the pose, kept to pose the robot again when it is reloaded
        self._pose: dict[int, float] = {}
        #: the terrain the client holds (shown or hidden) and its body (-1: none)
        self._held: HeightMap | None = None
        self._ground = -1
        #: what is shown now: the static links, the moving links, the terrain
        self._shown = (True, True, False)
        self._load(None)
        self._terrain: HeightMap | None = None
        #: (terrain, camera, its picture (h, w, 3), its depth buffer (h, w)) drawn last, the
        #: static links included
        self._layer: tuple[HeightMap, Camera, npt.NDArray[np.uint8], DepthArray] | None = None
        #: (camera, picture, depth) of the static links alone
        self._static_layer: tuple[Camera, npt.NDArray[np.uint8], DepthArray] | None = None

    def __enter__(self) -> SceneRenderer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """Disconnect the pybullet client."""
        if self._client >= 0:
            pb.disconnect(self._client)
            self._client = -1

    def set_joints(self, joint_positions: Mapping[str, float]) -> None:
        """Pose the robot: rad by joint name; joints not named keep their position."""
        for name, value in joint_positions.items():
            index = self._joints.get(name)
            if index is not None:
                self._pose[index] = float(value)
                pb.resetJointState(self._body, index, float(value), physicsClientId=self._client)

    def _hold(self, terrain: HeightMap) -> None:
        """Hold ``terrain`` beside the robot. A change empties the client and loads the robot
        again in its pose: pybullet keeps a removed heightfield body's collision shape and
        TinyRenderer's mesh of it until the client is emptied (it refuses to remove a shape it
        counts as used), about 9 MB per 126 x 126 terrain, and a replay goes through the
        mission's terrains."""
        if terrain is not self._held:
            self._load(terrain)

    def _load(self, terrain: HeightMap | None) -> None:
        """Empty the client, then load the robot in its pose and ``terrain`` (None: none),
        everything shown."""
        pb.resetSimulation(physicsClientId=self._client)
        self._body = pb.loadURDF(
            str(self._urdf_path), useFixedBase=True, physicsClientId=self._client
        )
        self._joints = {
            pb.getJointInfo(self._body, i, physicsClientId=self._client)[1].decode(): i
            for i in range(pb.getNumJoints(self._body, physicsClientId=self._client))
        }
        for index, value in self._pose.items():
            pb.resetJointState(self._body, index, value, physicsClientId=self._client)
        self._static_colours, self._moving_colours = _link_colours(self._body, self._client)
        self._ground = -1 if terrain is None else _add_terrain(terrain, self._client)
        self._held = terrain
        self._shown = (True, True, terrain is not None)

    def _show(self, static: bool, moving: bool, ground: bool) -> None:
        """Show or hide the static links, the moving links and the terrain held."""
        shown = self._shown
        if static != shown[0]:
            _show_links(self._body, self._client, self._static_colours, static)
        if moving != shown[1]:
            _show_links(self._body, self._client, self._moving_colours, moving)
        if ground != shown[2] and self._ground >= 0:
            rgba = [*TERRAIN_RGBA[:3], TERRAIN_RGBA[3] if ground else 0.0]
            pb.changeVisualShape(self._ground, -1, rgbaColor=rgba, physicsClientId=self._client)
        self._shown = (static, moving, ground and self._ground >= 0)

    def set_terrain(self, terrain: HeightMap | None) -> None:
        """Show ``terrain`` (None: no terrain); the heightfield is rebuilt only when it changed
        (pass the same object for the same terrain)."""
        self._terrain = terrain

    def robot_points(self) -> npt.NDArray[np.float64]:
        """(8 * links, 3) m: the corners of every link's bounding box in the current pose."""
        corners = []
        for link in range(-1, len(self._joints)):
            low, high = pb.getAABB(self._body, link, physicsClientId=self._client)
            for cx in (low[0], high[0]):
                for cy in (low[1], high[1]):
                    for cz in (low[2], high[2]):
                        corners.append((cx, cy, cz))
        return np.asarray(corners, dtype=np.float64)

    def render(self, camera: Camera, shadow: bool = True) -> npt.NDArray[np.uint8]:
        """(height, width, 3) RGB image from ``camera``; ``shadow`` off is faster and, at small
        sizes, free of TinyRenderer's shadow acne (stripes on flat faces)."""
        terrain = self._terrain
        if terrain is not None:
            self._hold(terrain)
        if shadow or terrain is None:
            self._show(True, True, terrain is not None)
            return _draw(self._client, camera, shadow)[0]
        layer = self._layer
        if layer is None or layer[0] is not terrain or layer[1] != camera:
            static, static_depth = self._static_picture(camera)
            self._show(False, False, True)
            ground, ground_depth = _draw(self._client, camera, False)
            layer = (terrain, camera, *_nearer(static, static_depth, ground, ground_depth))
            self._layer = layer
        self._show(False, True, False)
        robot, robot_depth = _draw(self._client, camera, False)
        _, _, rest, rest_depth = layer
        return _nearer(robot, robot_depth, rest, rest_depth)[0]

    def _static_picture(self, camera: Camera) -> tuple[npt.NDArray[np.uint8], DepthArray]:
        """The static links alone from ``camera``: picture and depth buffer (kept per camera)."""
        kept = self._static_layer
        if kept is None or kept[0] != camera:
            self._show(True, False, False)
            kept = (camera, *_draw(self._client, camera, False))
            self._static_layer = kept
        return kept[1], kept[2]

    def picture(
        self,
        joint_positions: Mapping[str, float],
        terrain: HeightMap | None = None,
        camera: Camera | None = None,
        around: Iterable[tuple[float, float, float]] = (),
    ) -> npt.NDArray[np.uint8]:
        """The lander at ``joint_positions`` on ``terrain`` (see :func:`render_scene`)."""
        self.set_joints(joint_positions)
        cam = camera or fit_camera(scene_points(self.robot_points(), around))
        self.set_terrain(None if terrain is None else visible_terrain(terrain, cam))
        return self.render(cam)


def scene_points(
    robot: npt.NDArray[np.float64], around: Iterable[tuple[float, float, float]] = ()
) -> npt.NDArray[np.float64]:
    """The points a camera must see: the robot's (N, 3) m and the ``around`` points (m)."""
    extra = np.asarray(list(around), dtype=np.float64).reshape(-1, 3)
    return np.vstack([robot, extra])


def render_scene(
    joint_positions: Mapping[str, float],
    terrain: HeightMap | None = None,
    camera: Camera | None = None,
    urdf_path: Path = URDF_PATH,
    around: Iterable[tuple[float, float, float]] = (),
) -> npt.NDArray[np.uint8]:
    """Render the lander at ``joint_positions`` on ``terrain``.

    Args:
        joint_positions: rad, by joint name; joints not named stay at 0.
        terrain: height map drawn under the lander, or None.
        camera: where to look from (default: :func:`fit_camera` on the whole robot and the
            ``around`` points, 1024x768).
        urdf_path: robot description.
        around: (x, y, z) m points of base_link the default camera must also see.

    Returns:
        (height, width, 3) RGB image.
    """
    with SceneRenderer(urdf_path) as scene:
        return scene.picture(joint_positions, terrain, camera, around)


def crop_terrain(terrain: HeightMap, points: npt.ArrayLike, margin: float = 0.2) -> HeightMap:
    """The part of ``terrain`` under the bounding box of ``points`` ((N, 3) m) grown by
    ``margin`` m (TinyRenderer's cost grows with the triangles it draws)."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    xs, ys = terrain.cell_centres()
    cols = np.flatnonzero((xs >= pts[:, 0].min() - margin) & (xs <= pts[:, 0].max() + margin))
    rows = np.flatnonzero((ys >= pts[:, 1].min() - margin) & (ys <= pts[:, 1].max() + margin))
    if len(cols) < 2 or len(rows) < 2:
        return terrain
    heights = terrain.heights[rows[0] : rows[-1] + 1, cols[0] : cols[-1] + 1]
    return HeightMap(heights, terrain.resolution, float(xs[cols[0]]), float(ys[rows[0]]))


def visible_terrain(terrain: HeightMap, camera: Camera, reach: float = 3.0) -> HeightMap:
    """The part of ``terrain`` that ``camera`` sees: under the rays through the image's corners
    and edge midpoints down to the terrain's lowest point, each at most ``reach`` camera
    distances long (rays above the horizon would never meet it)."""
    right, up, forward = camera_axes(camera.yaw, camera.pitch)
    eye = np.asarray(camera.target) - forward * camera.distance
    tan_v = math.tan(math.radians(FOV_DEG) / 2)
    tan_h = tan_v * camera.width / camera.height
    low = float(terrain.heights.min())
    ends = []
    for u in (-1.0, 0.0, 1.0):
        for v in (-1.0, 0.0, 1.0):
            ray = forward + right * u * tan_h + up * v * tan_v
            longest = reach * camera.distance / float(np.linalg.norm(ray))
            hit = (low - eye[2]) / ray[2] if ray[2] < 0 else longest
            ends.append(eye + ray * min(hit, longest))
    return crop_terrain(terrain, np.vstack([ends, [camera.target]]))


def _nearer(
    a: npt.NDArray[np.uint8], a_depth: DepthArray, b: npt.NDArray[np.uint8], b_depth: DepthArray
) -> tuple[npt.NDArray[np.uint8], DepthArray]:
    """Two pictures of the same projection laid over each other by depth: each pixel from the
    nearer (``a`` where ``a`` is strictly nearer), and the nearer depth."""
    nearer = a_depth < b_depth
    return np.where(nearer[:, :, None], a, b), np.where(nearer, a_depth, b_depth)


def _draw(client: int, camera: Camera, shadow: bool) -> tuple[npt.NDArray[np.uint8], DepthArray]:
    """What ``client`` holds seen from ``camera`` with TinyRenderer: (height, width, 3) RGB and
    (height, width) depth buffer (1: nothing drawn)."""
    view = pb.computeViewMatrixFromYawPitchRoll(
        camera.target, camera.distance, camera.yaw, camera.pitch, 0.0, 2, physicsClientId=client
    )
    far = max(30.0, 3.0 * camera.distance)
    projection = pb.computeProjectionMatrixFOV(
        FOV_DEG, camera.width / camera.height, 0.05, far, physicsClientId=client
    )
    _, _, rgba, depth, _ = pb.getCameraImage(
        camera.width,
        camera.height,
        view,
        projection,
        renderer=pb.ER_TINY_RENDERER,
        lightDirection=[0.4, -0.6, 1.0],
        shadow=int(shadow),
        physicsClientId=client,
    )
    shape = (camera.height, camera.width)
    image = np.reshape(np.asarray(rgba, dtype=np.uint8), (*shape, 4))
    return np.ascontiguousarray(image[:, :, :3]), np.reshape(
        np.asarray(depth, dtype=np.float32), shape
    )


def _add_terrain(terrain: HeightMap, client: int) -> int:
    """Add ``terrain`` to ``client`` as a heightfield body in :data:`TERRAIN_RGBA`; its id."""
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
    pb.changeVisualShape(
        ground, -1, rgbaColor=list(TERRAIN_RGBA), textureUniqueId=-1, physicsClientId=client
    )
    return int(ground)
