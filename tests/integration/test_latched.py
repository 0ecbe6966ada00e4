"""``ow_runtime.latched``: a latched publisher tells every subscriber that it latches, also one
that connects between the publisher's registration with the master and the moment rospy enables
its latch (the window in which a loaded machine once recorded ``/viz/terrain`` as not latched).

A registration listener holds that window open: it runs once the topic is registered and waits
there until a subscriber in another process, started before and waiting for a publisher, has
connected. That subscriber prints the connection header of the first message it receives."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

import pytest
import rospy
from rospy.impl.registration import Registration, RegistrationListener, get_registration_listeners
from std_msgs.msg import String
from tf2_msgs.msg import TFMessage

from ow_runtime.latched import latched_publisher, static_transform_broadcaster

#: The subscriber: prints the first message's connection header as JSON and exits.
SUBSCRIBER = """
import json, sys, threading
import rospy
rospy.init_node("latched_test_subscriber", anonymous=True, disable_signals=True)
done = threading.Event()
def on(msg):
    print(json.dumps(dict(msg._connection_header)), flush=True)
    done.set()
rospy.Subscriber(sys.argv[1], rospy.AnyMsg, on)
print("subscribed", flush=True)
done.wait(30.0)
"""


class _HoldRegistration(RegistrationListener):
    """On the registration of ``topic`` as published here, waits (10 s at most) until a
    subscriber has connected to this node's publisher of it, and keeps whether one did."""

    def __init__(self, topic: str) -> None:
        self.topic = topic
        self.connected_in_window: bool | None = None

    def reg_added(self, resolved_name: str, data_type_or_uri: str, reg_type: str) -> None:
        if resolved_name != self.topic or reg_type != Registration.PUB:
            return
        impl = rospy.topics.get_topic_manager().pubs[resolved_name]
        deadline = time.monotonic() + 10.0
        while not impl.connections and time.monotonic() < deadline:
            time.sleep(0.01)
        self.connected_in_window = bool(impl.connections)


@contextmanager
def _held(topic: str) -> Iterator[_HoldRegistration]:
    listeners = get_registration_listeners()
    hold = _HoldRegistration(topic)
    with listeners.lock:
        listeners.listeners.append(hold)
    try:
        yield hold
    finally:
        with listeners.lock:
            listeners.listeners.remove(hold)


def _first_header(topic: str, make: Callable[[], Any]) -> dict:
    """The connection header of the first message received by a subscriber (another process)
    that connected inside the registration window of the publisher ``make()`` creates."""
    proc = subprocess.Popen(
        [sys.executable, "-c", SUBSCRIBER, topic], stdout=subprocess.PIPE, text=True
    )
    publisher = None
    try:
        assert proc.stdout is not None
        assert proc.stdout.readline().strip() == "subscribed"
        with _held(topic) as hold:
            publisher = make()
        assert hold.connected_in_window, "the subscriber did not connect inside the window"
        if isinstance(publisher, rospy.Publisher):
            publisher.publish(String("latched"))
        else:
            from geometry_msgs.msg import TransformStamped

            transform = TransformStamped()
            transform.header.frame_id, transform.child_frame_id = "world", "test_latched"
            transform.transform.rotation.w = 1.0
            publisher.sendTransform(transform)
        out, _ = proc.communicate(timeout=30.0)
        return json.loads(out)
    finally:
        proc.kill()
        proc.wait()
        if publisher is not None:
            getattr(publisher, "pub_tf", publisher).unregister()  # a broadcaster's publisher


def test_rospy_alone_tells_a_subscriber_of_that_window_it_does_not_latch(ros_stack):
    """The defect the helper exists for, still in the installed rospy."""
    header = _first_header(
        "/latched_test/plain",
        lambda: rospy.Publisher("/latched_test/plain", String, queue_size=1, latch=True),
    )
    assert header["latching"] == "0"


def test_a_latched_publisher_tells_a_subscriber_of_that_window_it_latches(ros_stack):
    header = _first_header(
        "/latched_test/helper", lambda: latched_publisher("/latched_test/helper", String)
    )
    assert header["latching"] == "1"


def test_the_static_transform_broadcaster_latches_tf_static_from_registration(ros_stack):
    header = _first_header("/tf_static", static_transform_broadcaster)
    assert header["latching"] == "1"
    assert header["type"] == TFMessage._type


def test_a_topic_published_here_already_keeps_its_publisher(ros_stack):
    first = latched_publisher("/latched_test/twice", String)
    try:
        second = latched_publisher("/latched_test/twice", String)
        assert second.impl is first.impl
        second.unregister()
    finally:
        first.unregister()
    with pytest.raises(KeyError):
        _ = rospy.topics.get_topic_manager().pubs["/latched_test/twice"]
