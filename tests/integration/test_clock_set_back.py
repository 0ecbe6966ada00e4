"""A clock set back under running nodes (a simulation restarted, a bag replayed in a loop):
every action server's periodic status goes on from the new time. actionlib's own status timer,
a ``rospy.Timer``, ends its thread with ``ROSTimeMovedBackwardsException`` instead; every server
publishes from ``share_status_timer``'s, which restarts.

``/clock`` is published by this test, so that it can set it back: the nodes run without a
simulation (their action servers start without one)."""

from __future__ import annotations

import threading
import time

import rospy
from actionlib_msgs.msg import GoalStatusArray
from rosgraph_msgs.msg import Clock

from ow_bringup.testing import advertise, subscribe, wait_connected

#: the status topics of the action servers of each node started here.
NODES = {
    ("ow_lander", "pan_tilt"): ["/PanTiltMoveJoints/status", "/PanTiltMoveCartesian/status"],
    ("ow_faults", "detector"): ["/FaultClear/status"],
}
STEP = 0.01  # s of sim time a /clock message
STATUSES = 3  # after the set-back, from each server


class Statuses:
    """The stamps (s) of each status topic's messages."""

    def __init__(self, topics: list[str]) -> None:
        self._lock = threading.Lock()
        self._stamps: dict[str, list[float]] = {topic: [] for topic in topics}
        self.subs = [
            subscribe(topic, GoalStatusArray, lambda m, topic=topic: self._on(topic, m))
            for topic in topics
        ]

    def _on(self, topic: str, msg: GoalStatusArray) -> None:
        with self._lock:
            self._stamps[topic].append(msg.header.stamp.to_sec())

    def since(self, start: float, end: float) -> dict[str, list[float]]:
        with self._lock:
            stamps = {topic: list(got) for topic, got in self._stamps.items()}
        return {topic: [s for s in got if start <= s <= end] for topic, got in stamps.items()}


def _run_clock(clock: rospy.Publisher, start: float, statuses: Statuses) -> dict[str, list[float]]:
    """Publish /clock from ``start`` on, a step every few ms of wall time, until every server
    sent :data:`STATUSES` statuses stamped from ``start`` (at most 60 s of sim time); those."""
    t = start
    while True:
        clock.publish(Clock(rospy.Time(*divmod(round(t * 1e9), 10**9))))
        seen = statuses.since(start, t)
        if all(len(stamps) >= STATUSES for stamps in seen.values()) or t > start + 60.0:
            return seen
        time.sleep(0.003)
        t += STEP


def test_every_action_servers_status_goes_on_after_the_clock_is_set_back(ros_stack):
    clock = advertise("/clock", Clock, queue_size=100)
    topics = [topic for topics in NODES.values() for topic in topics]
    statuses = Statuses(topics)
    clock.publish(Clock(rospy.Time(100)))  # the nodes start at 100 s
    started = [
        (ros_stack.start_node(package, executable, wait=False), served)
        for (package, executable), served in NODES.items()
    ]
    for node, served in started:
        ros_stack.wait_ready(node, topics=served)
    for sub in statuses.subs:
        wait_connected(sub)
    wait_connected(clock)
    before = _run_clock(clock, 100.0, statuses)
    assert all(len(stamps) >= STATUSES for stamps in before.values()), before
    after = _run_clock(clock, 1.0, statuses)  # set back by 99 s
    assert all(len(stamps) >= STATUSES for stamps in after.values()), after
