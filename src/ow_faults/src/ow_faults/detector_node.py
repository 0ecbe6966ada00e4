"""``rosrun ow_faults detector``: OceanWATERS' fault telemetry and FaultClear (rospy wiring)."""

from __future__ import annotations

import sys
import threading
from functools import partial
from typing import Any

import rospy
from actionlib_msgs.msg import GoalStatusArray
from sensor_msgs.msg import Image
from std_msgs.msg import Empty

from ow_faults.detection import FaultDetector, FaultStatus, action_group, cleared_text
from ow_faults.errors import FaultError
from ow_faults.listener_node import FaultsListener
from ow_faults.stream_order import PacingStream
from ow_msgs.msg import JointStatesFlag
from ow_runtime.action_server import ActionServer
from ow_runtime.latched import latched_publisher
from ow_runtime.names import (
    ARM_ACTIONS,
    ARM_END_EFFECTOR_FORCE_TORQUE,
    ARM_FAULTS_STATUS,
    BATTERY_STATE_OF_CHARGE,
    BATTERY_TEMPERATURE,
    CAMERA_ACTIONS,
    CAMERA_FAULTS_STATUS,
    EVERY_MESSAGE,
    FLAGS_JOINT_STATES,
    PAN_TILT_ACTIONS,
    PAN_TILT_FAULTS_STATUS,
    POWER_FAULTS_STATUS,
    STEREO_LEFT_IMAGE_RAW,
    STEREO_LEFT_TRIGGER,
    SYSTEM_FAULTS_STATUS,
)
from ow_runtime.node import init_node, quiet_at_shutdown, spin
from ow_runtime.status_timer import share_status_timer
from owl_msgs.msg import (
    ArmEndEffectorForceTorque,
    ArmFaultsStatus,
    BatteryStateOfCharge,
    BatteryTemperature,
    CameraFaultsStatus,
    FaultClearAction,
    PanTiltFaultsStatus,
    PowerFaultsStatus,
    SystemFaultsStatus,
)

#: The action servers whose goals make goal errors (arm_services, pan_tilt and camera serve
#: them).
ACTIONS = (*ARM_ACTIONS, *PAN_TILT_ACTIONS, *CAMERA_ACTIONS)
#: s of wall time an input waits for the lock flags up to its stamp (ow_faults.stream_order).
PACING_TIMEOUT_S = 5.0

#: (topic, message class, FaultStatus field) of the five outputs.
OUTPUTS = (
    (ARM_FAULTS_STATUS, ArmFaultsStatus, "arm"),
    (PAN_TILT_FAULTS_STATUS, PanTiltFaultsStatus, "pan_tilt"),
    (POWER_FAULTS_STATUS, PowerFaultsStatus, "power"),
    (SYSTEM_FAULTS_STATUS, SystemFaultsStatus, "system"),
    (CAMERA_FAULTS_STATUS, CameraFaultsStatus, "camera"),
)


class DetectorNode:
    """Publishes OceanWATERS' fault bitmasks (:mod:`ow_faults.detection` has the rules).

    Subscribes: ``/flags/joint_states`` (ow_msgs/JointStatesFlag, locked joints);
        ``/arm_end_effector_force_torque`` (owl_msgs/ArmEndEffectorForceTorque, its arrival);
        ``/battery_state_of_charge`` (owl_msgs/BatteryStateOfCharge, 0-1);
        ``/battery_temperature`` (owl_msgs/BatteryTemperature, degrees C);
        ``/faults/changes`` (ow_msgs/FaultChange: injected F/T zero signal,
        ``auto_clear_goal_errors``; the status a change makes is stamped with its stamp);
        ``/StereoCamera/left/image_trigger`` (std_msgs/Empty) and
        ``/StereoCamera/left/image_raw`` (sensor_msgs/Image): the stereo camera's triggers and
        left images (NO_IMAGE);
        ``/<Action>/status`` (actionlib_msgs/GoalStatusArray) of the arm, task, pan/tilt and
        camera actions.
    Publishes (latched, on every change; ``header.frame_id`` "world", stamp: the simulation
        time of the input that changed it, the wall clock's ROS time for a trigger, which has
        no stamp): ``/arm_faults_status`` (owl_msgs/ArmFaultsStatus),
        ``/pan_tilt_faults_status`` (owl_msgs/PanTiltFaultsStatus), ``/power_faults_status``
        (owl_msgs/PowerFaultsStatus), ``/system_faults_status`` (owl_msgs/SystemFaultsStatus),
        ``/camera_faults_status`` (owl_msgs/CameraFaultsStatus).
    Actions: ``FaultClear`` (owl_msgs/FaultClear): clears one *_GOAL_ERROR (2, 8, 16 or 64);
        another value is rejected naming it.
    """

    def __init__(self) -> None:
        self.detector = FaultDetector()
        self._lock = threading.Lock()
        self._flags = PacingStream()  # the simulation's lock flags pace the other inputs
        self._publishers = [
            (latched_publisher(topic, cls, queue_size=10), cls, field)
            for topic, cls, field in OUTPUTS
        ]
        self._publish(self.detector.status, rospy.Time(0))
        self.listener = FaultsListener(
            lambda faults, stamp_s: self._update(
                "on_injected", faults, stamp=rospy.Time.from_sec(stamp_s)
            ),
            "detector",
        )
        rospy.Subscriber(
            FLAGS_JOINT_STATES, JointStatesFlag, self._on_flags, queue_size=EVERY_MESSAGE
        )
        rospy.Subscriber(
            ARM_END_EFFECTOR_FORCE_TORQUE,
            ArmEndEffectorForceTorque,
            lambda m: self._update("on_wrist", m.header.stamp.to_sec(), stamp=m.header.stamp),
            queue_size=EVERY_MESSAGE,
        )
        rospy.Subscriber(
            BATTERY_STATE_OF_CHARGE,
            BatteryStateOfCharge,
            lambda m: self._update("on_soc", m.value, stamp=m.header.stamp),
            queue_size=EVERY_MESSAGE,
        )
        rospy.Subscriber(
            BATTERY_TEMPERATURE,
            BatteryTemperature,
            lambda m: self._update("on_temperature", m.value, stamp=m.header.stamp),
            queue_size=EVERY_MESSAGE,
        )
        # The stereo camera: its trigger (no stamp: the status is stamped now) and left image.
        rospy.Subscriber(
            STEREO_LEFT_TRIGGER, Empty, lambda _m: self._update("on_camera_trigger"), queue_size=10
        )
        rospy.Subscriber(
            STEREO_LEFT_IMAGE_RAW,
            Image,
            lambda m: self._update("on_camera_image", stamp=m.header.stamp),
            queue_size=2,
        )
        for action in ACTIONS:
            rospy.Subscriber(
                f"/{action}/status",
                GoalStatusArray,
                partial(self._on_status, action),
                queue_size=EVERY_MESSAGE,
            )
        self.clear_server = ActionServer("FaultClear", FaultClearAction, self._on_clear)
        self.clear_server.start()
        # Its status from a timer that outlives a clock set back (actionlib's own ends).
        self._status_timer = share_status_timer([self.clear_server])

    def _on_flags(self, msg: JointStatesFlag) -> None:
        stamp = msg.header.stamp
        self._update("on_joint_flags", msg.name, msg.flags, stamp.to_sec(), stamp=stamp)
        self._flags.taken(stamp.to_sec())

    def _on_status(self, action: str, msg: GoalStatusArray) -> None:
        if not msg.status_list or action_group(action) is None:
            return
        # The newest goal: the latest stamp, and of goals stamped alike (sent while the clock
        # stood still) the last in the list, which the server keeps in order of arrival.
        _, newest = max(
            enumerate(msg.status_list), key=lambda item: (item[1].goal_id.stamp, item[0])
        )
        # Stamped with the server's clock when it published the status (the arm services in a
        # mission: the time the simulation is held at when a goal ends).
        self._update(
            "on_goal_status", action, newest.goal_id.id, newest.status, stamp=msg.header.stamp
        )

    def _update(self, rule: str, *args: Any, stamp: Any = None) -> None:
        paced = stamp is not None and rule != "on_joint_flags"  # the flags up to it first
        if paced and not self._flags.wait_for(stamp.to_sec(), PACING_TIMEOUT_S):
            rospy.logwarn(f"detector: no lock flags up to t={stamp.to_sec():.3f} s")
        with self._lock:
            if getattr(self.detector, rule)(*args):
                self._publish(self.detector.status, rospy.Time.now() if stamp is None else stamp)

    @quiet_at_shutdown
    def _publish(self, status: FaultStatus, stamp: Any) -> None:
        for publisher, cls, field in self._publishers:
            msg = cls(value=getattr(status, field))
            msg.header.stamp = stamp
            msg.header.frame_id = "world"
            publisher.publish(msg)

    def _on_clear(self, handle: Any) -> None:
        fault = handle.get_goal().fault
        with self._lock:
            try:
                changed = self.detector.clear(fault)
            except FaultError as error:
                # OceanWATERS' server accepts every goal and aborts a bad one.
                handle.set_accepted()
                handle.set_aborted(text=str(error))
                return
            if changed:
                self._publish(self.detector.status, rospy.Time.now())
        handle.set_accepted()
        handle.set_succeeded(text=cleared_text(fault))


def main() -> int:
    """Run the detector until shutdown."""
    init_node("detector")
    DetectorNode()
    rospy.loginfo(
        "detector: publishing /arm_faults_status, /pan_tilt_faults_status, "
        "/power_faults_status, /system_faults_status, /camera_faults_status"
    )
    spin()
    return 0


if __name__ == "__main__":
    sys.exit(main())
