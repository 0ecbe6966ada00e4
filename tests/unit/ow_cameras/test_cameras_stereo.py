"""The stereo pipeline (no master): the reprojection of known disparities, and the point cloud a
whole capture makes of flat ground against the true plane."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ow_cameras.capture import Shot, StereoCamera
from ow_cameras.config import CameraConfig, StereoConfig
from ow_cameras.errors import StereoError
from ow_cameras.rig import BASELINE_M, Pinhole
from ow_cameras.stereo import StereoMatcher
from ow_cameras.texture import regolith_albedo
from ow_description.description import STOWED
from ow_description.terrain import HeightMap

GROUND_Z = -0.155
#: The default configuration: 800 x 600 px, fx = 2158 px, 336 disparities.
CONFIG = CameraConfig()
#: The mast looks back over the lander's +y side at bare ground 1.6 to 2.3 m away.
GROUND_VIEW = {"j_ant_pan": 3.1, "j_ant_tilt": 0.9}
#: m, the farthest ground point in view.
FARTHEST_M = 2.3


def test_a_uniform_disparity_reprojects_to_its_depth():
    pinhole = Pinhole(400, 300, math.radians(21.0))
    matcher = StereoMatcher(StereoConfig(num_disparities=64), pinhole)
    texture = regolith_albedo(3)[:300, :, 0]
    shift = 40  # px: a plane parallel to the image at fx * B / 40
    left = np.ascontiguousarray(texture[:, 100:500])
    right = np.ascontiguousarray(texture[:, 100 + shift : 500 + shift])
    cloud = matcher.match(left, right)
    valid = cloud.valid
    assert valid[:, 80:].mean() > 0.95  # all but the band the right image cannot see
    assert not valid[:, :63].any()
    disparity = cloud.disparity[valid]
    assert np.median(disparity) == pytest.approx(shift, abs=0.05)
    assert np.percentile(np.abs(disparity - shift), 99) < 0.25
    # Each point is its pixel's ray at the depth its disparity says (the reprojection, Q).
    points = cloud.points[valid]
    depth = pinhole.focal_px * BASELINE_M / disparity
    assert np.allclose(points[:, 2], depth, rtol=1e-5)
    v, u = np.nonzero(valid)
    assert np.allclose(points[:, 0], (u - pinhole.cx) * depth / pinhole.focal_px, rtol=1e-5)
    assert np.allclose(points[:, 1], (v - pinhole.cy) * depth / pinhole.focal_px, rtol=1e-5)
    assert np.isnan(cloud.points[~valid]).all()


@pytest.mark.parametrize(
    ("left", "right", "message"),
    [
        (np.zeros((300, 400), np.float32), np.zeros((300, 400), np.uint8), "left image is float32"),
        (np.zeros((300, 400), np.uint8), np.zeros((200, 400), np.uint8), "right image is uint8"),
        (np.zeros((300, 400), np.uint8), np.zeros((300, 400, 3), np.uint8), "differ in shape"),
    ],
)
def test_a_pair_it_cannot_match_is_refused(left, right, message):
    matcher = StereoMatcher(StereoConfig(), Pinhole(400, 300, math.radians(21.0)))
    with pytest.raises(StereoError, match=message):
        matcher.match(left, right)


def test_the_cloud_of_flat_ground_lies_on_the_plane():
    """A whole capture at the default configuration (800 x 600, the regolith texture) of flat
    ground 1.6-2.3 m away; its points, in base_link, against z = -0.155 m.

    Bound: a disparity error of e px is Z^2 / (fx * B) * e in depth; at the farthest point
    (2.3 m, fx 2158 px, B 0.2 m) 12.3 mm per px, so SGBM's ~0.25 px is 3.1 mm in range and,
    the rays meeting the ground at 45-60 deg, ~2.4 mm in z. A normal error's median |e| is
    0.67 sigma: 1.6 mm. The bound, 3 mm, is that with a margin for TinyRenderer's texture
    sampling (nearest texel: blocks of 1-2 px); the measured median is ~1.0 mm. The signed median
    must be under 1 mm: a wrong focal length or baseline shows as a bias (1 % of 2 m is 14 mm in
    z). The points valid: every pixel whose scene the right camera also sees (right of the
    leftmost 336 columns, the search range) but a few speckles.
    """
    camera = StereoCamera(CONFIG)
    try:
        shot = Shot(
            {**STOWED, **GROUND_VIEW},
            0,
            HeightMap.flat(GROUND_Z, half_extent=4.0, resolution=0.1),
            CONFIG.exposure_s,
            {"left": 1.0, "right": 1.0},
        )
        capture = camera.capture(shot)
    finally:
        camera.close()
    assert capture.cloud is not None
    cloud = capture.cloud
    X = capture.X_base_left
    matchable = np.zeros(cloud.valid.shape, bool)
    matchable[:, CONFIG.stereo.min_disparity + CONFIG.stereo.num_disparities :] = True
    assert cloud.valid[matchable].mean() > 0.95
    assert not cloud.valid[~matchable].any()
    points = cloud.points[cloud.valid] @ X[:3, :3].T + X[:3, 3]
    assert np.linalg.norm(points - X[:3, 3], axis=1).max() < FARTHEST_M + 0.1
    error = points[:, 2] - GROUND_Z
    assert np.median(np.abs(error)) < 0.003
    assert abs(np.median(error)) < 0.001
