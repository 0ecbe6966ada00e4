"""Messages of the cameras' arrays and back (generated message classes, no rospy).

The readers (:func:`image_pixels`, :func:`cloud_points`) serve clients of the camera too (the
mission), which must not load pinocchio: it is imported by :func:`transform_msg` alone, when the
node first calls it.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt
from geometry_msgs.msg import TransformStamped
from sensor_msgs.msg import CameraInfo, Image, PointCloud2, PointField

from ow_cameras.errors import CameraError
from ow_cameras.rig import Pinhole

#: The fields of the point clouds, as stereo_image_proc writes them: x, y, z (m) and rgb (the
#: colour packed 0x00RRGGBB in a float32's bits), 16 bytes a point.
CLOUD_FIELDS = [
    PointField(name="x", offset=0, datatype=PointField.FLOAT32, count=1),
    PointField(name="y", offset=4, datatype=PointField.FLOAT32, count=1),
    PointField(name="z", offset=8, datatype=PointField.FLOAT32, count=1),
    PointField(name="rgb", offset=12, datatype=PointField.FLOAT32, count=1),
]


def image_msg(rgb: npt.NDArray[np.uint8], stamp: Any, frame_id: str) -> Image:
    """A ``sensor_msgs/Image`` (rgb8) of ``rgb`` ((height, width, 3) uint8)."""
    height, width = rgb.shape[:2]
    msg = Image(height=height, width=width, encoding="rgb8", is_bigendian=0, step=3 * width)
    msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    msg.data = np.ascontiguousarray(rgb, dtype=np.uint8).tobytes()
    return msg


def camera_info_msg(pinhole: Pinhole, stamp: Any, frame_id: str, tx_px_m: float) -> CameraInfo:
    """A ``sensor_msgs/CameraInfo`` of a distortion-free camera of a rectified pair (``tx_px_m``:
    ``P[0, 3]``, px m, 0 for the left camera and ``-fx * baseline`` for the right one)."""
    msg = CameraInfo(width=pinhole.width, height=pinhole.height, distortion_model="plumb_bob")
    msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    msg.D = [0.0] * 5
    msg.K = pinhole.K.ravel().tolist()
    msg.R = np.eye(3).ravel().tolist()
    msg.P = pinhole.P(tx_px_m).ravel().tolist()
    return msg


def cloud_msg(
    points: npt.NDArray[np.float32], rgb: npt.NDArray[np.uint8], stamp: Any, frame_id: str
) -> PointCloud2:
    """An organised ``sensor_msgs/PointCloud2`` of ``points`` ((height, width, 3) m, NaN where
    there is none) coloured by ``rgb`` ((height, width, 3) uint8)."""
    height, width = points.shape[:2]
    packed = (
        (rgb[:, :, 0].astype(np.uint32) << 16)
        | (rgb[:, :, 1].astype(np.uint32) << 8)
        | rgb[:, :, 2].astype(np.uint32)
    )
    data = np.empty((height, width, 4), dtype="<f4")
    data[:, :, :3] = points
    data[:, :, 3] = packed.view("<f4")
    msg = PointCloud2(
        height=height,
        width=width,
        fields=CLOUD_FIELDS,
        is_bigendian=False,
        point_step=16,
        row_step=16 * width,
        is_dense=bool(np.isfinite(points).all()),
    )
    msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    msg.data = data.tobytes()
    return msg


def image_pixels(msg: Any) -> npt.NDArray[np.uint8]:
    """(height, width, 3) RGB of an rgb8 ``sensor_msgs/Image`` (as :func:`image_msg` writes).

    Raises:
        CameraError: the image is not rgb8, or its data is not height x step bytes.
    """
    if msg.encoding != "rgb8" or len(msg.data) != msg.height * msg.step:
        msg_text = (
            f"image of encoding {msg.encoding!r} with {len(msg.data)} bytes is not an rgb8 image "
            f"of {msg.height} rows of {msg.step} bytes"
        )
        raise CameraError(msg_text)
    rows = np.frombuffer(msg.data, dtype=np.uint8).reshape(msg.height, msg.step)
    return rows[:, : 3 * msg.width].reshape(msg.height, msg.width, 3)


def cloud_points(msg: Any) -> npt.NDArray[np.float32]:
    """(height, width, 3) m of an organised ``PointCloud2`` written by :func:`cloud_msg`."""
    data = np.frombuffer(msg.data, dtype="<f4").reshape(msg.height, msg.width, 4)
    return data[:, :, :3]


def transform_msg(parent: str, child: str, X: npt.NDArray[np.float64], stamp: Any) -> Any:
    """A ``geometry_msgs/TransformStamped`` of ``X`` ((4, 4), ``child`` in ``parent``)."""
    msg = TransformStamped()
    msg.header.stamp = stamp
    msg.header.frame_id = parent
    msg.child_frame_id = child
    msg.transform.translation.x, msg.transform.translation.y, msg.transform.translation.z = (
        float(v) for v in X[:3, 3]
    )
    import pinocchio as pin

    quaternion = pin.Quaternion(np.ascontiguousarray(X[:3, :3]))
    quaternion.normalize()
    x, y, z, w = (float(v) for v in quaternion.coeffs())
    msg.transform.rotation.x, msg.transform.rotation.y = x, y
    msg.transform.rotation.z, msg.transform.rotation.w = z, w
    return msg
