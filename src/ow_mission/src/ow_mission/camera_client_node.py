"""The mission's stereo capture through OceanWATERS' ``CameraCapture`` (rospy/actionlib wiring
only; :mod:`ow_mission.workspace_capture` makes the files and the report's entry of it)."""

from __future__ import annotations

import threading
from typing import Any

import numpy as np
import rospy
from actionlib_msgs.msg import GoalStatus
from sensor_msgs.msg import CameraInfo, Image, PointCloud2

from ow_cameras import protocol
from ow_cameras.conversions import cloud_points, image_pixels
from ow_cameras.errors import CameraError
from ow_mission.errors import CaptureError
from ow_mission.workspace_capture import StereoShot
from ow_runtime.action_client import ActionClient, connect
from ow_runtime.connections import wait_sending
from owl_msgs.msg import CameraCaptureAction, CameraCaptureGoal

#: The capture's messages the mission keeps, by topic: the left image, its intrinsics, the cloud.
TOPICS: dict[str, type] = {
    protocol.LEFT_IMAGE_RAW: Image,
    protocol.LEFT_CAMERA_INFO: CameraInfo,
    protocol.POINTS2: PointCloud2,
}
#: s of wall time the messages may come after the goal's end (each topic on its own connection).
MESSAGES_WAIT_S = 10.0


class _Received:
    """The newest message of each of :data:`TOPICS` while subscribed."""

    def __init__(self) -> None:
        self._changed = threading.Condition()
        self.latest: dict[str, Any] = {}
        self.subscribers = [
            # One capture's cloud is 7.7 MB at the default size: a buffer that takes it whole.
            rospy.Subscriber(topic, cls, self._on, topic, queue_size=1, buff_size=2**25)
            for topic, cls in TOPICS.items()
        ]

    def _on(self, msg: Any, topic: str) -> None:
        with self._changed:
            self.latest[topic] = msg
            self._changed.notify_all()

    def wait_for_one_stamp(self, timeout_s: float) -> dict[str, Any] | None:
        """Every topic's message of one stamp (wall ``timeout_s`` at most), or None."""

        def complete() -> bool:
            stamps = {m.header.stamp for m in self.latest.values()}
            return len(self.latest) == len(TOPICS) and len(stamps) == 1

        with self._changed:
            if not self._changed.wait_for(complete, timeout_s):
                return None
            return dict(self.latest)

    def close(self) -> None:
        for subscriber in self.subscribers:
            subscriber.unregister()


def capture_workspace(timeout_s: float) -> StereoShot:
    """Send one ``CameraCapture`` goal and return its left image, intrinsics and point cloud.

    Args:
        timeout_s: s of wall time for the connection and the capture each.

    Raises:
        CaptureError: no camera node, the goal did not succeed (its status text), or its
            messages did not come.
    """
    received = _Received()
    try:
        for subscriber in received.subscribers:
            if not wait_sending(subscriber, timeout_s):
                msg = f"the camera node's {subscriber.resolved_name} not connected in {timeout_s} s"
                raise CaptureError(msg)
        try:
            client = connect(protocol.CAMERA_CAPTURE, CameraCaptureAction, timeout_s)
        except TimeoutError as error:
            raise CaptureError(str(error)) from error
        try:
            succeeded, text = _run(client, timeout_s)
        finally:
            _release(client)
        if not succeeded:
            msg = f"{protocol.CAMERA_CAPTURE} did not succeed: {text}"
            raise CaptureError(msg)
        messages = received.wait_for_one_stamp(MESSAGES_WAIT_S)
    finally:
        received.close()
    if messages is None:
        msg = (
            f"{protocol.CAMERA_CAPTURE} succeeded but its images did not come within "
            f"{MESSAGES_WAIT_S:g} s"
        )
        raise CaptureError(msg)
    try:
        left = image_pixels(messages[protocol.LEFT_IMAGE_RAW])
    except CameraError as error:
        raise CaptureError(f"{protocol.LEFT_IMAGE_RAW}: {error}") from error
    cloud = messages[protocol.POINTS2]
    return StereoShot(
        left=left,
        points=cloud_points(cloud),
        K=np.array(messages[protocol.LEFT_CAMERA_INFO].K, dtype=np.float64).reshape(3, 3),
        stamp_s=cloud.header.stamp.to_sec(),
    )


def _run(client: ActionClient, timeout_s: float) -> tuple[bool, str]:
    """Send a goal and wait for its end: (whether it succeeded, its status text).

    Raises:
        CaptureError: no end within ``timeout_s`` s of wall time (the goal is then cancelled).
    """
    client.send_goal(CameraCaptureGoal())
    if not client.wait_for_end(timeout_s):
        client.cancel_goal()
        msg = f"{protocol.CAMERA_CAPTURE}: no end within {timeout_s:g} s (wall)"
        raise CaptureError(msg)
    return client.get_state() == GoalStatus.SUCCEEDED, client.get_goal_status_text()


def _release(client: ActionClient) -> None:
    """Leave the action's topics: the mission captures once, and the server's status heartbeat
    would otherwise come to it all mission long."""
    ac = client.action_client
    for topic in (ac.status_sub, ac.result_sub, ac.feedback_sub, ac.pub_goal, ac.pub_cancel):
        topic.unregister()
