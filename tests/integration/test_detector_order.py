"""``ow_faults.detector_node.DetectorNode`` takes a goal's end after the simulation's lock flags
up to it: the two arrive on connections of their own, the flags in the simulation's batches,
and a goal's end taken first published a status stamped at the goal's end without the lock
flagged before it (a run's bag showed the lock cleared there; two equal missions differed)."""

from __future__ import annotations

import threading
import time

import pytest
import rospy
from actionlib_msgs.msg import GoalID, GoalStatus, GoalStatusArray
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Header

from ow_bringup.testing import advertise, wait_connected
from ow_faults.detector_node import DetectorNode
from ow_msgs.msg import JointStatesFlag

JOINTS = ["j_shou_yaw", "j_shou_pitch"]


def _flags(t: float, locked: bool) -> JointStatesFlag:
    return JointStatesFlag(Header(stamp=rospy.Time.from_sec(t)), JOINTS, [False, locked])


@pytest.fixture()
def detector(ros_stack):
    """The detector in this process; its status timers end with the test: the one it stopped
    (actionlib's own) and its shared one wake to a /clock a second on and see they are stopped,
    rather than to the next module's simulation starting at 0 (a clock set back, which ends a
    timer actionlib made with an exception)."""
    node = DetectorNode()
    yield node
    node._status_timer.shutdown()
    clock = wait_connected(advertise("/clock", Clock, queue_size=1))  # this process's own clock
    timers = (node._status_timer, node.clear_server.status_timer)
    deadline = time.monotonic() + 20.0
    while any(timer.is_alive() for timer in timers):  # a second on, again (from 0: twice)
        assert time.monotonic() < deadline, "the detector's status timers did not end"
        clock.publish(Clock(rospy.get_rostime() + rospy.Duration(1.0)))
        time.sleep(0.1)
    clock.unregister()


def test_a_goals_end_is_taken_after_the_flags_before_it(detector):
    published: list[tuple[float, int]] = []
    publish = detector._publish
    detector._publish = lambda status, stamp: (
        published.append((stamp.to_sec(), status.arm)),
        publish(status, stamp),
    )
    detector._on_flags(_flags(39.0, False))
    detector._on_flags(_flags(39.01, False))
    aborted = GoalStatusArray(
        Header(stamp=rospy.Time.from_sec(40.92)),
        [GoalStatus(GoalID(rospy.Time.from_sec(39.0), "grind"), GoalStatus.ABORTED, "")],
    )
    ended = threading.Thread(target=detector._on_status, args=("TaskGrind", aborted))
    ended.start()  # the goal's end arrives first ...
    time.sleep(0.2)
    for k in range(2, 192):  # ... then the flags, the shoulder locked from 39.81 s
        t = round(39.0 + k * 0.01, 2)
        detector._on_flags(_flags(t, t >= 39.81))
    ended.join(timeout=10.0)
    stamps = [t for t, _ in published]
    assert stamps == sorted(stamps)  # in stamp order: no status goes back in time
    at_end = [arm for t, arm in published if abs(t - 40.92) < 1e-6]
    assert at_end and all(arm & 1 for arm in at_end)  # HARDWARE: the lock is still flagged
