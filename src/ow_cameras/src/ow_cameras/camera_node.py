"""The camera node: OceanWATERS' stereo camera, its lights and their actions (rospy wiring only;
the images are :mod:`ow_cameras.capture`'s, the goals' decisions :mod:`ow_cameras.commands`')."""

from __future__ import annotations

import ctypes
import sys
import threading
import time
from typing import Any

import rospy
from sensor_msgs.msg import CameraInfo, Image, JointState, PointCloud2
from std_msgs.msg import Empty, Float64

from ow_cameras import commands, protocol
from ow_cameras.capture import Capture, Shot, StereoCamera
from ow_cameras.config import CameraConfig
from ow_cameras.conversions import camera_info_msg, cloud_msg, image_msg, transform_msg
from ow_cameras.errors import CameraError, ConfigError, GoalError
from ow_cameras.rig import BASELINE_M, FIXED_FRAMES, LEFT_OPTICAL_FRAME
from ow_description.conversions import height_map_from_msg
from ow_description.errors import TerrainError
from ow_description.terrain import HeightMap
from ow_faults.change_follower_node import ChangeFollower
from ow_msgs.msg import FaultChange
from ow_msgs.msg import HeightMap as HeightMapMsg
from ow_power.loads import LOADS_TOPIC
from ow_runtime.action_server import SimpleActionServer
from ow_runtime.latched import latched_publisher, static_transform_broadcaster
from ow_runtime.names import EVERY_MESSAGE, JOINT_STATES, SYSTEM_FAULTS_STATUS, TERRAIN_TOPIC
from ow_runtime.node import init_node, spin
from ow_runtime.status_timer import share_status_timer
from owl_msgs.msg import (
    CameraCaptureAction,
    CameraCaptureResult,
    CameraSetExposureAction,
    CameraSetExposureResult,
    LightSetIntensityAction,
    LightSetIntensityResult,
    SystemFaultsStatus,
)

#: s of wall time a CameraCapture goal waits for its capture at most (one takes 1-5 s).
CAPTURE_WAIT_S = 120.0
#: s of wall time between a waiting goal's looks at a cancel.
_POLL_S = 0.05
#: s of wall time a capture waits for the first ``/sim/terrain`` of a simulation it is connected
#: to (the latched message is on its way: drawn without it, the ground would be the fallback's).
TERRAIN_WAIT_S = 5.0


def _glibc() -> ctypes.CDLL | None:
    try:
        return ctypes.CDLL("libc.so.6")
    except OSError:
        return None


#: glibc, for ``malloc_trim`` after each capture (None elsewhere).
_LIBC = _glibc()


def _trim_heap() -> None:
    """Give the heap's free memory back to the system. A capture's arrays (~130 MB at 800 x 600)
    are freed into glibc's heap, which keeps them mapped: without this the node stayed that much
    larger after its first capture, for the rest of a mission (320 MB resident instead of
    ~190 MB)."""
    if _LIBC is not None:
        _LIBC.malloc_trim(0)


class CameraNode:
    """OceanWATERS' triggered stereo camera (``StereoCamera``), ``stereo_image_proc`` and the two
    mast lights, rendered headless on request: nothing is drawn until a capture is asked for.

    A capture poses the lander from the newest ``/joint_states`` (the mast's pan and tilt place
    the cameras), draws both cameras on the newest ``/sim/terrain``, matches them and publishes
    the images, their CameraInfo, the rectified images and the point cloud, all stamped with that
    joint state's stamp (the simulation time the pictures show). Captures run one at a time in a
    thread of their own; triggers arriving meanwhile are served by one more capture.

    Actions (owl_msgs; OceanWATERS' semantics and status texts, docs/cameras.md):
        ``CameraCapture``: a capture; SUCCEEDED "Point cloud received" once its cloud is out;
            ABORTED "Timed out waiting for point cloud ..." when the left camera's trigger
            fails (no cloud); PREEMPTED "Action was preempted" on a cancel (the capture still
            publishes).
        ``CameraSetExposure``: ``automatic`` refused; ``exposure`` s > 0 sets it for the next
            captures ("Exposure set to 0.01"), <= 0 keeps it ("Exposure not changed").
        ``LightSetIntensity``: ``name`` "left"/"right" (any case), ``intensity`` 0 to 1.
        While SystemFaultsStatus CAMERA_GOAL_ERROR stands and ``auto_clear_goal_errors`` is
        false, CameraCapture and CameraSetExposure goals are refused (OceanWATERS' CAMERA group).

    Subscriptions:
        ``/joint_states`` (sensor_msgs/JointState): the newest only; joints by name, rad.
        ``/sim/terrain`` (ow_msgs/HeightMap): the ground, m (flat at ``~fallback_ground_z``
            until one arrives; a capture waits up to :data:`TERRAIN_WAIT_S` for the first
            while a simulation publishing it is connected).
        ``/StereoCamera/left/image_trigger`` (std_msgs/Empty): a capture, as the action's.
        ``/gazebo/plugins/camera_sim/exposure`` (std_msgs/Float64): s, > 0 sets the exposure.
        ``/faults/changes`` (ow_msgs/FaultChange, through ChangeFollower):
            ``camera_left_trigger_failure``, ``auto_clear_goal_errors``.
        ``/system_faults_status`` (owl_msgs/SystemFaultsStatus): CAMERA_GOAL_ERROR.

    Publications (every capture, one stamp; frame_id ``StereoCameraLeft_optical_frame`` for
    all, as OceanWATERS' plugin with its ``hackBaseline``):
        ``/StereoCamera/{left,right}/image_raw`` (sensor_msgs/Image, rgb8).
        ``/StereoCamera/{left,right}/camera_info`` (sensor_msgs/CameraInfo): no distortion; the
            right P[0, 3] = -fx * 0.2 px m.
        ``/StereoCamera/{left,right}/image_rect_color`` (sensor_msgs/Image, rgb8).
        ``/StereoCamera/points2`` (sensor_msgs/PointCloud2): organised height x width, x y z
            (m, left optical frame) rgb; NaN where the pair did not match.
        While ``camera_left_trigger_failure`` is injected only the right image and camera_info.
        ``/electrical_power`` (std_msgs/Float64, W, latched; ow_power's loads): lights 4.8 W
            each at intensity 1, the cameras 0.1 W during a capture.
        ``/tf_static``: the camera and light frames under ``l_ant_panel`` (OceanWATERS' names).
        Parameters ``/OWLightControlPlugin/{left,right}_light`` (0-1): the lights' intensities,
            mirrored for OceanWATERS clients.

    Parameters (private, read once): :class:`~ow_cameras.config.CameraConfig`.
    """

    def __init__(self, config: CameraConfig) -> None:
        self.config = config
        self._lock = threading.Lock()
        self._changed = threading.Condition(self._lock)
        self._joint_state: JointState | None = None
        self._terrain: HeightMap | None = None
        self._exposure_s = config.exposure_s
        self._intensities = {"left": config.lights.left, "right": config.lights.right}
        self._left_fails = False
        self._auto_clear = True
        self._system_faults = 0
        self._requested = 0  # captures asked for
        self._done = 0  # the request number the last finished capture served
        self._last_outcome: tuple[bool, str] = (False, "")
        self._capturing = False
        self._camera_ready = threading.Event()

        self._frame = LEFT_OPTICAL_FRAME
        self._publishers = {
            topic: rospy.Publisher(topic, cls, queue_size=2)
            for topic, cls in (
                (protocol.LEFT_IMAGE_RAW, Image),
                (protocol.LEFT_CAMERA_INFO, CameraInfo),
                (protocol.RIGHT_IMAGE_RAW, Image),
                (protocol.RIGHT_CAMERA_INFO, CameraInfo),
                (protocol.LEFT_IMAGE_RECT_COLOR, Image),
                (protocol.RIGHT_IMAGE_RECT_COLOR, Image),
                (protocol.POINTS2, PointCloud2),
            )
        }
        self._load = latched_publisher(LOADS_TOPIC, Float64, queue_size=10)
        self._static = static_transform_broadcaster()
        stamp = rospy.Time.now()
        self._static.sendTransform(
            [transform_msg(parent, child, X, stamp) for parent, child, X in FIXED_FRAMES]
        )
        self._publish_lights()

        self._worker = threading.Thread(target=self._work, name="captures", daemon=True)
        self._worker.start()

        rospy.Subscriber(JOINT_STATES, JointState, self._on_joint_state, queue_size=1)
        self._terrain_sub = rospy.Subscriber(
            TERRAIN_TOPIC, HeightMapMsg, self._on_terrain, queue_size=1
        )
        rospy.Subscriber(protocol.LEFT_TRIGGER, Empty, self._on_trigger, queue_size=10)
        rospy.Subscriber(protocol.EXPOSURE_TOPIC, Float64, self._on_exposure, queue_size=10)
        rospy.Subscriber(
            SYSTEM_FAULTS_STATUS, SystemFaultsStatus, self._on_system, queue_size=EVERY_MESSAGE
        )
        self.follower = ChangeFollower(self._on_fault_change)
        self._trigger = rospy.Publisher(protocol.LEFT_TRIGGER, Empty, queue_size=10)

        self.capture_server = SimpleActionServer(
            protocol.CAMERA_CAPTURE, CameraCaptureAction, self._on_capture
        )
        self.exposure_server = SimpleActionServer(
            protocol.CAMERA_SET_EXPOSURE, CameraSetExposureAction, self._on_exposure_goal
        )
        self.light_server = SimpleActionServer(
            protocol.LIGHT_SET_INTENSITY, LightSetIntensityAction, self._on_light_goal
        )
        servers = (self.capture_server, self.exposure_server, self.light_server)
        for server in servers:
            server.start()
        # One status timer that outlives a clock set back (actionlib's own end their thread).
        self._status_timer = share_status_timer([s.action_server for s in servers])

    def wait_ready(self, timeout_s: float) -> bool:
        """Wait (wall time) until the renderer has started; whether it has."""
        return self._camera_ready.wait(timeout_s)

    # -------------------------------------------------------------------------------- inputs
    def _on_joint_state(self, msg: JointState) -> None:
        with self._lock:
            self._joint_state = msg

    def _on_terrain(self, msg: Any) -> None:
        try:
            terrain = height_map_from_msg(msg)
        except TerrainError as error:
            rospy.logerr(f"camera: /sim/terrain ignored: {error}")
            return
        with self._lock:
            self._terrain = terrain
            self._changed.notify_all()

    def _on_trigger(self, msg: Any) -> None:
        header = getattr(msg, "_connection_header", None) or {}
        if header.get("callerid") == rospy.get_name():
            return  # our own CameraCapture's trigger: that goal asked for its capture already
        self._request()

    def _on_exposure(self, msg: Float64) -> None:
        try:
            exposure = commands.exposure_change(False, float(msg.data))
        except GoalError as error:
            rospy.logwarn(f"camera: {protocol.EXPOSURE_TOPIC} ignored: {error}")
            return
        if exposure is not None:
            with self._lock:
                self._exposure_s = exposure

    def _on_system(self, msg: SystemFaultsStatus) -> None:
        with self._lock:
            self._system_faults = int(msg.value)

    def _on_fault_change(self, msg: FaultChange, _stamp_s: float) -> None:
        values = {kv.name: kv.value for kv in msg.config.bools}
        with self._lock:
            self._left_fails = bool(values.get(protocol.LEFT_TRIGGER_FAILURE, False))
            self._auto_clear = bool(values.get("auto_clear_goal_errors", True))

    # ------------------------------------------------------------------------------ captures
    def _request(self) -> int:
        """Ask for a capture; the number it will serve."""
        with self._lock:
            self._requested += 1
            self._changed.notify_all()
            return self._requested

    def _work(self) -> None:
        """The capture thread: owns the renderer; one capture per wake-up, serving every request
        made before it started."""
        try:
            camera = StereoCamera(self.config)
        except CameraError as error:
            rospy.logfatal(f"camera: cannot start the renderer: {error}")
            rospy.signal_shutdown("no renderer")
            return
        self._camera_ready.set()
        while not rospy.is_shutdown():
            with self._lock:
                self._changed.wait_for(
                    lambda: self._requested > self._done or rospy.is_shutdown(), 1.0
                )
                if self._requested <= self._done:
                    continue
                self._changed.wait_for(
                    lambda: (
                        self._terrain is not None or not self._terrain_sub.get_num_connections()
                    ),
                    TERRAIN_WAIT_S,
                )
                serving = self._requested
                state, shot = self._shot()
            outcome = self._capture(camera, shot) if shot is not None else (False, state)
            _trim_heap()
            with self._lock:
                self._done = serving
                self._last_outcome = outcome
                self._changed.notify_all()
        camera.close()

    def _shot(self) -> tuple[str, Shot | None]:
        """What the next capture is of (under the lock); without a joint state, why none."""
        state = self._joint_state
        if state is None:
            return "no /joint_states yet: the mast's pose, and so the cameras', is unknown", None
        positions = dict(zip(state.name, state.position, strict=False))
        return "", Shot(
            joint_positions=positions,
            stamp_ns=state.header.stamp.to_nsec(),
            terrain=self._terrain,
            exposure_s=self._exposure_s,
            intensities=dict(self._intensities),
            left_fails=self._left_fails,
        )

    def _capture(self, camera: StereoCamera, shot: Shot) -> tuple[bool, str]:
        """Run one capture and publish it; (whether a point cloud went out, the goal's text)."""
        self._set_capturing(True)
        try:
            if shot.terrain is None:
                rospy.logwarn_once(
                    "camera: no /sim/terrain yet: drawing flat ground at "
                    f"z = {self.config.fallback_ground_z} m"
                )
            capture = camera.capture(shot)
            self._publish(capture)
        except CameraError as error:
            rospy.logerr(f"camera: capture failed: {error}")
            return False, f"{commands.CAPTURE_TIMED_OUT}: the capture failed: {error}"
        finally:
            self._set_capturing(False)
        timings = ", ".join(f"{k} {1e3 * v:.0f} ms" for k, v in capture.timings_s.items())
        rospy.loginfo(f"camera: capture at t = {shot.stamp_ns * 1e-9:.3f} s ({timings})")
        if capture.cloud is None:
            return False, (
                f"{commands.CAPTURE_TIMED_OUT}: {protocol.LEFT_TRIGGER_FAILURE} is injected, the "
                "left image was not published and no point cloud was made"
            )
        return True, commands.CAPTURE_SUCCEEDED

    def _publish(self, capture: Capture) -> None:
        stamp = rospy.Time(capture.stamp_ns // 10**9, capture.stamp_ns % 10**9)
        pinhole, frame = self.config.pinhole, self._frame
        tx = -pinhole.focal_px * BASELINE_M
        right = image_msg(capture.right, stamp, frame)
        self._publishers[protocol.RIGHT_IMAGE_RAW].publish(right)
        self._publishers[protocol.RIGHT_CAMERA_INFO].publish(
            camera_info_msg(pinhole, stamp, frame, tx)
        )
        if capture.left is None or capture.cloud is None:
            return
        left = image_msg(capture.left, stamp, frame)
        self._publishers[protocol.LEFT_IMAGE_RAW].publish(left)
        self._publishers[protocol.LEFT_CAMERA_INFO].publish(
            camera_info_msg(pinhole, stamp, frame, 0.0)
        )
        self._publishers[protocol.LEFT_IMAGE_RECT_COLOR].publish(left)
        self._publishers[protocol.RIGHT_IMAGE_RECT_COLOR].publish(right)
        self._publishers[protocol.POINTS2].publish(
            cloud_msg(capture.cloud.points, capture.left, stamp, frame)
        )

    # -------------------------------------------------------------------------------- goals
    def _refusal(self) -> str | None:
        """Why a goal of the CAMERA group is refused now, or None."""
        bit = SystemFaultsStatus.CAMERA_GOAL_ERROR
        with self._lock:
            if self._system_faults & bit and not self._auto_clear:
                return (
                    "CAMERA_GOAL_ERROR stands and auto_clear_goal_errors is false: clear it with "
                    f"FaultClear (fault: {bit})"
                )
        return None

    def _on_capture(self, _goal: Any) -> None:
        server, result = self.capture_server, CameraCaptureResult()
        refused = self._refusal()
        if refused is not None:
            server.set_aborted(result, refused)
            return
        serving = self._request()
        self._trigger.publish(Empty())  # for those who watch the trigger (a fault detector)
        outcome = self._wait_for_capture(serving)
        if outcome is None:
            server.set_preempted(result, commands.PREEMPTED)
            return
        succeeded, text = outcome
        finish = server.set_succeeded if succeeded else server.set_aborted
        finish(result, text)

    def _wait_for_capture(self, serving: int) -> tuple[bool, str] | None:
        """(whether it published a point cloud, the goal's text) of the capture serving request
        ``serving``; None on a cancel of the running CameraCapture goal."""
        deadline = time.monotonic() + CAPTURE_WAIT_S
        while not rospy.is_shutdown():
            with self._lock:
                if self._changed.wait_for(lambda: self._done >= serving, _POLL_S):
                    return self._last_outcome
            if self.capture_server.is_preempt_requested():
                return None
            if time.monotonic() > deadline:
                break
        return False, f"{commands.CAPTURE_TIMED_OUT}: no capture within {CAPTURE_WAIT_S:.0f} s"

    def _on_exposure_goal(self, goal: Any) -> None:
        server, result = self.exposure_server, CameraSetExposureResult()
        refused = self._refusal()
        if refused is not None:
            server.set_aborted(result, refused)
            return
        try:
            exposure = commands.exposure_change(bool(goal.automatic), float(goal.exposure))
        except GoalError as error:
            server.set_aborted(result, str(error))
            return
        if exposure is not None:
            with self._lock:
                self._exposure_s = exposure
        server.set_succeeded(result, commands.exposure_text(exposure))

    def _on_light_goal(self, goal: Any) -> None:
        server, result = self.light_server, LightSetIntensityResult()
        try:
            name, intensity = commands.light_change(str(goal.name), float(goal.intensity))
        except GoalError as error:
            server.set_aborted(result, str(error))
            return
        with self._lock:
            self._intensities[name] = intensity
        self._publish_lights()
        server.set_succeeded(result, commands.light_text(name))

    # -------------------------------------------------------------------------------- power
    def _set_capturing(self, capturing: bool) -> None:
        with self._lock:
            self._capturing = capturing
        self._publish_load()

    def _publish_lights(self) -> None:
        with self._lock:
            intensities = dict(self._intensities)
        for name, param in protocol.LIGHT_PARAMS.items():
            rospy.set_param(param, intensities[name])
        self._publish_load()

    def _publish_load(self) -> None:
        with self._lock:
            load = commands.electrical_power_w(self.config, self._intensities, self._capturing)
        self._load.publish(Float64(load))


def main(argv: list[str] | None = None) -> int:
    """Run the camera node until shutdown; 1 on a configuration error."""
    init_node("camera", argv=argv)
    try:
        config = CameraConfig.from_dict(rospy.get_param("~", {}))
    except ConfigError as exc:
        rospy.logfatal(f"camera: {exc}")
        return 1
    node = CameraNode(config)
    if not node.wait_ready(60.0):
        rospy.logwarn("camera: the renderer is still starting")
    rospy.loginfo(
        f"camera: {config.width} x {config.height} px stereo pair, CameraCapture, "
        "CameraSetExposure and LightSetIntensity ready"
    )
    spin()
    return 0


if __name__ == "__main__":
    sys.exit(main())
