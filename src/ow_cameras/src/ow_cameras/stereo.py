"""Stereo reconstruction as ROS's ``stereo_image_proc`` does it, free of ROS: a rectified pair,
a disparity map from OpenCV's semi-global block matcher, and the points it reprojects to.

The renderer's cameras are ideal pinholes with parallel optical axes, the same intrinsics and no
distortion, 0.2 m apart along the left camera's x: their images are a rectified pair as they
come (the rectification ``stereo_image_proc`` would apply with OceanWATERS' CameraInfo, R = I
and D = 0, is the identity). So the matcher takes them as they are, and the reprojection matrix
Q is the one ROS's ``StereoCameraModel`` builds from the two CameraInfo projection matrices:
the right one has ``P[0, 3] = -fx * baseline``.

Accuracy (docs/cameras.md): a disparity ``d`` px is a depth ``Z = fx * B / d``; an error of
``e`` px in ``d`` is ``Z^2 / (fx * B) * e`` m in depth. SGBM's sub-pixel disparities (1/16 px)
on the textured ground are good to about 0.1-0.2 px.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
import numpy.typing as npt

from ow_cameras.config import StereoConfig
from ow_cameras.errors import StereoError
from ow_cameras.rig import BASELINE_M, Pinhole

Float32Array = npt.NDArray[np.float32]
ByteImage = npt.NDArray[np.uint8]

#: OpenCV's fixed-point disparity: 4 fractional bits.
_DISPARITY_SCALE = 16.0


@dataclass(frozen=True)
class StereoCloud:
    """A matched pair.

    Attributes:
        disparity: (height, width) px, left-image disparity (NaN: no match).
        points: (height, width, 3) m, the left optical frame's x right, y down, z forward
            (NaN where there is no match).
    """

    disparity: Float32Array
    points: Float32Array

    @property
    def valid(self) -> npt.NDArray[np.bool_]:
        """(height, width) pixels with a point."""
        return np.isfinite(self.disparity)


class StereoMatcher:
    """Disparities and points of rectified pairs of one camera pair.

    Args:
        config: the matcher's parameters.
        pinhole: both cameras' projection.
        baseline_m: m, the right camera's offset along the left camera's x.
    """

    def __init__(
        self, config: StereoConfig, pinhole: Pinhole, baseline_m: float = BASELINE_M
    ) -> None:
        self.config = config
        self.pinhole = pinhole
        self.baseline_m = baseline_m
        channels = 1
        block = config.block_size
        self._sgbm = cv2.StereoSGBM.create(
            minDisparity=config.min_disparity,
            numDisparities=config.num_disparities,
            blockSize=block,
            P1=8 * channels * block * block,
            P2=32 * channels * block * block,
            disp12MaxDiff=1,
            preFilterCap=63,
            uniquenessRatio=config.uniqueness_ratio,
            speckleWindowSize=config.speckle_window,
            speckleRange=config.speckle_range,
            mode=cv2.STEREO_SGBM_MODE_SGBM_3WAY,
        )

    @property
    def Q(self) -> npt.NDArray[np.float64]:
        """(4, 4) reprojection matrix: ``Q @ (u, v, d, 1)`` is the point (x, y, z, w)."""
        p = self.pinhole
        return np.array(
            [
                [1.0, 0.0, 0.0, -p.cx],
                [0.0, 1.0, 0.0, -p.cy],
                [0.0, 0.0, 0.0, p.focal_px],
                [0.0, 0.0, 1.0 / self.baseline_m, 0.0],
            ]
        )

    def match(self, left: ByteImage, right: ByteImage) -> StereoCloud:
        """Match a rectified pair.

        Args:
            left: (height, width, 3) RGB or (height, width) grey, uint8.
            right: the same shape.

        Raises:
            StereoError: the images are not uint8 of the pinhole's size, or differ in shape.
        """
        expected = (self.pinhole.height, self.pinhole.width)
        for name, image in (("left", left), ("right", right)):
            if image.dtype != np.uint8 or image.shape[:2] != expected or image.ndim not in (2, 3):
                msg = (
                    f"{name} image is {image.dtype} {image.shape}; the matcher takes uint8 "
                    f"{expected[0]} x {expected[1]} (grey or RGB)"
                )
                raise StereoError(msg)
        if left.shape != right.shape:
            msg = f"left image {left.shape} and right image {right.shape} differ in shape"
            raise StereoError(msg)
        raw = self._sgbm.compute(_grey(left), _grey(right))
        disparity = raw.astype(np.float32) / _DISPARITY_SCALE
        disparity[(raw < self.config.min_disparity * _DISPARITY_SCALE) | (raw <= 0)] = np.nan
        points = cv2.reprojectImageTo3D(np.nan_to_num(disparity, nan=-1.0), self.Q)
        points[~np.isfinite(disparity)] = np.nan
        return StereoCloud(disparity, points.astype(np.float32))


def _grey(image: ByteImage) -> ByteImage:
    if image.ndim == 2:
        return image
    return np.asarray(cv2.cvtColor(image, cv2.COLOR_RGB2GRAY), dtype=np.uint8)
