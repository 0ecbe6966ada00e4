"""The mission's capture of the workspace without a master (ow_mission.workspace_capture): the
mast aimed at the trench, the trench's footprint measured in a cloud of known ground, the files
(byte for byte the same for the same capture) and the report's figure."""

from __future__ import annotations

from dataclasses import asdict

import numpy as np
import pytest
from PIL import Image

from ow_cameras.config import CameraConfig
from ow_cameras.rig import Mast, X_panel
from ow_mission.mission_config import MissionConfig
from ow_mission.report_files import Figures, image_links, markdown
from ow_mission.workspace_capture import (
    CLOUD,
    LEFT_IMAGE,
    OUTLINE_RGB,
    ROLE,
    SITE_IMAGE,
    StereoShot,
    capture_figure,
    failed_capture,
    left_camera,
    mast_aim,
    outlined,
    site_view,
    trench_footprint,
    trench_target,
    write_capture,
)

CONFIG = asdict(MissionConfig.from_dict({}))  # the default mission: the trench at (1.65, 0) m
PINHOLE = CameraConfig().pinhole
#: px, the leftmost columns the stereo matcher leaves without points (its disparity range).
BLIND_COLUMNS = 336


def flat_ground_cloud(X_base_left: np.ndarray, z: float) -> np.ndarray:
    """(height, width, 3) m, left optical frame: each pixel's ray meeting the plane z (base_link);
    NaN where it does not, and in the columns the matcher cannot match."""
    u, v = PINHOLE.rays()
    rays = np.stack([u, v, np.ones_like(u)], axis=-1)
    down = rays @ X_base_left[2, :3]
    with np.errstate(divide="ignore", invalid="ignore"):
        scale = (z - X_base_left[2, 3]) / down
    points = rays * scale[..., None]
    points[~(scale > 0)] = np.nan
    points[:, :BLIND_COLUMNS] = np.nan
    return points.astype(np.float32)


@pytest.fixture(scope="module")
def aim():
    return mast_aim(CONFIG)


def test_the_mast_looks_at_the_middle_of_the_trench(aim):
    mast = Mast.from_urdf()
    X_head = mast.X_base_panel(aim["j_ant_pan"], aim["j_ant_tilt"]) @ X_panel(
        "StereoCamera_head_link"
    )
    target = trench_target(CONFIG)
    offset = target - X_head[:3, 3]
    along = offset @ X_head[:3, 0]
    assert np.linalg.norm(offset - along * X_head[:3, 0]) < 1e-3
    assert 2.0 < along < 2.6  # m, beyond the matcher's nearest range (1.29 m)
    # The middle of the trench line, 0.3 m long from (about) the mission's (x, y), at the
    # expected ground.
    assert target[2] == CONFIG["expected_ground"]
    assert target[0] == pytest.approx(CONFIG["x"] + CONFIG["trench_length"] / 2, abs=0.05)
    assert target[1] == pytest.approx(CONFIG["y"], abs=0.05)


def test_the_trench_footprint_is_seen_whole_on_flat_ground(aim):
    X = left_camera(aim)
    z = CONFIG["expected_ground"]
    view = site_view(flat_ground_cloud(X, z), X, PINHOLE.K, trench_footprint(CONFIG))
    u0, v0, u1, v1 = view.box_px
    assert BLIND_COLUMNS < u0 < u1 < PINHOLE.width  # where the matcher has points
    assert 0 < v0 < v1 < PINHOLE.height
    # The head looks at the middle; the left camera, 0.1 m aside, sees it that far right of its
    # centre.
    aside_px = PINHOLE.focal_px * 0.1 / view.range_m
    assert view.corners_px.mean(axis=0) == pytest.approx((PINHOLE.cx + aside_px, PINHOLE.cy), abs=8)
    assert np.all((view.corners_px >= (u0, v0)) & (view.corners_px <= (u1, v1)))
    assert view.pixels == (u1 - u0) * (v1 - v0) > 1000
    assert view.valid_fraction == 1.0
    assert view.ground_z == pytest.approx(z, abs=1e-5)
    assert view.range_m == pytest.approx(2.3, abs=0.3)


def test_a_footprint_without_stereo_points_or_out_of_view_says_so(aim):
    X = left_camera(aim)
    blind = np.full((PINHOLE.height, PINHOLE.width, 3), np.nan, dtype=np.float32)
    view = site_view(blind, X, PINHOLE.K, trench_footprint(CONFIG))
    assert view.pixels > 0
    assert (view.valid_fraction, view.ground_z) == (0.0, None)
    behind = trench_footprint({**CONFIG, "x": -1.65, "y": 1.0})  # the lander's other side
    view = site_view(blind, X, PINHOLE.K, behind)
    assert (view.box_px, view.pixels, view.ground_z) == ((0, 0, 0, 0), 0, None)


def test_the_outline_is_a_border_of_the_box():
    image = np.zeros((20, 30, 3), dtype=np.uint8)
    out = outlined(image, (5, 4, 15, 12))
    marked = (out == OUTLINE_RGB).all(axis=2)
    assert marked[4, 5:15].all() and marked[11, 5:15].all()  # top and bottom rows
    assert marked[4:12, 5].all() and marked[4:12, 14].all()  # left and right columns
    assert not marked[6:10, 7:13].any() and not marked[:4].any() and not marked[:, 15:].any()
    assert not image.any()  # a copy
    assert np.array_equal(outlined(image, (0, 0, 0, 0)), image)


def read_ply(data: bytes) -> tuple[list[str], np.ndarray]:
    head, body = data.split(b"end_header\n", 1)
    lines = head.decode("ascii").splitlines()
    assert lines[:2] == ["ply", "format binary_little_endian 1.0"]
    count = int(next(line.split()[2] for line in lines if line.startswith("element vertex")))
    layout = [(n, "<f4") for n in "xyz"] + [(n, "u1") for n in ("red", "green", "blue")]
    vertices = np.frombuffer(body, dtype=layout)
    assert vertices.size == count
    return [line for line in lines if line.startswith("comment")], vertices


@pytest.fixture
def shot(aim):
    X = left_camera(aim)
    rng = np.random.default_rng(3)
    left = rng.integers(0, 256, (PINHOLE.height, PINHOLE.width, 3), dtype=np.uint8)
    points = flat_ground_cloud(X, CONFIG["expected_ground"])
    return StereoShot(left, points, PINHOLE.K, 0.0)


def test_the_capture_leaves_its_files_and_its_numbers(tmp_path, aim, shot):
    entry = write_capture(tmp_path, shot, aim, trench_footprint(CONFIG))
    assert np.array_equal(np.asarray(Image.open(tmp_path / LEFT_IMAGE)), shot.left)
    site = np.asarray(Image.open(tmp_path / SITE_IMAGE))
    u0, v0, u1, _ = entry["site"]["box_px"]
    assert (site[v0, u0:u1] == OUTLINE_RGB).all()
    assert np.array_equal(site[: v0 - 1], shot.left[: v0 - 1])
    comments, vertices = read_ply((tmp_path / CLOUD).read_bytes())
    valid = np.isfinite(shot.points).all(axis=2)
    assert vertices.size == entry["cloud_points"] == valid.sum()
    assert np.array_equal(vertices["x"], shot.points[valid][:, 0])
    assert np.array_equal(vertices["green"], shot.left[valid][:, 1])
    assert comments[0] == "comment frame_id StereoCameraLeft_optical_frame (m)"
    assert entry["success"] and entry["mast"] == aim
    assert entry["site"]["valid_fraction"] == 1.0
    assert np.allclose(entry["X_base_left"], left_camera(aim))
    # The same capture makes the same bytes (no time in a PNG or PLY written here).
    again = tmp_path / "again"
    again.mkdir()
    assert write_capture(again, shot, aim, trench_footprint(CONFIG)) == entry
    for name in (LEFT_IMAGE, SITE_IMAGE, CLOUD):
        assert (again / name).read_bytes() == (tmp_path / name).read_bytes(), name


def test_the_report_shows_the_picture_first_with_its_caption(tmp_path, aim, shot):
    entry = write_capture(tmp_path, shot, aim, trench_footprint(CONFIG))
    document = {
        "config": {**CONFIG, "terrain_spec": "europa:7"},
        "success": True,
        "ground_z": -0.153,
        "wall_time_s": 1.0,
        "sim_time_s": 2.0,
        "real_time_factor": 2.0,
        "peak_memory_mb": 1.0,
        "steps": [],
        "capture": {**entry, "wall_time_s": 3.0},
    }
    figures = Figures()
    capture_figure(tmp_path, document, figures)
    assert figures.files == {ROLE: SITE_IMAGE}
    caption = figures.captions[ROLE]
    assert "100 % have a stereo point" in caption
    assert "median height -0.155 m; the guarded move found the ground at -0.153 m" in caption
    assert f"`{CLOUD}`" in caption and f"{entry['cloud_points']} points" in caption
    text = markdown(tmp_path, document, figures)
    assert image_links(text) == [SITE_IMAGE]
    assert f"*{caption}*" in text


def test_a_failed_capture_is_a_note_and_no_capture_nothing(tmp_path):
    figures = Figures()
    document = {"capture": failed_capture("CameraCapture did not succeed: Timed out")}
    capture_figure(tmp_path, document, figures)
    assert figures.files == {}
    assert figures.notes[ROLE] == (
        "No picture of the workspace: the capture before the first arm step failed: "
        "CameraCapture did not succeed: Timed out"
    )
    nothing = Figures()
    capture_figure(tmp_path, {}, nothing)
    assert (nothing.files, nothing.notes) == ({}, {})
