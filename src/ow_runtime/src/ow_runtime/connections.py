"""Whether a subscription will receive what is published from now on (rospy wiring only).

A rospy subscriber counts a connection once the publisher has answered its handshake, but the
publisher adds that connection to the ones it writes to only after answering: a message it
publishes in between is not sent to the new subscriber. Under load that window grew long enough
to lose an action's result (a rejected goal then never ended for its client). The publisher's
own list, read through its node's ``getBusInfo``, says when it is closed.

That list must name this very connection, not any to this node on the topic. rospy adds a
subscriber's connection to its list before it connects, and a publisher notices a closed
connection only when it next writes: a subscription made again soon after one was unregistered
counted its unconnected connection against the old one the publisher still listed, and 3-4 of 40
receipts published just after were lost. A connection is told by this side's address, known once
it is connected, which the publisher's side gives as its peer (``to [host:port on socket n]``).
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
    connected to writes to this node on that topic through that very connection (each publisher
    node's ``getBusInfo``)."""
    me, topic = rospy.get_name(), subscriber.resolved_name
    mine: dict[str, list[Any]] = {}
    for connection in list(subscriber.impl.connections):
        mine.setdefault(connection.endpoint_id, []).append(connection)
    if not mine:
        return False
    for uri, connections in mine.items():
        try:
            reply: Any = xmlrpc.client.ServerProxy(uri).getBusInfo(me)
        except (OSError, xmlrpc.client.Error):
            return False  # the publisher is going away: its connection does not count
        theirs = [c for c in reply[2] if c[1] == me and c[2] == "o" and c[4] == topic and c[5]]
        if not all(_listed(connection, theirs) for connection in connections):
            return False
    return True


def _listed(connection: Any, theirs: list[Any]) -> bool:
    """Whether ``connection`` (this side's transport) is connected and among the publisher's
    connections ``theirs`` (``getBusInfo`` rows), told by its address as their peer."""
    port = getattr(connection, "local_endpoint", (None, None))[1]
    if port is None:
        return False  # not connected yet
    return any(len(row) > 6 and f":{port} on socket" in row[6] for row in theirs)


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
    :meth:`ow_bringup.stack.RosStack.service`)."""
    return rospy.ServiceProxy(name, service_class)
