"""The scoop tip for the velocity ground detector, from ``/tf`` (rospy wiring only): part of the
arm services' observing side (:class:`~ow_lander.arm_services.observer.ArmObserver`)."""

from __future__ import annotations

import threading
from collections.abc import Callable

import numpy as np
import rospy
import tf2_ros
from tf2_msgs.msg import TFMessage

from ow_description.description import BASE_FRAME, SCOOP_TIP_FRAME
from ow_lander import conversions as conv
from ow_lander.execution.guard_streams import GuardStreams
from ow_lander.execution.monitor import ExecutionMonitor
from ow_runtime.names import EVERY_MESSAGE, TF, TF_STATIC


class TipSampler:
    """Feeds the running monitor the scoop tip (base_link) at each ``/tf`` stamp its velocity
    detector wants, and its guard streams every ``/tf`` stamp.

    A ``/tf`` message is read for its stamps only and deserialised when one is wanted: 30 Hz of
    a dozen frames, for nothing outside a guarded descent. tf2 gets the static transforms and
    those of the wanted stamps only: the simulation sends all its movable frames of a stamp in
    one message, and a lookup at a stored stamp is that stamp's.

    Args:
        condition: the observer's condition; its lock guards the monitor and the streams.
        streams: the observer's guard streams (``"tip"`` arrives here).
        monitor: the running execution monitor, or None.
        publish_signals: publishes a monitor's detector samples.
    """

    def __init__(
        self,
        condition: threading.Condition,
        streams: GuardStreams,
        monitor: Callable[[], ExecutionMonitor | None],
        publish_signals: Callable[[ExecutionMonitor], None],
    ) -> None:
        self._condition = condition
        self._streams = streams
        self._monitor = monitor
        self._publish_signals = publish_signals
        self._tf = tf2_ros.BufferCore(rospy.Duration(30.0))
        rospy.Subscriber(TF, rospy.AnyMsg, self._on_tf, queue_size=EVERY_MESSAGE, tcp_nodelay=True)
        rospy.Subscriber(TF_STATIC, TFMessage, self._on_tf_static, queue_size=10)

    def _on_tf_static(self, msg: TFMessage) -> None:
        for transform in msg.transforms:
            self._tf.set_transform_static(transform, "sim")

    def _on_tf(self, msg: rospy.AnyMsg) -> None:
        data = msg._buff
        try:
            times = conv.tf_message_stamps(data)
        except ValueError as error:
            rospy.logwarn_throttle(5.0, f"arm services: /tf message skipped: {error}")
            return
        if not times:
            return
        monitor = self._monitor()
        if monitor is not None and any(monitor.wants_tip(t) for t in set(times)):
            self._sample(TFMessage().deserialize(data))
        # Only now: a decision waiting for the tip stream to reach a stamp must see a contact
        # at that stamp (the simulation's /tf and joint states share stamps). Marked before
        # the sample, a contact at t=40.17 s was once acted on a joint state late, under load.
        with self._condition:
            self._streams.arrived("tip", max(times))

    def _sample(self, msg: TFMessage) -> None:
        """Feed the monitor the scoop tip at each stamp of ``msg`` it wants, in stamp order."""
        stamps = {transform.header.stamp for transform in msg.transforms}
        for stamp in sorted(stamps):
            monitor = self._monitor()
            if monitor is None or not monitor.wants_tip(stamp.to_sec()):
                continue
            for transform in msg.transforms:
                if transform.header.stamp == stamp:
                    self._tf.set_transform(transform, "sim")
            try:
                tip = self._tf.lookup_transform_core(BASE_FRAME, SCOOP_TIP_FRAME, stamp)
            except tf2_ros.TransformException:
                continue  # not every link's transform of this stamp has arrived yet
            p = tip.transform.translation
            with self._condition:
                contact = monitor.tip_sample(stamp.to_sec(), np.array([p.x, p.y, p.z]))
                if contact:
                    self._condition.notify_all()
            self._publish_signals(monitor)
            if contact:
                return
