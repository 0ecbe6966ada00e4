"""OceanWATERS' camera trigger fault end to end on a master: ``camera_left_trigger_failure`` set
through the ``/faults`` server (dynamic_reconfigure, as a user does), the camera node, the fault
detector and the simulation.

With the fault a ``CameraCapture`` aborts ("Timed out waiting for point cloud"), publishing the
right image only; the aborted goal is a CAMERA_GOAL_ERROR; the second trigger still without a
left image is NO_IMAGE and CAMERA_EXECUTION_ERROR (OceanWATERS' detector does not flag the
first). Cleared, a capture succeeds and every camera bit goes. With ``auto_clear_goal_errors``
false the CAMERA group is refused until ``FaultClear``.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import Any

import pytest
from actionlib_msgs.msg import GoalStatus
from dynamic_reconfigure.client import Client
from sensor_msgs.msg import Image, PointCloud2

from ow_bringup.testing import action_client, subscribe
from ow_cameras import protocol
from ow_description.description import DEFAULT_GROUND_Z
from ow_faults.injection import FaultSet
from ow_faults.protocol import APPLIED_TOPIC
from ow_msgs.msg import FaultChangeApplied
from ow_runtime.names import (
    CAMERA_FAULTS_STATUS,
    STEREO_LEFT_IMAGE_RAW,
    STEREO_LEFT_TRIGGER,
    SYSTEM_FAULTS_STATUS,
)
from owl_msgs.msg import (
    CameraCaptureAction,
    CameraCaptureGoal,
    CameraFaultsStatus,
    FaultClearAction,
    FaultClearGoal,
    SystemFaultsStatus,
)

RESULT_WAIT_S = 120.0  # s of wall time (a capture takes 1-5 s, more on a loaded machine)
GOAL_ERROR = SystemFaultsStatus.CAMERA_GOAL_ERROR
EXECUTION_ERROR = SystemFaultsStatus.CAMERA_EXECUTION_ERROR
NO_IMAGE = CameraFaultsStatus.NO_IMAGE


class Messages:
    """Every message of one topic, and waits for one that matches."""

    def __init__(self, topic: str, msg_type: type) -> None:
        self.topic = topic
        self.received: list[Any] = []
        self._changed = threading.Condition()
        subscribe(topic, msg_type, self._on)

    def _on(self, msg: Any) -> None:
        with self._changed:
            self.received.append(msg)
            self._changed.notify_all()

    def take(self) -> list[Any]:
        with self._changed:
            taken, self.received = self.received, []
        return taken

    def wait_for(self, predicate: Callable[[Any], bool], what: str, timeout_s: float = 30.0):
        with self._changed:
            if not self._changed.wait_for(
                lambda: any(predicate(m) for m in self.received), timeout_s
            ):
                pytest.fail(f"timed out waiting for {what} on {self.topic}")
            return next(m for m in reversed(self.received) if predicate(m))


@pytest.fixture(scope="module")
def stack(ros_stack):
    ros_stack.start_node("ow_faults", "faults", wait_for_services=["/faults/set_parameters"])
    ros_stack.start_node(
        "ow_sim_bullet",
        "sim",
        params={
            "real_time_factor": 1.0,
            "terrain": f"flat:{DEFAULT_GROUND_Z}",
            # The mast looks at bare ground (as test_cameras): captures that succeed have points.
            "initial_positions": {"j_ant_pan": 3.1, "j_ant_tilt": 0.9},
        },
        wait_for_topics=["/joint_states"],
    )
    ros_stack.start_node(
        "ow_cameras", "camera", wait_for_topics=[f"/{protocol.CAMERA_CAPTURE}/status"]
    )
    # The detector last: its subscriptions find the camera's publishers when it registers them
    # (a publisher registered later reaches a subscriber only through the master's update, which
    # a loaded CI once missed for good); then until it is connected to all three.
    ros_stack.start_node("ow_faults", "detector", wait_for_topics=[CAMERA_FAULTS_STATUS])
    watched = [f"/{protocol.CAMERA_CAPTURE}/status", STEREO_LEFT_TRIGGER, STEREO_LEFT_IMAGE_RAW]
    deadline = time.monotonic() + 30.0
    while ros_stack.master.unconnected(watched):
        assert time.monotonic() < deadline, f"unconnected: {ros_stack.master.unconnected(watched)}"
        time.sleep(0.01)
    ros_stack.faults = Client("/faults", timeout=30)
    # The tests compare whole bitmasks: a fault injected from the start would set bits of its
    # own (one an earlier module on this master left injected: ow_bringup.testing.module_stack).
    injected = FaultSet.from_dict(ros_stack.faults.get_configuration(timeout=30)).active()
    assert not injected, f"the /faults server started with faults injected: {injected}"
    ros_stack.applied = Messages(APPLIED_TOPIC, FaultChangeApplied)
    ros_stack.camera = Messages(CAMERA_FAULTS_STATUS, CameraFaultsStatus)
    ros_stack.system = Messages(SYSTEM_FAULTS_STATUS, SystemFaultsStatus)
    ros_stack.left = Messages(protocol.LEFT_IMAGE_RAW, Image)
    ros_stack.right = Messages(protocol.RIGHT_IMAGE_RAW, Image)
    ros_stack.points = Messages(protocol.POINTS2, PointCloud2)
    ros_stack.capture = action_client(protocol.CAMERA_CAPTURE, CameraCaptureAction)
    ros_stack.clear = action_client("FaultClear", FaultClearAction)
    return ros_stack


def inject(stack, **faults: Any) -> None:
    """Set ``faults`` on the /faults server and wait until the camera node has applied them."""
    stack.applied.take()
    version = stack.faults.update_configuration(faults)
    assert all(version[name] == value for name, value in faults.items()), version
    stack.applied.wait_for(lambda m: m.node == "/camera", "the camera node applying the change")


def capture(stack) -> tuple[int, str]:
    """A CameraCapture goal to its end: (state, status text)."""
    client = stack.capture
    client.send_goal(CameraCaptureGoal())
    assert client.wait_for_end(RESULT_WAIT_S), "no result"
    return client.get_state(), client.get_goal_status_text()


def latest_value(messages: Messages, what: str, expected: int) -> None:
    """Wait until the newest message of a status topic has value ``expected``."""
    messages.wait_for(lambda m: m is messages.received[-1] and m.value == expected, what)


def test_a_failing_left_trigger_aborts_captures_and_sets_the_camera_bits(stack):
    inject(stack, camera_left_trigger_failure=True)
    for topic in (stack.left, stack.right, stack.points):
        topic.take()

    state, text = capture(stack)
    assert state == GoalStatus.ABORTED
    assert text.startswith("Timed out waiting for point cloud")  # OceanWATERS' text first
    assert protocol.LEFT_TRIGGER_FAILURE in text  # then why
    stack.right.wait_for(lambda m: True, "the right image (never gated)")
    time.sleep(0.5)  # anything else the capture published would be here by now
    assert not stack.left.take() and not stack.points.take()
    latest_value(stack.system, "CAMERA_GOAL_ERROR", GOAL_ERROR)
    assert stack.camera.received[-1].value == 0  # the first failed trigger is not flagged

    state, _ = capture(stack)
    assert state == GoalStatus.ABORTED
    latest_value(stack.camera, "NO_IMAGE", NO_IMAGE)
    latest_value(
        stack.system, "CAMERA_EXECUTION_ERROR and _GOAL_ERROR", GOAL_ERROR | EXECUTION_ERROR
    )

    inject(stack, camera_left_trigger_failure=False)
    state, text = capture(stack)
    assert (state, text) == (GoalStatus.SUCCEEDED, "Point cloud received")
    stack.points.wait_for(lambda m: True, "the point cloud")
    latest_value(stack.camera, "no camera fault", 0)
    latest_value(stack.system, "no system fault", 0)


def test_without_auto_clear_the_camera_group_is_refused_until_fault_clear(stack):
    inject(stack, auto_clear_goal_errors=False, camera_left_trigger_failure=True)
    assert capture(stack)[0] == GoalStatus.ABORTED
    latest_value(stack.system, "CAMERA_GOAL_ERROR", GOAL_ERROR)
    inject(stack, camera_left_trigger_failure=False)
    state, text = capture(stack)
    assert state == GoalStatus.ABORTED
    assert "CAMERA_GOAL_ERROR stands and auto_clear_goal_errors is false" in text

    stack.clear.send_goal(FaultClearGoal(fault=GOAL_ERROR))
    assert stack.clear.wait_for_end(30.0)
    assert stack.clear.get_state() == GoalStatus.SUCCEEDED
    latest_value(stack.system, "the goal error cleared", 0)
    assert capture(stack) == (GoalStatus.SUCCEEDED, "Point cloud received")
    inject(stack, auto_clear_goal_errors=True)
