"""The mission's look at the workspace before its first arm step (no ROS): where the mast looks,
what a stereo capture shows of the trench site, and the files and report entry it makes.

The mast looks at the middle of the trench from the start (:func:`mast_aim`: the simulation's
initial pan and tilt, OceanWATERS' PanTiltMoveCartesian solution). Before the first arm step
the mission asks the camera node for one capture through OceanWATERS' ``CameraCapture``
(``ow_mission.camera_client_node``); :func:`site_view` measures the trench's footprint in the
left image (the share of its pixels the stereo matcher gave a point, and the height of those
points); :func:`write_capture` writes ``camera/left.png``, ``camera/left_site.png`` (the
footprint outlined) and ``camera/cloud.ply``, and returns ``report.json``'s ``capture`` entry;
:func:`capture_figure` puts the picture in the report. The trench site is the mission file's:
the capture only reports what the cameras saw of it.

Nothing here reads a clock but the capture's wall time (``wall_time_s``, left out of run
comparisons): the images are the renderer's of the simulation at t = 0, and the files are the
same bytes for the same mission file.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt
from PIL import Image

from ow_cameras.rig import Mast, RigPose
from ow_description.description import ANTENNA_JOINTS
from ow_mission.plots import TrenchGeometry

if TYPE_CHECKING:
    from ow_mission.report_files import Figures

FloatArray = npt.NDArray[np.float64]
ByteImage = npt.NDArray[np.uint8]

#: The run directory's folder of the capture, and its files.
CAPTURE_DIR = "camera"
LEFT_IMAGE = f"{CAPTURE_DIR}/left.png"
SITE_IMAGE = f"{CAPTURE_DIR}/left_site.png"
CLOUD = f"{CAPTURE_DIR}/cloud.ply"
#: m, half the width of the trench footprint measured (across the trench line; the grinder's
#: two passes are 0.08 m apart).
FOOTPRINT_HALF_WIDTH_M = 0.05
#: The footprint's outline in ``left_site.png``: colour (RGB) and width (px).
OUTLINE_RGB = (255, 64, 0)
OUTLINE_PX = 2
#: The capture's role in the report's figures (:class:`~ow_mission.report_files.Figures`).
ROLE = "workspace"


@dataclass(frozen=True)
class StereoShot:
    """One capture as the mission received it.

    Attributes:
        left: (height, width, 3) RGB, the left camera's image.
        points: (height, width, 3) m, the point cloud in the left optical frame, NaN where the
            pair did not match.
        K: (3, 3) the left camera's intrinsic matrix (px).
        stamp_s: s of sim time, the capture's stamp (the joint state it was posed from).
    """

    left: ByteImage
    points: npt.NDArray[np.float32]
    K: FloatArray
    stamp_s: float


@dataclass(frozen=True)
class SiteView:
    """The trench's footprint as the left camera saw it.

    Attributes:
        corners_px: (4, 2) px, the footprint's corners in the left image (u right, v down).
        box_px: (u0, v0, u1, v1) px, their bounding box within the image (u1, v1 exclusive);
            empty (u0 == u1) when the footprint is out of view.
        pixels: pixels in the box.
        valid_fraction: the share of them with a stereo point (0 without pixels).
        ground_z: m (base_link), median height of those points; None without any.
        range_m: m, the left camera's distance to the trench's middle.
    """

    corners_px: FloatArray
    box_px: tuple[int, int, int, int]
    pixels: int
    valid_fraction: float
    ground_z: float | None
    range_m: float


def trench_target(config: Mapping[str, Any]) -> FloatArray:
    """(3,) m, base_link: the middle of the trench line at the expected ground height, from the
    mission's settings (``x``, ``y``, ``trench_length``, ``parallel``, ``expected_ground``)."""
    middle = TrenchGeometry.from_config(config).middle
    return np.array([middle[0], middle[1], float(config["expected_ground"])])


def trench_footprint(config: Mapping[str, Any]) -> FloatArray:
    """(4, 3) m, base_link: the corners of the trench's footprint at the expected ground, the
    trench line's length by twice :data:`FOOTPRINT_HALF_WIDTH_M`, in order round it."""
    g = TrenchGeometry.from_config(config)
    z = float(config["expected_ground"])
    corners = []
    for along, across in ((0.0, -1.0), (g.length, -1.0), (g.length, 1.0), (0.0, 1.0)):
        xy = g.start + g.direction * along + g.normal * across * FOOTPRINT_HALF_WIDTH_M
        corners.append((float(xy[0]), float(xy[1]), z))
    return np.array(corners)


def mast_aim(config: Mapping[str, Any], mast: Mast | None = None) -> dict[str, float]:
    """rad by joint name: the pan and tilt that look at :func:`trench_target`."""
    pan, tilt = (mast or Mast.from_urdf()).look_at(trench_target(config))
    return dict(zip(ANTENNA_JOINTS, (pan, tilt), strict=True))


def left_camera(aim: Mapping[str, float], mast: Mast | None = None) -> FloatArray:
    """(4, 4) the left optical frame in base_link with the mast at ``aim`` (rad by joint)."""
    pan, tilt = (float(aim[j]) for j in ANTENNA_JOINTS)
    return RigPose.from_panel((mast or Mast.from_urdf()).X_base_panel(pan, tilt)).X_base_left


def site_view(
    points: npt.NDArray[np.float32], X_base_left: FloatArray, K: FloatArray, footprint: FloatArray
) -> SiteView:
    """What the left camera saw of ``footprint`` ((4, 3) m, base_link).

    Args:
        points: (height, width, 3) m, the cloud in the left optical frame (NaN: no point).
        X_base_left: (4, 4) the left optical frame in base_link when the images were taken.
        K: (3, 3) the left camera's intrinsic matrix (px).
        footprint: (4, 3) m, base_link, the corners of the area to look at.
    """
    height, width = points.shape[:2]
    X_left_base = np.linalg.inv(X_base_left)
    corners = footprint @ X_left_base[:3, :3].T + X_left_base[:3, 3]
    range_m = float(np.linalg.norm(footprint.mean(axis=0) - X_base_left[:3, 3]))
    if (corners[:, 2] <= 0.0).any():  # behind the camera
        nan = np.full((4, 2), np.nan)
        return SiteView(nan, (0, 0, 0, 0), 0, 0.0, None, range_m)
    projected = corners @ K.T
    uv = projected[:, :2] / projected[:, 2:]
    u0, v0 = (max(0, math.floor(float(c))) for c in uv.min(axis=0))
    u1 = min(width, math.ceil(float(uv[:, 0].max())) + 1)
    v1 = min(height, math.ceil(float(uv[:, 1].max())) + 1)
    if u0 >= u1 or v0 >= v1:
        return SiteView(uv, (0, 0, 0, 0), 0, 0.0, None, range_m)
    window = points[v0:v1, u0:u1].reshape(-1, 3)
    valid = np.isfinite(window).all(axis=1)
    heights = window[valid].astype(np.float64) @ X_base_left[2, :3] + X_base_left[2, 3]
    return SiteView(
        uv,
        (u0, v0, u1, v1),
        int(window.shape[0]),
        float(valid.mean()),
        float(np.median(heights)) if heights.size else None,
        range_m,
    )


def outlined(image: ByteImage, box_px: Sequence[int]) -> ByteImage:
    """A copy of ``image`` ((height, width, 3) RGB) with ``box_px`` (u0, v0, u1, v1) outlined in
    :data:`OUTLINE_RGB`, :data:`OUTLINE_PX` wide (unchanged for an empty box)."""
    out = image.copy()
    u0, v0, u1, v1 = box_px
    if u0 >= u1 or v0 >= v1:
        return out
    w = OUTLINE_PX
    colour = np.asarray(OUTLINE_RGB, dtype=np.uint8)
    out[v0 : v0 + w, u0:u1] = colour
    out[max(v0, v1 - w) : v1, u0:u1] = colour
    out[v0:v1, u0 : u0 + w] = colour
    out[v0:v1, max(u0, u1 - w) : u1] = colour
    return out


def write_ply(
    path: Path, points: npt.NDArray[np.float32], rgb: ByteImage, comments: Sequence[str]
) -> int:
    """Write the valid points of an organised cloud as a binary little-endian PLY (x y z float,
    red green blue uchar), in the cloud's frame, ``comments`` in its header; how many."""
    valid = np.isfinite(points).all(axis=2)
    vertices = np.empty(
        int(valid.sum()),
        dtype=[
            ("x", "<f4"),
            ("y", "<f4"),
            ("z", "<f4"),
            ("red", "u1"),
            ("green", "u1"),
            ("blue", "u1"),
        ],
    )
    for axis, name in enumerate("xyz"):
        vertices[name] = points[valid][:, axis]
    for channel, name in enumerate(("red", "green", "blue")):
        vertices[name] = rgb[valid][:, channel]
    header = (
        "ply\nformat binary_little_endian 1.0\n"
        + "".join(f"comment {c}\n" for c in comments)
        + f"element vertex {vertices.size}\n"
        + "".join(f"property float {n}\n" for n in "xyz")
        + "".join(f"property uchar {n}\n" for n in ("red", "green", "blue"))
        + "end_header\n"
    )
    path.write_bytes(header.encode("ascii") + vertices.tobytes())
    return int(vertices.size)


def _png(path: Path, image: ByteImage) -> None:
    # PIL writes no time chunk: the same pixels give the same bytes.
    Image.fromarray(image, "RGB").save(path, format="PNG")


def write_capture(
    run_dir: Path,
    shot: StereoShot,
    aim: Mapping[str, float],
    footprint: FloatArray,
) -> dict[str, Any]:
    """Write the capture's files into ``run_dir`` (:data:`LEFT_IMAGE`, :data:`SITE_IMAGE`,
    :data:`CLOUD`) and return ``report.json``'s ``capture`` entry.

    Args:
        run_dir: the run directory.
        shot: the capture.
        aim: rad by joint name, the mast's pan and tilt when it was taken (the simulation's
            initial ones: the mission captures at t = 0).
        footprint: (4, 3) m, base_link, the trench's footprint (:func:`trench_footprint`).
    """
    (run_dir / CAPTURE_DIR).mkdir(exist_ok=True)
    X_base_left = left_camera(aim)
    view = site_view(shot.points, X_base_left, shot.K, footprint)
    _png(run_dir / LEFT_IMAGE, shot.left)
    _png(run_dir / SITE_IMAGE, outlined(shot.left, view.box_px))
    frame = np.array2string(X_base_left, precision=9, separator=" ").replace("\n", "")
    points = write_ply(
        run_dir / CLOUD,
        shot.points,
        shot.left,
        (
            "frame_id StereoCameraLeft_optical_frame (m)",
            f"stamp {shot.stamp_s:.9f} s of simulation time",
            f"X_base_left {frame}",
        ),
    )
    height, width = shot.left.shape[:2]
    return {
        "success": True,
        "message": "",
        "stamp_s": shot.stamp_s,
        "width": width,
        "height": height,
        "mast": dict(aim),
        "image": LEFT_IMAGE,
        "site_image": SITE_IMAGE,
        "cloud": CLOUD,
        "cloud_points": points,
        "X_base_left": X_base_left.tolist(),
        "site": {
            "footprint": footprint.tolist(),
            "corners_px": view.corners_px.tolist(),
            "box_px": list(view.box_px),
            "pixels": view.pixels,
            "valid_fraction": view.valid_fraction,
            "ground_z": view.ground_z,
            "range_m": view.range_m,
        },
    }


def failed_capture(message: str) -> dict[str, Any]:
    """``report.json``'s ``capture`` entry of a capture that failed (``message``: why)."""
    return {"success": False, "message": message}


def caption(capture: Mapping[str, Any], ground_z: float | None) -> str:
    """The report's caption of a successful ``capture`` entry (``ground_z``: m, the ground the
    guarded move found, or None)."""
    site = capture["site"]
    mast = capture["mast"]
    pan, tilt = (mast[j] for j in ANTENNA_JOINTS)
    target = np.mean(site["footprint"], axis=0)
    head = (
        f"The workspace before the first arm step: the left stereo camera at "
        f"t = {capture['stamp_s']:.2f} s, {capture['width']} x {capture['height']} px, the mast "
        f"at pan {pan:.3f} rad, tilt {tilt:.3f} rad, looking at the trench's middle "
        f"({target[0]:.3f}, {target[1]:.3f}, {target[2]:.3f}) m."
    )
    if not site["pixels"]:
        seen = " The trench's footprint is out of view."
    else:
        found = (
            "" if ground_z is None else f"; the guarded move found the ground at {ground_z:.3f} m"
        )
        height = (
            "no point"
            if site["ground_z"] is None
            else f"their median height {site['ground_z']:.3f} m{found}"
        )
        seen = (
            f" Outlined: the box around the trench's footprint (its line, "
            f"{2 * FOOTPRINT_HALF_WIDTH_M:.2f} m wide, at the expected ground, "
            f"{site['range_m']:.2f} m away), {site['pixels']} px of which "
            f"{100 * site['valid_fraction']:.0f} % have a stereo point; {height}."
        )
    files = (
        f" The image alone: `{capture['image']}`; the point cloud ({capture['cloud_points']} "
        f"points, left optical frame): `{capture['cloud']}`."
    )
    return head + seen + files


def capture_figure(run_dir: Path, document: Mapping[str, Any], figures: Figures) -> None:
    """File the capture of ``document`` (``report.json``) in ``figures``: its outlined picture
    with :func:`caption`, or a note when it failed (nothing without a capture)."""
    capture = document.get("capture")
    if capture is None:
        return
    if not capture["success"]:
        figures.notes[ROLE] = (
            f"No picture of the workspace: the capture before the first arm step failed: "
            f"{capture['message']}"
        )
        return
    if (run_dir / capture["site_image"]).is_file():
        figures.files[ROLE] = capture["site_image"]
        figures.captions[ROLE] = caption(capture, document.get("ground_z"))
