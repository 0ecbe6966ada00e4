"""Headless camera images of the lander on its terrain: pybullet's TinyRenderer on the CPU, in a
DIRECT client of its own, lit by the sun and the mast's two spot lights. No ROS.

TinyRenderer has one directional light, shadows that only darken to 80 %, and no point or spot
lights, so it draws only the geometry and the light is added up here (deferred shading):

1. per camera, one unlit TinyRenderer pass: the **albedo** (ambient 1, diffuse 0), the depth
   buffer and the segmentation mask (the sky where nothing was drawn);
2. each pixel's point in base_link from the depth buffer, and its normal: on the terrain the
   mesh's vertex normals interpolated (as a shaded mesh), elsewhere from neighbouring points;
3. the **sun**: ``E_sun * max(0, n.s)``, in shadow where a shadow map says so: one more unlit
   pass, seen from the sun (a camera 1 km away whose field of view just covers the points of
   step 2, so that a texel is 1-3 mm), each point compared with the depth there;
4. the **spot lights**: ``I * E_1m * max(0, n.l) / d^2`` inside each light's cone (hard-edged, no
   shadows: OceanWATERS' lights cast none);
5. ``albedo * (ambient + lights + sun)``: the albedo-weighted irradiance (W/m^2) each pixel
   integrates over the exposure (:func:`expose`).

The lander is drawn from the URDF (posed from joint positions), less any primitive of
``l_ant_panel`` that would hold a camera inside it (a box drawn around the whole antenna would
blind the cameras; OceanWATERS' panel mesh is open in front of them). The terrain is a mesh of
the height map with the regolith texture of :mod:`ow_cameras.texture`.
"""

from __future__ import annotations

import math
import tempfile
import xml.etree.ElementTree as ET
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import numpy.typing as npt
import pybullet as pb

from ow_cameras.errors import RenderError
from ow_cameras.rig import (
    LEFT_OPTICAL_FRAME,
    PANEL_LINK,
    RIGHT_OPTICAL_FRAME,
    Pinhole,
    Spotlight,
    X_panel,
    transform,
)
from ow_cameras.texture import TILE_M, write_texture
from ow_description.description import URDF_PATH
from ow_description.terrain import HeightMap

FloatArray = npt.NDArray[np.float64]
Float32Array = npt.NDArray[np.float32]
ByteImage = npt.NDArray[np.uint8]

#: m, the cameras' clip planes (OceanWATERS: near 0.1; its far 200 km would leave the depth
#: buffer no precision, and nothing stands beyond 50 m here).
NEAR_M = 0.1
FAR_M = 50.0
#: px, the longer side of the sun's shadow map.
SUN_MAP_PX = 1024
#: m, distance of the shadow map's camera: far enough that its perspective is parallel to 0.1 %.
SUN_DISTANCE_M = 1000.0
#: m, depth range of the shadow map's camera either side of the scene's centre.
SUN_DEPTH_RANGE_M = 20.0
#: m, constant part of the shadow test's bias (surfaces do not shadow themselves).
SHADOW_BIAS_M = 0.004
#: The points on the panel (``l_ant_panel`` frame, m) no visual may enclose: the cameras'
#: optical centres. A primitive of the URDF that holds one would blind that camera.
CAMERA_CENTRES_PANEL: tuple[tuple[float, float, float], ...] = tuple(
    (float(X[0, 3]), float(X[1, 3]), float(X[2, 3]))
    for X in (X_panel(LEFT_OPTICAL_FRAME), X_panel(RIGHT_OPTICAL_FRAME))
)
#: Vertices of the terrain mesh at most (pybullet takes 131072); larger maps are subsampled.
MAX_TERRAIN_VERTICES = 100_000


@dataclass(frozen=True)
class Lighting:
    """The light falling on the scene.

    Attributes:
        sun_direction: (3,) unit vector towards the sun, base_link (z <= 0: below the horizon).
        sun_irradiance_w_m2: W/m^2 on a surface facing the sun.
        ambient_w_m2: W/m^2 on every surface.
        light_irradiance_at_1m_w_m2: W/m^2 at 1 m on a surface facing a light at intensity 1.
        cone_angle_rad: rad, each light's cone, edge to edge.
        intensities: name ("left", "right") -> intensity, 0 to 1.
    """

    sun_direction: FloatArray
    sun_irradiance_w_m2: float
    ambient_w_m2: float
    light_irradiance_at_1m_w_m2: float
    cone_angle_rad: float
    intensities: Mapping[str, float]

    @property
    def sun_up(self) -> bool:
        """Whether the sun shines on the scene."""
        return bool(self.sun_direction[2] > 0.0) and self.sun_irradiance_w_m2 > 0.0


@dataclass(frozen=True)
class View:
    """What one camera sees.

    Attributes:
        irradiance: (height, width, 3) W/m^2, albedo-weighted irradiance per RGB channel (0 for
            the sky).
        depth_m: (height, width) m, depth along the optical axis (inf for the sky).
    """

    irradiance: Float32Array
    depth_m: Float32Array


def expose(irradiance: Float32Array, exposure_s: float, saturation_j_m2: float) -> ByteImage:
    """An 8-bit RGB image of ``irradiance`` (W/m^2) exposed ``exposure_s`` s: linear, 255 at
    ``saturation_j_m2`` J/m^2 and above.

    Returns:
        (height, width, 3) uint8.
    """
    scale = 255.0 * exposure_s / saturation_j_m2
    return np.clip(np.rint(irradiance * scale), 0, 255).astype(np.uint8)


def _matrix(values: Sequence[float]) -> FloatArray:
    """(4, 4) of pybullet's column-major 16-list."""
    return np.asarray(values, dtype=np.float64).reshape(4, 4).T


def _linear_depth(buffer: Float32Array, near: float, far: float) -> FloatArray:
    """m, eye-space depth of an OpenGL depth buffer (0..1)."""
    return far * near / (far - (far - near) * buffer.astype(np.float64))


def _look(eye: FloatArray, forward: FloatArray, up: FloatArray) -> list[float]:
    return list(pb.computeViewMatrix(eye.tolist(), (eye + forward).tolist(), up.tolist()))


def _dot(vectors: npt.NDArray[Any], v: npt.NDArray[Any]) -> npt.NDArray[Any]:
    """``vectors`` (..., 3) dotted with ``v`` (3,) or with ``vectors``' twin (..., 3), written out
    (numpy's matmul hands thin products to OpenBLAS, and einsum is slow on them: each several
    times slower here, much more on a loaded machine)."""
    return vectors[..., 0] * v[..., 0] + vectors[..., 1] * v[..., 1] + vectors[..., 2] * v[..., 2]


def _rows(M: FloatArray, points: Float32Array) -> list[Float32Array]:
    """Each row of ``M @ [p, 1]`` ((n,) each) for ``points`` (n, 3); M is (k, 4)."""
    x, y, z = points[:, 0], points[:, 1], points[:, 2]
    m = M.astype(np.float32)
    return [x * r[0] + y * r[1] + z * r[2] + r[3] for r in m]


@dataclass
class _Pass:
    """One camera's TinyRenderer pass and the geometry that follows from it (float32 arrays of
    the image's shape; only pixels in ``mask`` are meaningful)."""

    albedo: Float32Array  # (h, w, 3), 0..1
    mask: npt.NDArray[np.bool_]  # (h, w) something drawn
    depth: Float32Array  # (h, w) m along the optical axis
    points: Float32Array  # (h, w, 3) m, base_link
    normals: Float32Array  # (h, w, 3) unit, facing the camera
    eye: FloatArray  # (3,) m


class SceneRenderer:
    """The lander and its terrain in a pybullet DIRECT client of its own, for TinyRenderer.

    Use it from one thread only (pybullet clients are not thread-safe); :meth:`close` (or a
    ``with`` block) disconnects it.

    Args:
        urdf_path: the robot description.
        texture_seed: seed of the terrain's regolith texture.

    Raises:
        RenderError: the URDF cannot be loaded.
    """

    def __init__(self, urdf_path: Path = URDF_PATH, texture_seed: int = 0) -> None:
        self._tmp = tempfile.TemporaryDirectory(prefix="ow_cameras_")
        self.client = pb.connect(pb.DIRECT)
        try:
            model = Path(self._tmp.name) / "lander_for_cameras.urdf"
            model.write_text(_unblinded(urdf_path, PANEL_LINK, CAMERA_CENTRES_PANEL))
            self.robot = pb.loadURDF(str(model), useFixedBase=True, physicsClientId=self.client)
            texture = write_texture(Path(self._tmp.name) / "regolith.png", texture_seed)
            self._texture = pb.loadTexture(str(texture), physicsClientId=self.client)
        except (pb.error, OSError) as error:
            self.close()
            msg = f"cannot load {urdf_path} for the cameras: {error}"
            raise RenderError(msg) from error
        self._joints: dict[str, int] = {}
        self._links: dict[str, int] = {}
        for index in range(pb.getNumJoints(self.robot, physicsClientId=self.client)):
            info = pb.getJointInfo(self.robot, index, physicsClientId=self.client)
            if info[2] != pb.JOINT_FIXED:
                self._joints[info[1].decode()] = index
            self._links[info[12].decode()] = index
        self._terrain: _Terrain | None = None

    # ------------------------------------------------------------------------------ the scene
    def close(self) -> None:
        """Disconnect the client and delete the temporary files."""
        if self.client >= 0 and pb.isConnected(physicsClientId=self.client):
            pb.disconnect(physicsClientId=self.client)
        self.client = -1
        self._tmp.cleanup()

    def __enter__(self) -> SceneRenderer:
        return self

    def __exit__(self, *_exc: object) -> None:
        self.close()

    def set_joints(self, positions: Mapping[str, float]) -> None:
        """Pose the lander: rad by joint name; joints not named keep their position, names not
        in the URDF are ignored."""
        for name, position in positions.items():
            index = self._joints.get(name)
            if index is not None:
                pb.resetJointState(self.robot, index, float(position), physicsClientId=self.client)

    def set_terrain(self, terrain: HeightMap) -> None:
        """Draw ``terrain`` (replacing the previous one; the same object again costs nothing)."""
        if self._terrain is not None:
            if self._terrain.height_map is terrain:
                return
            pb.removeBody(self._terrain.body, physicsClientId=self.client)
        self._terrain = _Terrain.add(terrain, self._texture, self.client)

    def X_base_link(self, link: str) -> FloatArray:
        """(4, 4) pose of URDF link ``link`` in base_link at the joint positions set.

        Raises:
            RenderError: no such link.
        """
        index = self._links.get(link)
        if index is None:
            msg = f"the URDF has no link {link!r}"
            raise RenderError(msg)
        state = pb.getLinkState(
            self.robot, index, computeForwardKinematics=True, physicsClientId=self.client
        )
        X = np.eye(4)
        X[:3, :3] = np.reshape(pb.getMatrixFromQuaternion(state[5]), (3, 3))
        X[:3, 3] = state[4]
        return X

    # ---------------------------------------------------------------------------- rendering
    def render(
        self,
        pinhole: Pinhole,
        cameras: Sequence[FloatArray],
        lighting: Lighting,
        lights: Sequence[Spotlight],
    ) -> list[View]:
        """What each camera sees of the scene as posed now.

        Args:
            pinhole: the cameras' projection (all alike).
            cameras: (4, 4) each camera's optical frame in base_link (z forward, y down).
            lighting: the light.
            lights: where the mast lights are (their intensities are ``lighting``'s).

        Returns:
            One :class:`View` per camera, in order.
        """
        passes = [self._pass(pinhole, X) for X in cameras]
        lit = self._sun_visibility(passes, lighting) if lighting.sun_up else None
        views = []
        for i, p in enumerate(passes):
            irradiance = np.full(p.mask.shape, lighting.ambient_w_m2, dtype=np.float32)
            irradiance += _spot_irradiance(p, lighting, lights)
            if lit is not None:
                sun = lighting.sun_direction.astype(np.float32)
                cos_sun = np.maximum(_dot(p.normals, sun), 0.0)
                irradiance += np.float32(lighting.sun_irradiance_w_m2) * cos_sun * lit[i]
            image = p.albedo * irradiance[:, :, None]
            image[~p.mask] = 0.0
            depth = np.where(p.mask, p.depth, np.float32(np.inf))
            views.append(View(image, depth))
        return views

    def _draw(
        self, width: int, height: int, view: list[float], projection: list[float]
    ) -> tuple[ByteImage, Float32Array, npt.NDArray[np.int32]]:
        """One TinyRenderer pass, unlit (ambient 1, no diffuse, no shadow): (h, w, 3) RGB albedo,
        (h, w) depth buffer 0..1, (h, w) segmentation (-1: nothing; else the body's id)."""
        _, _, rgba, depth, seg = pb.getCameraImage(
            width,
            height,
            view,
            projection,
            lightAmbientCoeff=1.0,
            lightDiffuseCoeff=0.0,
            lightSpecularCoeff=0.0,
            shadow=0,
            renderer=pb.ER_TINY_RENDERER,
            physicsClientId=self.client,
        )
        return (
            np.reshape(np.asarray(rgba, dtype=np.uint8), (height, width, 4))[:, :, :3],
            np.reshape(np.asarray(depth, dtype=np.float32), (height, width)),
            np.reshape(np.asarray(seg, dtype=np.int32), (height, width)),
        )

    def _pass(self, pinhole: Pinhole, X: FloatArray) -> _Pass:
        eye, R = X[:3, 3], X[:3, :3]
        view = _look(eye, R[:, 2], -R[:, 1])
        projection = list(
            pb.computeProjectionMatrixFOV(
                math.degrees(pinhole.vfov_rad), pinhole.width / pinhole.height, NEAR_M, FAR_M
            )
        )
        rgb, buffer, seg = self._draw(pinhole.width, pinhole.height, view, projection)
        mask = seg >= 0
        depth = _linear_depth(buffer, NEAR_M, FAR_M).astype(np.float32)
        x, y = pinhole.rays()
        R32 = R.astype(np.float32)
        points = (x.astype(np.float32) * depth)[:, :, None] * R32[:, 0]
        points += (y.astype(np.float32) * depth)[:, :, None] * R32[:, 1]
        points += depth[:, :, None] * R32[:, 2]
        points += eye.astype(np.float32)
        normals = _depth_normals(points, eye)
        if self._terrain is not None:
            ground = seg == self._terrain.body
            normals[ground] = self._terrain.normals_at(points[ground])
        return _Pass(rgb.astype(np.float32) / 255.0, mask, depth, points, normals, eye)

    def _sun_visibility(self, passes: list[_Pass], lighting: Lighting) -> list[Float32Array]:
        """Per camera, (h, w) fraction of each pixel's point the sun reaches (0: in shadow)."""
        seen = [p.points[p.mask] for p in passes if p.mask.any()]
        if not seen:
            return [np.zeros(p.mask.shape, dtype=np.float32) for p in passes]
        points = np.concatenate(seen)
        sun = lighting.sun_direction / np.linalg.norm(lighting.sun_direction)
        centre = (points.min(axis=0) + points.max(axis=0)).astype(np.float64) / 2
        up = np.array([0.0, 0.0, 1.0]) if abs(sun[2]) < 0.99 else np.array([1.0, 0.0, 0.0])
        view_list = _look(centre + sun * SUN_DISTANCE_M, -sun, up)
        V = _matrix(view_list)
        eye_x, eye_y = _rows(V[:2], points)
        margin = 1.05
        half_x = max(float(np.abs(eye_x).max()) * margin, 0.05)
        half_y = max(float(np.abs(eye_y).max()) * margin, 0.05)
        if half_x >= half_y:
            width, height = SUN_MAP_PX, max(16, round(SUN_MAP_PX * half_y / half_x))
        else:
            width, height = max(16, round(SUN_MAP_PX * half_x / half_y)), SUN_MAP_PX
        near, far = SUN_DISTANCE_M - SUN_DEPTH_RANGE_M, SUN_DISTANCE_M + SUN_DEPTH_RANGE_M
        fov_deg = math.degrees(2 * math.atan(half_y / SUN_DISTANCE_M))
        projection = list(pb.computeProjectionMatrixFOV(fov_deg, half_x / half_y, near, far))
        _, buffer, _ = self._draw(width, height, view_list, projection)
        shadow_map = _ShadowMap(V, _matrix(projection), _linear_depth(buffer, near, far))
        return [shadow_map.lit(p, sun) for p in passes]


@dataclass(frozen=True)
class _ShadowMap:
    """Depths seen from the sun: view ``V`` and projection ``P`` ((4, 4)), ``depth`` (h, w) m
    of the nearest surface along each texel's ray."""

    V: FloatArray
    P: FloatArray
    depth: FloatArray

    def lit(self, p: _Pass, sun: FloatArray) -> Float32Array:
        """(h, w) whether the sun reaches each pixel's point (softened over 3 x 3 pixels of the
        camera image: shadow edges one texel wide are not stair-stepped)."""
        height, width = self.depth.shape
        eye = np.stack(_rows(self.V[:3], p.points[p.mask]), axis=1)
        clip_x, clip_y, clip_w = _rows(self.P[[0, 1, 3]], eye)
        u = (clip_x / clip_w + 1.0) / 2.0 * width
        v = (1.0 - clip_y / clip_w) / 2.0 * height
        texel_m = 2.0 * SUN_DISTANCE_M / (float(self.P[1, 1]) * height)
        # A surface at a grazing angle to the sun spans more depth across one texel.
        cos_sun = np.clip(_dot(p.normals[p.mask], sun.astype(np.float32)), 0.05, 1.0)
        bias = SHADOW_BIAS_M + 2.0 * texel_m * np.sqrt(1.0 - cos_sun**2) / cos_sun
        row = np.clip(v.astype(np.intp), 0, height - 1)
        col = np.clip(u.astype(np.intp), 0, width - 1)
        lit = np.zeros(p.mask.shape, dtype=np.float32)
        lit[p.mask] = self.depth[row, col] >= -eye[:, 2] - bias
        return np.asarray(cv2.blur(lit, (3, 3)), dtype=np.float32)


def _spot_irradiance(p: _Pass, lighting: Lighting, lights: Sequence[Spotlight]) -> Float32Array:
    """(h, w) W/m^2 the mast lights put on each pixel's point."""
    total = np.zeros(p.mask.shape, dtype=np.float32)
    cos_edge = math.cos(lighting.cone_angle_rad / 2)
    for spot in lights:
        intensity = lighting.intensities.get(spot.name, 0.0)
        if intensity <= 0.0 or lighting.light_irradiance_at_1m_w_m2 <= 0.0:
            continue
        to_light = spot.position.astype(np.float32) - p.points
        distance_sq = np.maximum(_dot(to_light, to_light), np.float32(1e-6))
        to_light /= np.sqrt(distance_sq)[:, :, None]
        inside = _dot(to_light, -spot.axis.astype(np.float32)) >= cos_edge
        facing = np.maximum(_dot(p.normals, to_light), 0.0)
        scale = np.float32(intensity * lighting.light_irradiance_at_1m_w_m2)
        total += np.where(inside & p.mask, scale * facing / distance_sq, np.float32(0.0))
    return total


def _depth_normals(points: Float32Array, eye: FloatArray) -> Float32Array:
    """(h, w, 3) unit normals of the surface through ``points`` ((h, w, 3) m), facing ``eye``:
    from each pixel's neighbours, taking on each axis the one-sided difference of the smaller
    step (the same surface, at a depth edge)."""

    def tangent(axis: int) -> Float32Array:
        along = np.moveaxis(points, axis, 0)
        step = along[1:] - along[:-1]  # step k: from pixel k to pixel k + 1
        length = _dot(step, step)
        # Pixel k (0 < k < n - 1) lies between steps k - 1 and k: the shorter one.
        inner = np.where((length[1:] < length[:-1])[..., None], step[1:], step[:-1])
        return np.moveaxis(np.concatenate([step[:1], inner, step[-1:]]), 0, axis)

    n = np.cross(tangent(1), tangent(0))
    n /= np.maximum(np.sqrt(_dot(n, n)), np.float32(1e-12))[:, :, None]
    facing = _dot(n, eye.astype(np.float32) - points) >= 0.0
    return np.where(facing[:, :, None], n, -n)


@dataclass(frozen=True)
class _Terrain:
    """A height map drawn as a textured mesh, with its vertex normals for the shading."""

    height_map: HeightMap
    body: int
    xs: FloatArray  # (cols,) m, the mesh's vertex columns
    ys: FloatArray  # (rows,) m
    normals: Float32Array  # (rows, cols, 3) unit vertex normals

    @classmethod
    def add(cls, terrain: HeightMap, texture: int, client: int) -> _Terrain:
        """Add ``terrain`` to ``client`` as a mesh (no collision shape) with ``texture``."""
        xs, ys = terrain.cell_centres()
        rows, cols = terrain.shape
        stride = max(1, math.ceil(math.sqrt(rows * cols / MAX_TERRAIN_VERTICES)))
        keep_r = np.unique(np.r_[np.arange(0, rows, stride), rows - 1])
        keep_c = np.unique(np.r_[np.arange(0, cols, stride), cols - 1])
        heights = terrain.heights[np.ix_(keep_r, keep_c)]
        xs, ys = xs[keep_c], ys[keep_r]
        gx, gy = np.meshgrid(xs, ys)
        vertices = np.stack([gx.ravel(), gy.ravel(), heights.ravel()], axis=1)
        dz_dy, dz_dx = np.gradient(heights, ys, xs)
        normals = np.stack([-dz_dx, -dz_dy, np.ones_like(heights)], axis=2)
        normals /= np.linalg.norm(normals, axis=2, keepdims=True)
        n_r, n_c = heights.shape
        corner = (np.arange(n_r - 1)[:, None] * n_c + np.arange(n_c - 1)[None, :]).ravel()
        # Two counter-clockwise triangles per cell, seen from above.
        triangles = np.stack(
            [corner, corner + 1, corner + n_c + 1, corner, corner + n_c + 1, corner + n_c],
            axis=1,
        )
        mesh: dict[str, Any] = {
            "vertices": vertices.tolist(),
            "indices": triangles.ravel().tolist(),
            "uvs": (vertices[:, :2] / TILE_M).tolist(),
            "normals": normals.reshape(-1, 3).tolist(),
        }
        shape = pb.createVisualShape(pb.GEOM_MESH, physicsClientId=client, **mesh)
        body = pb.createMultiBody(0, -1, shape, physicsClientId=client)
        pb.changeVisualShape(
            body, -1, textureUniqueId=texture, rgbaColor=[1, 1, 1, 1], physicsClientId=client
        )
        return cls(terrain, int(body), xs, ys, normals.astype(np.float32))

    def normals_at(self, points: Float32Array) -> Float32Array:
        """(n, 3) the mesh's vertex normals interpolated bilinearly at points (n, 3) m (as
        TinyRenderer shades it)."""
        fc = np.interp(points[:, 0], self.xs, np.arange(len(self.xs)))
        fr = np.interp(points[:, 1], self.ys, np.arange(len(self.ys)))
        c0 = np.minimum(fc.astype(np.intp), len(self.xs) - 2)
        r0 = np.minimum(fr.astype(np.intp), len(self.ys) - 2)
        tc = (fc - c0).astype(np.float32)[:, None]
        tr = (fr - r0).astype(np.float32)[:, None]
        n = self.normals
        blend = (1 - tr) * ((1 - tc) * n[r0, c0] + tc * n[r0, c0 + 1]) + tr * (
            (1 - tc) * n[r0 + 1, c0] + tc * n[r0 + 1, c0 + 1]
        )
        return blend / np.sqrt(_dot(blend, blend))[:, None]


def _unblinded(urdf_path: Path, link: str, points: Sequence[tuple[float, float, float]]) -> str:
    """The URDF's text without the ``<visual>`` elements of ``link`` whose box, cylinder or
    sphere encloses one of ``points`` (m, in ``link``'s frame)."""
    root = ET.parse(urdf_path).getroot()
    for element in root.iter("link"):
        if element.get("name") != link:
            continue
        for visual in element.findall("visual"):
            if any(_encloses(visual, point) for point in points):
                element.remove(visual)
    return ET.tostring(root, encoding="unicode")


def _encloses(visual: ET.Element, point: tuple[float, float, float]) -> bool:
    """Whether the primitive of URDF ``<visual>`` ``visual`` holds ``point`` (its link's frame)."""
    origin = visual.find("origin")
    xyz, rpy = (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)
    if origin is not None:
        xyz = _floats(origin.get("xyz", "0 0 0"))
        rpy = _floats(origin.get("rpy", "0 0 0"))
    X = transform(xyz, rpy)
    local = X[:3, :3].T @ (np.asarray(point) - X[:3, 3])
    geometry = visual.find("geometry")
    shape = geometry[0] if geometry is not None and len(geometry) else None
    if shape is None:
        return False
    if shape.tag == "box":
        return bool(np.all(np.abs(local) <= np.asarray(_floats(shape.get("size", "0 0 0"))) / 2))
    if shape.tag == "cylinder":
        radius, length = float(shape.get("radius", 0)), float(shape.get("length", 0))
        return bool(np.hypot(local[0], local[1]) <= radius and abs(local[2]) <= length / 2)
    if shape.tag == "sphere":
        return bool(np.linalg.norm(local) <= float(shape.get("radius", 0)))
    return False


def _floats(text: str) -> tuple[float, float, float]:
    x, y, z = (float(v) for v in text.split())
    return x, y, z
