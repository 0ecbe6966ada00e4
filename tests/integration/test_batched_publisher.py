"""``ow_runtime.batched_publisher.BatchedPublisher``: what a callback publishes goes out
through a writer thread, several messages per socket write, and the subscribers receive every
message, in order, with the sequence numbers rospy would have given them."""

from __future__ import annotations

import time

import rospy
from geometry_msgs.msg import PointStamped
from std_msgs.msg import Header

from ow_bringup.testing import subscribe
from ow_runtime.batched_publisher import BatchedPublisher

COUNT = 2000


def test_every_message_arrives_in_order_and_in_fewer_writes_than_messages(ros_stack):
    received: list[PointStamped] = []
    sub = subscribe("/batched_test", PointStamped, received.append)
    publisher = BatchedPublisher("/batched_test", PointStamped)
    try:
        deadline = time.monotonic() + 10.0
        while publisher.get_num_connections() == 0 and time.monotonic() < deadline:
            time.sleep(0.01)
        assert publisher.get_num_connections() == 1
        connection = publisher.publisher.impl.connections[0]
        writes: list[int] = []
        write = connection.write_data
        connection.write_data = lambda data: (writes.append(len(data)), write(data))[1]
        for k in range(COUNT):  # as a callback publishing one message per joint state
            publisher.publish(PointStamped(Header(stamp=rospy.Time(k + 1), frame_id=f"m{k}"), None))
        while len(received) < COUNT and time.monotonic() < deadline:
            time.sleep(0.01)
        headers = [m.header for m in received]
        assert [h.frame_id for h in headers] == [f"m{k}" for k in range(COUNT)]
        assert [h.stamp.secs for h in headers] == list(range(1, COUNT + 1))
        assert [h.seq for h in headers] == list(range(1, COUNT + 1))  # as rospy numbers them
        assert 0 < len(writes) < COUNT  # batched: the writer took several at a time
        assert publisher.publisher.impl.message_data_sent == sum(writes)
    finally:
        sub.unregister()
        publisher.publisher.unregister()
