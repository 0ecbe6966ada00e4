"""``ow_lander.arm_services.tip_sampler.TipSampler``: a ``/tf`` message counts as arrived on the tip
stream only once its tip has been sampled. The simulation's ``/tf`` and joint states share
stamps, and a decision on the joint state of ``t`` waits for the tip stream to reach ``t``: it
must see a contact found at ``t``. Marked before the sample, a contact was once acted on one
joint state late (a run that differed from its twin under load)."""

from __future__ import annotations

import threading
from io import BytesIO

import genpy
import numpy as np
import rospy
from geometry_msgs.msg import Quaternion, Transform, TransformStamped, Vector3
from std_msgs.msg import Header
from tf2_msgs.msg import TFMessage

from ow_description.description import BASE_FRAME, SCOOP_TIP_FRAME
from ow_lander.arm_services.tip_sampler import TipSampler
from ow_lander.execution.guard_streams import GuardStreams


def _transform(parent: str, child: str, stamp: genpy.Time) -> TransformStamped:
    return TransformStamped(
        Header(stamp=stamp, frame_id=parent),
        child,
        Transform(Vector3(1.0, 0.0, -0.1), Quaternion(0.0, 0.0, 0.0, 1.0)),
    )


class _Monitor:
    """Records, at each tip sample, how far the tip stream counted as arrived."""

    def __init__(self, streams: GuardStreams) -> None:
        self.streams = streams
        self.samples: list[tuple[float, float]] = []

    def wants_tip(self, t: float) -> bool:
        return True

    def tip_sample(self, t: float, position: np.ndarray) -> bool:
        self.samples.append((t, self.streams.newest["tip"]))
        return False


def test_the_tip_stream_reaches_a_stamp_only_after_that_stamps_tip_is_sampled(ros_stack):
    condition = threading.Condition()
    streams = GuardStreams(condition)
    monitor = _Monitor(streams)
    sampler = TipSampler(condition, streams, lambda: monitor, lambda _: None)
    sampler._on_tf_static(TFMessage([_transform(BASE_FRAME, SCOOP_TIP_FRAME, genpy.Time(0))]))
    buffer = BytesIO()
    TFMessage([_transform("world", "marker", genpy.Time(40, 170_000_000))]).serialize(buffer)
    message = rospy.AnyMsg()
    message._buff = buffer.getvalue()
    sampler._on_tf(message)
    assert monitor.samples == [(40.17, -1.0)]  # sampled before the stream said 40.17 s
    assert streams.newest["tip"] == 40.17
