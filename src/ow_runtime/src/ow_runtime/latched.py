"""Latched publishers that say so to every subscriber (rospy wiring only).

``rospy.Publisher(..., latch=True)`` registers the topic with the master first and enables the
latch only afterwards: a subscriber that connects in between is told ``latching: 0`` in the
connection header, and keeps that for the connection's life. The message still arrives (it is
published after), but a recorder writes the connection as not latched, and a bag replayed from
that file no longer latches it (a loaded machine once recorded ``/viz/terrain`` so). Here the
publisher's topic implementation is latched before it is registered.
"""

from __future__ import annotations

from typing import Any

import rospy
from rospy.impl.registration import Registration
from rospy.topics import _PublisherImpl, get_topic_manager


def latched_publisher(
    name: str, data_class: type, queue_size: int | None = 1, **kwargs: Any
) -> Any:
    """A ``rospy.Publisher`` of ``name`` latched from its registration on.

    Args:
        name: the topic (resolved as rospy resolves it).
        data_class: the message class.
        queue_size: as for ``rospy.Publisher`` (None: synchronous writes).
        kwargs: other ``rospy.Publisher`` arguments (not ``latch``).
    """
    prepare_latched(name, data_class)
    return rospy.Publisher(name, data_class, queue_size=queue_size, latch=True, **kwargs)


def prepare_latched(name: str, data_class: type) -> None:
    """Latch the topic implementation of ``name`` before anything registers it, so that a
    latched publisher made later by other code (``tf2_ros.StaticTransformBroadcaster``'s
    ``/tf_static``) is latched for every subscriber. Nothing happens when this node publishes
    the topic already."""
    resolved = rospy.names.resolve_name(name)
    manager = get_topic_manager()
    with manager.lock:
        if resolved in manager.pubs:
            return
        impl = _PublisherImpl(resolved, data_class)
        impl.enable_latch()
        # Registers with the master: the first Publisher made on it then takes this
        # implementation (reference count 0 until then, as a fresh one is before it is counted).
        manager._add(impl, manager.pubs, Registration.PUB)


def static_transform_broadcaster() -> Any:
    """A ``tf2_ros.StaticTransformBroadcaster`` whose ``/tf_static`` is latched from its
    registration on."""
    import tf2_ros
    from tf2_msgs.msg import TFMessage

    prepare_latched("/tf_static", TFMessage)
    return tf2_ros.StaticTransformBroadcaster()
