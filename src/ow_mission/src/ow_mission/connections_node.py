"""Whether a subscription will receive what is published from now on (rospy wiring only).

A rospy subscriber counts a connection once the publisher has answered its handshake, but the
publisher adds that connection to the ones it writes to only after answering: a message it
publishes in between is not sent to the new subscriber. Under load that window grew long enough
to lose an action's result (a rejected goal then never ended for its client). The publisher's
own list, read through its node's ``getBusInfo``, says when it is closed.
"""

from __future__ import annotations

import time
import xmlrpc.client
from typing import Any

import rospy

#: s of wall time between checks.
_POLL_S = 0.01


def publishers_send_to(subscriber: Any) -> bool:
    """Whether ``subscriber`` (a rospy Subscriber) has a connection and every publisher it is
    connected to writes to this node on that topic (each publisher node's ``getBusInfo``)."""
    me, topic = rospy.get_name(), subscriber.resolved_name
    uris = {c.endpoint_id for c in list(subscriber.impl.connections)}
    if not uris:
        return False
    for uri in uris:
        try:
            reply: Any = xmlrpc.client.ServerProxy(uri).getBusInfo(me)
        except (OSError, xmlrpc.client.Error):
            return False  # the publisher is going away: its connection does not count
        if not any(c[1] == me and c[2] == "o" and c[4] == topic and c[5] for c in reply[2]):
            return False
    return True


def wait_sending(subscriber: Any, timeout_s: float) -> bool:
    """Wait (wall time, ``timeout_s`` at most) until :func:`publishers_send_to`; whether it
    did."""
    deadline = time.monotonic() + timeout_s
    while not publishers_send_to(subscriber):
        if time.monotonic() > deadline or rospy.is_shutdown():
            return False
        time.sleep(_POLL_S)
    return True


def service_proxy(name: str, service_class: Any) -> Any:
    """A ``rospy.ServiceProxy`` for ``name`` (for ROS-free callers such as the test harness's
    :meth:`ow_mission.stack.RosStack.service`)."""
    return rospy.ServiceProxy(name, service_class)
