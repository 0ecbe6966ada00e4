"""The camera node on the real simulation, through actionlib's stock SimpleActionClient: captures
publish both images, their CameraInfo and a point cloud with one stamp (the simulation time of
the capture) that an exact-time synchronizer pairs, the cloud lies on the ground the simulation
holds, exposure and lights change the pictures and the power drawn, bad goals are refused naming
the field, and the injected trigger fault makes a capture fail without a left image."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import Any

import actionlib
import message_filters
import numpy as np
import pytest
import rospy
from actionlib_msgs.msg import GoalStatus
from dynamic_reconfigure.msg import BoolParameter, Config
from sensor_msgs.msg import CameraInfo, Image, JointState, PointCloud2
from std_msgs.msg import Empty, Float64

from ow_bringup.testing import advertise, subscribe, tf_buffer, wait_connected, wait_for_server
from ow_cameras import protocol
from ow_cameras.conversions import cloud_points
from ow_cameras.rig import LEFT_OPTICAL_FRAME
from ow_description.description import DEFAULT_GROUND_Z
from ow_faults.protocol import CHANGES_TOPIC
from ow_msgs.msg import FaultChange
from ow_power.loads import LOADS_TOPIC
from owl_msgs.msg import (
    CameraCaptureAction,
    CameraCaptureGoal,
    CameraSetExposureAction,
    CameraSetExposureGoal,
    LightSetIntensityAction,
    LightSetIntensityGoal,
)

RESULT_WAIT_S = 120.0  # s of wall time (a capture takes 1-5 s, more on a loaded machine)
#: The mast looks back over the lander's +y side at bare flat ground (the stowed arm out of view,
#: the simulation's terrain all the way up the image): 1.6 to 2.3 m away.
PAN, TILT = 3.1, 0.9
#: m, median |z - ground| of the cloud's points in base_link: see docs/cameras.md (the unit
#: test's bound, with the simulation's own terrain and the joint states' small offsets).
CLOUD_MEDIAN_BOUND_M = 0.005


class Recorder:
    """Every message of some topics, by topic."""

    def __init__(self, topics: dict[str, type]) -> None:
        self.lock = threading.Lock()
        self.messages: dict[str, list[Any]] = {topic: [] for topic in topics}
        for topic, cls in topics.items():
            subscribe(topic, cls, self._on, callback_args=topic)

    def _on(self, msg: Any, topic: str) -> None:
        with self.lock:
            self.messages[topic].append(msg)

    def take(self) -> dict[str, list[Any]]:
        with self.lock:
            taken = {topic: list(msgs) for topic, msgs in self.messages.items()}
            for msgs in self.messages.values():
                msgs.clear()
        return taken

    def latest(self) -> Any:
        """The data of the newest message of the first topic (None before any)."""
        with self.lock:
            msgs = next(iter(self.messages.values()))
            return msgs[-1].data if msgs else None

    def wait_for(self, topic: str, count: int = 1, timeout_s: float = RESULT_WAIT_S) -> None:
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            with self.lock:
                if len(self.messages[topic]) >= count:
                    return
            time.sleep(0.02)
        pytest.fail(f"no {topic} within {timeout_s} s")


TOPICS = {
    protocol.LEFT_IMAGE_RAW: Image,
    protocol.LEFT_CAMERA_INFO: CameraInfo,
    protocol.RIGHT_IMAGE_RAW: Image,
    protocol.RIGHT_CAMERA_INFO: CameraInfo,
    protocol.LEFT_IMAGE_RECT_COLOR: Image,
    protocol.RIGHT_IMAGE_RECT_COLOR: Image,
    protocol.POINTS2: PointCloud2,
}


class Synchronized:
    """OceanWATERS' IdentifySampleLocation's inputs: an exact-time synchronizer (queue 10) of
    the left rectified image and the point cloud; the pairs it made."""

    def __init__(self) -> None:
        self.pairs: list[tuple[Image, PointCloud2]] = []
        image = message_filters.Subscriber(protocol.LEFT_IMAGE_RECT_COLOR, Image)
        cloud = message_filters.Subscriber(protocol.POINTS2, PointCloud2)
        self.filters = (image, cloud)
        self.sync = message_filters.TimeSynchronizer([image, cloud], 10)
        self.sync.registerCallback(lambda i, c: self.pairs.append((i, c)))


@pytest.fixture(scope="module")
def cameras(ros_stack):
    ros_stack.start_node(
        "ow_sim_bullet",
        "sim",
        params={
            "real_time_factor": 1.0,
            "terrain": f"flat:{DEFAULT_GROUND_Z}",
            "initial_positions": {"j_ant_pan": PAN, "j_ant_tilt": TILT},
        },
        wait_for_topics=["/joint_states"],
    )
    ros_stack.start_node(
        "ow_cameras", "camera", wait_for_topics=[f"/{protocol.CAMERA_CAPTURE}/status"]
    )
    clients = {}
    for name, action in (
        (protocol.CAMERA_CAPTURE, CameraCaptureAction),
        (protocol.CAMERA_SET_EXPOSURE, CameraSetExposureAction),
        (protocol.LIGHT_SET_INTENSITY, LightSetIntensityAction),
    ):
        client = actionlib.SimpleActionClient(name, action)
        wait_for_server(client, 30.0)
        clients[name] = client
    recorder = Recorder(TOPICS)
    loads = Recorder({LOADS_TOPIC: Float64})
    synchronized = Synchronized()
    tf = tf_buffer()  # from now on: the tests look up the frames at their captures' stamps
    yield clients, recorder, loads, synchronized, tf
    for f in synchronized.filters:
        f.sub.unregister()


def run(client: Any, goal: Any) -> tuple[int, str]:
    """Send ``goal``, wait for its end: (state, status text)."""
    client.send_goal(goal)
    assert client.wait_for_result(rospy.Duration(RESULT_WAIT_S)), "no result"
    return client.get_state(), client.get_goal_status_text()


def capture(clients: dict[str, Any]) -> tuple[int, str]:
    return run(clients[protocol.CAMERA_CAPTURE], CameraCaptureGoal())


def pixels(msg: Image) -> np.ndarray:
    return np.frombuffer(msg.data, dtype=np.uint8).reshape(msg.height, msg.width, 3)


def set_light(clients: dict[str, Any], name: str, intensity: float) -> tuple[int, str]:
    goal = LightSetIntensityGoal(name=name, intensity=intensity)
    return run(clients[protocol.LIGHT_SET_INTENSITY], goal)


def set_exposure(clients: dict[str, Any], exposure: float, automatic: bool = False) -> Any:
    goal = CameraSetExposureGoal(automatic=automatic, exposure=exposure)
    return run(clients[protocol.CAMERA_SET_EXPOSURE], goal)


def test_a_capture_publishes_images_info_and_cloud_with_one_stamp(cameras):
    clients, recorder, _, synchronized, _ = cameras
    recorder.take()
    before = rospy.wait_for_message("/joint_states", JointState, timeout=10).header.stamp
    state, text = capture(clients)
    assert state == GoalStatus.SUCCEEDED, text
    assert text == "Point cloud received"
    recorder.wait_for(protocol.POINTS2)
    got = recorder.take()
    assert all(len(msgs) == 1 for msgs in got.values()), {t: len(m) for t, m in got.items()}
    stamps = {msgs[0].header.stamp for msgs in got.values()}
    assert len(stamps) == 1, stamps
    (stamp,) = stamps
    assert stamp >= before  # the simulation time of a joint state at or after the goal
    assert stamp.to_sec() > 0.0
    assert {msgs[0].header.frame_id for msgs in got.values()} == {LEFT_OPTICAL_FRAME}
    left, right = got[protocol.LEFT_IMAGE_RAW][0], got[protocol.RIGHT_IMAGE_RAW][0]
    assert (left.width, left.height, left.encoding) == (800, 600, "rgb8")
    assert not np.array_equal(pixels(left), pixels(right))  # two viewpoints
    right_info = got[protocol.RIGHT_CAMERA_INFO][0]
    assert right_info.P[3] == pytest.approx(-right_info.P[0] * 0.2)
    cloud = got[protocol.POINTS2][0]
    assert (cloud.width, cloud.height) == (800, 600)
    deadline = time.monotonic() + 10.0
    while not any(c.header.stamp == stamp for _, c in synchronized.pairs):
        assert time.monotonic() < deadline, "the exact-time synchronizer made no pair"
        time.sleep(0.05)


def test_the_cloud_lies_on_the_simulated_ground(cameras):
    clients, recorder, _, _, buffer = cameras
    recorder.take()
    assert capture(clients)[0] == GoalStatus.SUCCEEDED
    recorder.wait_for(protocol.POINTS2)
    cloud = recorder.take()[protocol.POINTS2][0]
    transform = buffer.lookup_transform(
        "base_link", LEFT_OPTICAL_FRAME, cloud.header.stamp, rospy.Duration(10.0)
    )
    t, q = transform.transform.translation, transform.transform.rotation
    x, y, z, w = q.x, q.y, q.z, q.w
    R = np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )
    points = cloud_points(cloud).reshape(-1, 3)
    valid = np.isfinite(points).all(axis=1)
    assert valid.mean() > 0.5  # all but the columns the right camera cannot see
    base = points[valid] @ R.T + np.array([t.x, t.y, t.z])
    error = base[:, 2] - DEFAULT_GROUND_Z
    assert np.median(np.abs(error)) < CLOUD_MEDIAN_BOUND_M


def test_exposure_scales_the_brightness(cameras):
    clients, recorder, _, _, _ = cameras
    means = {}
    for exposure in (0.0005, 0.001):
        state, text = set_exposure(clients, exposure)
        assert state == GoalStatus.SUCCEEDED, text
        assert text == f"Exposure set to {exposure}"
        recorder.take()
        assert capture(clients)[0] == GoalStatus.SUCCEEDED
        recorder.wait_for(protocol.LEFT_IMAGE_RAW)
        means[exposure] = pixels(recorder.take()[protocol.LEFT_IMAGE_RAW][0]).mean()
    assert means[0.001] / means[0.0005] == pytest.approx(2.0, rel=0.05)


@pytest.mark.parametrize(
    ("automatic", "exposure", "state", "text"),
    [
        (False, -1.0, GoalStatus.SUCCEEDED, "Exposure not changed"),
        (False, 0.0, GoalStatus.SUCCEEDED, "Exposure not changed"),
        (True, 0.01, GoalStatus.ABORTED, "CameraSetExposure action does not support autoexposure."),
        (False, float("inf"), GoalStatus.ABORTED, "exposure = inf s is not a finite number"),
    ],
)
def test_exposure_goals_end_as_oceanwaters(cameras, automatic, exposure, state, text):
    clients = cameras[0]
    got_state, got_text = set_exposure(clients, exposure, automatic)
    assert got_state == state
    assert got_text.startswith(text)


def test_lights_change_the_picture_and_the_power_drawn(cameras):
    clients, recorder, loads, _, _ = cameras
    images = {}
    for intensity in (0.0, 1.0):
        for name in ("left", "Right"):  # any case, as OceanWATERS
            state, text = set_light(clients, name, intensity)
            assert state == GoalStatus.SUCCEEDED, text
            assert text == f"{name.lower()} light intensity set successfully."
        assert rospy.get_param(protocol.LIGHT_PARAMS["left"]) == intensity
        assert rospy.get_param(protocol.LIGHT_PARAMS["right"]) == intensity
        lights_w = 2 * 4.8 * intensity
        _until(lambda w=lights_w: loads.latest() == pytest.approx(w))
        loads.take()
        recorder.take()
        assert capture(clients)[0] == GoalStatus.SUCCEEDED
        recorder.wait_for(protocol.LEFT_IMAGE_RAW)
        images[intensity] = pixels(recorder.take()[protocol.LEFT_IMAGE_RAW][0]).astype(float)
        _until(lambda w=lights_w: loads.latest() == pytest.approx(w))
        drawn = [m.data for m in loads.take()[LOADS_TOPIC]]
        assert drawn == pytest.approx([lights_w + 0.1, lights_w])  # the cameras while capturing
    added = images[1.0] - images[0.0]
    # The lights reach the bare ground in view (about 7 W/m^2 beside the sun's 25, at 2 m).
    assert np.median(added) >= 10.0


@pytest.mark.parametrize(
    ("name", "intensity", "text"),
    [
        ("left", 1.5, "Intensity = 1.5 is out of range."),
        ("left", -0.1, "Intensity = -0.1 is out of range."),
        ("left", float("nan"), "Intensity = nan is out of range."),
        ("Top", 0.5, "'top' is not a light identifier."),
        ("top", 2.0, "Intensity = 2.0 is out of range."),  # the range is checked first
    ],
)
def test_bad_light_goals_are_refused_naming_the_field(cameras, name, intensity, text):
    state, got = set_light(cameras[0], name, intensity)
    assert state == GoalStatus.ABORTED
    assert got.startswith(text)


def test_the_trigger_topic_captures_too(cameras):
    _, recorder, _, _, _ = cameras
    trigger = wait_connected(advertise(protocol.LEFT_TRIGGER, Empty, queue_size=1))
    recorder.take()
    trigger.publish(Empty())
    recorder.wait_for(protocol.POINTS2)
    assert len(recorder.take()[protocol.LEFT_IMAGE_RAW]) == 1


def _fault_change(left_fails: bool, version: int) -> FaultChange:
    msg = FaultChange(version=version)
    msg.header.stamp = rospy.Time.now()
    msg.config = Config(
        bools=[
            BoolParameter(name=protocol.LEFT_TRIGGER_FAILURE, value=left_fails),
            BoolParameter(name="auto_clear_goal_errors", value=True),
        ]
    )
    return msg


def _until(condition: Callable[[], bool], timeout_s: float = 10.0) -> None:
    deadline = time.monotonic() + timeout_s
    while not condition():
        assert time.monotonic() < deadline
        time.sleep(0.05)


def test_the_trigger_fault_fails_a_capture_without_a_left_image(cameras):
    clients, recorder, _, _, _ = cameras
    # What the /faults server publishes on a change (test_camera_fault.py sets the fault
    # through the server itself, with the detector).
    changes = wait_connected(advertise(CHANGES_TOPIC, FaultChange, queue_size=1, latch=True))
    changes.publish(_fault_change(True, 1))
    time.sleep(0.5)
    recorder.take()
    state, text = capture(clients)
    assert state == GoalStatus.ABORTED
    assert text.startswith("Timed out waiting for point cloud")
    assert protocol.LEFT_TRIGGER_FAILURE in text
    recorder.wait_for(protocol.RIGHT_IMAGE_RAW)
    time.sleep(0.5)
    got = recorder.take()
    assert len(got[protocol.RIGHT_IMAGE_RAW]) == 1  # the right camera is not gated
    assert not got[protocol.LEFT_IMAGE_RAW]
    assert not got[protocol.POINTS2]
    changes.publish(_fault_change(False, 2))
    time.sleep(0.5)
    assert capture(clients)[0] == GoalStatus.SUCCEEDED
