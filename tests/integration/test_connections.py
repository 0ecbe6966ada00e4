"""``ow_runtime.connections``: a subscription counts as sending only once the publisher's
node writes to it through that very connection, read from the publisher's side
(``getBusInfo``), not from the count rospy keeps on the subscriber's side."""

from __future__ import annotations

import time

import rospy
from std_msgs.msg import Float64, Header, String

from ow_bringup.testing import FLAT, advertise, subscribe, wait_connected
from ow_runtime.connections import publishers_send_to, wait_sending


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


def test_a_subscription_made_again_counts_only_once_its_own_connection_is_written_to(ros_stack):
    """A subscription unregistered and made again at once, 40 times, each time followed by one
    message from a publisher in another process that publishes only on request (the simulation's
    set-point receipt): every message arrives. The publisher still lists the old connection (it
    notices a closed one only when it next writes), and rospy lists the new one on this side
    before it is connected; counting either lost 3-4 messages of 40."""
    ros_stack.start_node(
        "ow_sim_bullet",
        "sim",
        params={"real_time_factor": 0.0, "terrain": FLAT, "start_paused": True},
        wait_for_services=["/sim/step"],
    )
    command = wait_connected(
        advertise("/shou_yaw_position_controller/command", Float64, queue_size=1)
    )
    lost = []
    for k in range(40):
        received: list[str] = []
        receipts = subscribe(
            "/sim/setpoint_received", Header, lambda m, got=received: got.append(m.frame_id)
        )
        sub = wait_connected(receipts)
        command.publish(Float64(0.01 * k))
        deadline = time.monotonic() + 10.0
        while not received and time.monotonic() < deadline:
            time.sleep(0.005)
        if received != ["j_shou_yaw"]:
            lost.append((k, received))
        sub.unregister()
    assert not lost
