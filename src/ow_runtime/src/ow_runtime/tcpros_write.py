"""Writing to a rospy publisher's connections as rospy does, for publishers that batch their
messages (no rospy import: the connections are rospy's transports, handed in)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any


def write_or_drop(connection: Any, data: bytes, topic: str, log: Callable[[str], None]) -> None:
    """Write ``data`` (length-prefixed messages) to one subscriber's ``connection`` (a rospy
    ``TCPROSTransport``: blocks while the subscriber lags); a connection whose write fails is
    closed, which removes it from its publisher, as ``rospy.topics._PublisherImpl.publish``
    does. ``log`` gets why."""
    try:
        connection.write_data(data)
    except Exception as error:  # what rospy does: drop the connection
        log(f"dropping a subscriber of {topic}: {error}")
        try:
            connection.close()
        except Exception as close_error:
            log(f"closing it failed too: {close_error}")
