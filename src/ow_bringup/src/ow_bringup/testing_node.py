"""The test process as a rospy node (rospy wiring only): joining the private master, its
subscribers, connection waits, and a terrain change for :mod:`ow_bringup.testing`'s fixtures,
which re-exports the helpers."""

from __future__ import annotations

import time
from typing import TYPE_CHECKING, Any

import rospy

from ow_description.description import DEFAULT_GROUND_Z
from ow_runtime.connections import wait_sending
from ow_runtime.names import ARM_UNSTOW, TERRAIN_TOPIC
from ow_runtime.node import init_node

if TYPE_CHECKING:
    from collections.abc import Callable

    from ow_bringup.stack import RosStack

#: The terrain the lander starts on unless a test asks for another.
FLAT = f"flat:{DEFAULT_GROUND_Z}"
#: The subscribers :func:`subscribe` made; each module's stack unregisters them when it ends, so
#: no recorder of an earlier module runs on a later module's messages (one master per process).
_SUBSCRIBERS: list[Any] = []
#: The publishers :func:`advertise` made; unregistered when each module's stack ends.
_PUBLISHERS: list[Any] = []
#: s of wall time :func:`subscribe` waits for its connections.
SUBSCRIBE_WAIT_S = 5.0


def join_as_test_node() -> None:
    """Make this process the rospy node ``/pytest_*`` on the master of ``ROS_MASTER_URI``."""
    init_node("pytest", anonymous=True, disable_signals=True)


def leave_as_test_node() -> None:
    """Shut this process's rospy node down."""
    rospy.signal_shutdown("tests finished")


def unregister_endpoints() -> None:
    """Unregister every subscriber :func:`subscribe` and publisher :func:`advertise` made and
    the test has not."""
    while _SUBSCRIBERS:
        _SUBSCRIBERS.pop().unregister()
    while _PUBLISHERS:
        _PUBLISHERS.pop().unregister()


def registered_topics() -> set[tuple[str, str]]:
    """(``"pub"`` or ``"sub"``, topic) of every publisher and subscriber this process has
    registered right now, whoever made it (a ``dynamic_reconfigure`` client, an action
    client, a raw ``rospy.Subscriber``)."""
    from rospy.topics import get_topic_manager

    manager = get_topic_manager()
    return {("pub", name) for name, _ in manager.get_publications()} | {
        ("sub", name) for name, _ in manager.get_subscriptions()
    }


def release_topics(keep: set[tuple[str, str]]) -> list[tuple[str, str]]:
    """Unregister every publisher and subscriber of this process not in ``keep`` (as
    :func:`registered_topics` gives them), whatever handles still hold it; what was released.

    A test's ``dynamic_reconfigure`` client left open kept this process subscribed to
    ``/hand_yaw_position_controller/pid/parameter_updates``: the next module's simulation had a
    subscriber it had not connected to yet while it started, and a wait for every connection
    (as a mission waits before its first step) saw it unconnected. Action clients leave their
    ``status``, ``feedback`` and ``result`` subscriptions the same way. Handles a test still
    holds must not be unregistered after this (a module's fixtures end before its stack).
    """
    from rospy.impl.registration import Registration
    from rospy.topics import get_topic_manager

    manager = get_topic_manager()
    released = []
    for kind, name in sorted(registered_topics() - keep):
        reg_type = Registration.PUB if kind == "pub" else Registration.SUB
        impl = manager.get_impl(reg_type, name)
        if impl is None:
            continue
        impl.ref_count = 1  # every handle's share: the next release closes it
        manager.release_impl(reg_type, name)
        released.append((kind, name))
    return released


def advertise(topic: str, data_class: type, **kwargs: Any) -> Any:
    """A test's ``rospy.Publisher``, unregistered when the test module's stack ends.

    rospy keeps one publisher per topic in a process, with the connections it made and the
    ``queue_size`` they were made with, for as long as any handle is registered: a publisher
    an earlier module left registered kept advertising ``/joint_states`` with a queue of one,
    the next module's nodes connected to it at once, and their connections dropped a message
    whenever the writer thread lagged (a later ``queue_size`` applies to new connections only).
    """
    publisher = rospy.Publisher(topic, data_class, **kwargs)
    _PUBLISHERS.append(publisher)
    return publisher


def tf_buffer() -> Any:
    """A ``tf2_ros.Buffer`` filled by a listener that is unregistered when the test module's
    stack ends. A listener left registered keeps this process taking every later module's
    ``/tf`` (hundreds of messages a wall second at the tests' real-time factor), and a later
    listener shares its subscription and its backlog."""
    import tf2_ros

    buffer = tf2_ros.Buffer()
    _SUBSCRIBERS.append(tf2_ros.TransformListener(buffer))  # unregister() ends both of its
    return buffer


def set_terrain(stack: RosStack, spec: str = FLAT, lift_arm: bool = False) -> None:
    """Give the running simulation a new terrain and wait until the arm services have it.

    Args:
        stack: the running stack.
        spec: the terrain spec (``flat:<z m>``, ``europa:<seed>``, ``file:<path>``).
        lift_arm: unstow first, so that no tool is under the new surface.

    Raises:
        AssertionError: a service refused, or the new flat map did not arrive within 10 s.
    """
    import numpy as np

    from ow_description.conversions import height_map_from_msg
    from ow_msgs.msg import HeightMap as HeightMapMsg
    from ow_msgs.srv import SetTerrain, Unstow

    if lift_arm:
        response = stack.service(ARM_UNSTOW, Unstow)(delete_prev_traj=False)
        assert response.success, response.message
    reply = stack.service("/sim/set_terrain", SetTerrain)(terrain=spec)
    assert reply.success, reply.message
    if spec.startswith("flat:"):
        deadline = time.monotonic() + 10.0
        while True:  # the latched /sim/terrain carries the new, flat map ...
            msg = rospy.wait_for_message(TERRAIN_TOPIC, HeightMapMsg, timeout=10)
            if np.ptp(height_map_from_msg(msg).heights) == 0.0:
                break
            assert time.monotonic() < deadline, "/sim/terrain still shows the carved terrain"
        time.sleep(0.2)  # ... and the arm services, subscribed to it too, have it as well


def subscribe(topic: str, data_class: type, callback: Callable[..., Any], **kwargs: Any) -> Any:
    """A test's ``rospy.Subscriber`` that receives every message of ``topic``.

    rospy keeps one receive queue per topic in a process, and the last ``queue_size`` given by
    any subscriber of that topic in the process wins (None leaves it as it was); a queue of n
    keeps only the newest n messages of each socket read, so a recorder lagging a fast
    simulation loses samples. Every subscriber of the test process is made here, unbounded
    (:data:`ow_runtime.names.EVERY_MESSAGE`), so none of them limits another. It is
    unregistered when the test module's stack ends, if the test has not done so.

    It returns once connected to every publisher the master lists for ``topic`` (at most
    ``SUBSCRIBE_WAIT_S`` of wall time: a node killed without unregistering stays listed), so
    the test records from the simulation time it goes on at, not from whenever the connection
    happens to come up while the simulation runs on.
    """
    import rosgraph

    from ow_runtime.names import EVERY_MESSAGE

    subscriber = rospy.Subscriber(topic, data_class, callback, queue_size=EVERY_MESSAGE, **kwargs)
    _SUBSCRIBERS.append(subscriber)
    publishers, _, _ = rosgraph.Master(rospy.get_name()).getSystemState()
    resolved = subscriber.resolved_name
    listed = next((len(nodes) for name, nodes in publishers if name == resolved), 0)
    deadline = time.monotonic() + SUBSCRIBE_WAIT_S
    while subscriber.get_num_connections() < listed and time.monotonic() < deadline:
        time.sleep(0.01)
    return subscriber


def wait_connected(endpoint: Any, timeout_s: float = 10.0) -> Any:
    """Wait (wall time) until a rospy Publisher or Subscriber has a connection and return it:
    a message published, or one published to a subscriber, before then is lost. A subscriber's
    publishers must write to it on their side too
    (:func:`~ow_runtime.connections.publishers_send_to`).

    Raises:
        AssertionError: no connection within ``timeout_s``.
    """
    if isinstance(endpoint, rospy.Subscriber):
        assert wait_sending(endpoint, timeout_s), f"nothing sends {endpoint.name} in {timeout_s} s"
        return endpoint
    deadline = time.monotonic() + timeout_s
    while endpoint.get_num_connections() == 0:
        assert time.monotonic() < deadline, f"nothing connected to {endpoint.name} in {timeout_s} s"
        time.sleep(0.02)
    return endpoint
