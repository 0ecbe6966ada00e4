"""``ow_mission.connections_node``: a subscription counts as sending only once the publisher's
node writes to it, read from the publisher's side (``getBusInfo``), not from the count rospy
keeps on the subscriber's side."""

from __future__ import annotations

import time

import rospy
from std_msgs.msg import String

from ow_mission.connections_node import publishers_send_to, wait_sending
from ow_mission.testing import advertise, subscribe


def test_a_subscription_is_sending_once_its_publishers_write_to_it(ros_stack):
    received: list[str] = []
    sub = subscribe("/connections_test", String, lambda m: received.append(m.data))
    pub = None
    try:
        assert not publishers_send_to(sub)  # no publisher
        assert not wait_sending(sub, 0.2)
        pub = advertise("/connections_test", String, queue_size=10)
        assert wait_sending(sub, 10.0)
        # The publisher's side lists this node: what it publishes now arrives.
        assert rospy.get_name() in {c.endpoint_id for c in pub.impl.connections}
        pub.publish(String("first"))
        deadline = time.monotonic() + 10.0
        while not received and time.monotonic() < deadline:
            time.sleep(0.01)
        assert received == ["first"]
    finally:
        sub.unregister()
        if pub is not None:
            pub.unregister()
