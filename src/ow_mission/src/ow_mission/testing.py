"""Rostest-style pytest harness: a private ROS master, real nodes started with ``rosrun``.

Use it for the project's own integration tests and for your autonomy tests. In a ``conftest.py``::

    pytest_plugins = ["ow_mission.testing"]

and in a test module::

    import pytest
    from ow_msgs.srv import Unstow

    @pytest.fixture(scope="module")
    def stack(ros_stack):
        ros_stack.start_node("ow_sim_bullet", "sim", params={"real_time_factor": 0.0},
                             wait_for_services=["/sim/reset"])
        ros_stack.start_node("ow_lander", "arm_services", wait_for_services=["/arm/unstow"])
        return ros_stack

    def test_unstow(stack):
        response = stack.service("/arm/unstow", Unstow)(delete_prev_traj=False)
        assert response.success, response.message

Fixtures:
    ros_master (session): a ``rosmaster --core`` on a free port, with ``/use_sim_time`` true, and
        this test process initialised as a rospy node on it. One per pytest process, so files run
        in parallel under pytest-xdist without sharing a master.
    ros_stack (module): a :class:`RosStack` on that master; every node it started is stopped
        (SIGINT, then SIGKILL of its whole process group) when the module ends, and the private
        parameters it set are deleted.
    start_lander (module): a function starting the simulation (as fast as it runs, on flat
        ground at the default height unless told otherwise) and the arm services (plan and
        execute) on ``ros_stack``; keyword arguments give each node more parameters.

:func:`wait_connected` waits until a publisher or subscriber of the test is connected.
:func:`set_terrain` gives the running simulation a new terrain and waits until the arm services
have it: call it at the start of a test whose result must not depend on what earlier tests carved.

Each node's output goes to ``<log_dir>/<name>.log``; a node that dies or never offers its
services raises :class:`HarnessError` with the end of that log.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Iterable, Iterator, Mapping
from typing import Any

import pytest

from ow_lander.description import DEFAULT_GROUND_Z
from ow_mission.stack import HarnessError, NodeProcess, RosMaster, RosStack, private_master

__all__ = [
    "FLAT",
    "HarnessError",
    "NodeProcess",
    "RosMaster",
    "RosStack",
    "ros_master",
    "ros_stack",
    "set_terrain",
    "start_lander",
    "wait_connected",
]

#: The terrain the lander starts on unless a test asks for another.
FLAT = f"flat:{DEFAULT_GROUND_Z}"
#: The subscribers :func:`subscribe` made; each module's stack unregisters them when it ends, so
#: no recorder of an earlier module runs on a later module's messages (one master per process).
_SUBSCRIBERS: list[Any] = []
#: s of wall time :func:`subscribe` waits for its connections.
SUBSCRIBE_WAIT_S = 5.0


@pytest.fixture(scope="session")
def ros_master(tmp_path_factory: pytest.TempPathFactory) -> Iterator[RosMaster]:
    """A private master for this pytest process; this process is a rospy node on it."""
    with private_master(tmp_path_factory.mktemp("ros")) as master:
        os.environ.update(
            ROS_MASTER_URI=master.uri,
            ROS_HOSTNAME="127.0.0.1",
            ROS_HOME=str(master.log_dir),
            ROS_LOG_DIR=str(master.log_dir / "log"),
        )
        import rospy

        rospy.init_node("pytest", anonymous=True, disable_signals=True)
        try:
            yield master
        finally:
            rospy.signal_shutdown("tests finished")


@pytest.fixture(scope="module")
def ros_stack(ros_master: RosMaster) -> Iterator[RosStack]:
    """Nodes for one test module, all stopped when the module ends."""
    stack = RosStack(ros_master)
    try:
        yield stack
    finally:
        stack.shutdown()
        while _SUBSCRIBERS:
            _SUBSCRIBERS.pop().unregister()


#: sim s per wall s of the simulation :func:`start_lander` starts. Not as fast as it can: a
#: simulation left running free between a module's tests (and its subscribers, on every joint
#: state) would take a core from the other pytest worker for nothing.
TEST_REAL_TIME_FACTOR = 20.0


@pytest.fixture(scope="module")
def start_lander(ros_stack: RosStack) -> Callable[..., RosStack]:
    """A function starting the simulation and the arm services on this module's stack.

    Its keyword arguments: ``terrain`` (spec, default :data:`FLAT`); ``sim`` and ``arm`` (more
    private parameters of each node; the sim runs at :data:`TEST_REAL_TIME_FACTOR` and the arm
    services plan and execute unless these say otherwise); ``arm_services`` (services to wait
    for, default ``/arm/unstow``); ``sim_topics`` (topics of the sim to wait for, default
    ``/joint_states``). It returns the stack.
    """

    def start(
        terrain: str = FLAT,
        sim: Mapping[str, Any] | None = None,
        arm: Mapping[str, Any] | None = None,
        arm_services: Iterable[str] = ("/arm/unstow",),
        sim_topics: Iterable[str] = ("/joint_states",),
    ) -> RosStack:
        ros_stack.start_node(
            "ow_sim_bullet",
            "sim",
            params={
                "terrain": terrain,
                "real_time_factor": TEST_REAL_TIME_FACTOR,
                **(sim or {}),
            },
            wait_for_services=["/sim/set_terrain"],
            wait_for_topics=list(sim_topics),
        )
        ros_stack.start_node(
            "ow_lander",
            "arm_services",
            params={"plan_and_execute": True, **(arm or {})},
            wait_for_services=list(arm_services),
        )
        return ros_stack

    return start


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
    import rospy

    from ow_lander.conversions import height_map_from_msg
    from ow_msgs.msg import HeightMap as HeightMapMsg
    from ow_msgs.srv import SetTerrain, Unstow

    if lift_arm:
        response = stack.service("/arm/unstow", Unstow)(delete_prev_traj=False)
        assert response.success, response.message
    reply = stack.service("/sim/set_terrain", SetTerrain)(terrain=spec)
    assert reply.success, reply.message
    if spec.startswith("flat:"):
        deadline = time.monotonic() + 10.0
        while True:  # the latched /sim/terrain carries the new, flat map ...
            msg = rospy.wait_for_message("/sim/terrain", HeightMapMsg, timeout=10)
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
    (:data:`ow_lander.conversions.EVERY_MESSAGE`), so none of them limits another. It is
    unregistered when the test module's stack ends, if the test has not done so.

    It returns once connected to every publisher the master lists for ``topic`` (at most
    ``SUBSCRIBE_WAIT_S`` of wall time: a node killed without unregistering stays listed), so
    the test records from the simulation time it goes on at, not from whenever the connection
    happens to come up while the simulation runs on.
    """
    import rosgraph
    import rospy

    from ow_lander.conversions import EVERY_MESSAGE

    subscriber = rospy.Subscriber(topic, data_class, callback, queue_size=EVERY_MESSAGE, **kwargs)
    _SUBSCRIBERS.append(subscriber)
    publishers, _, _ = rosgraph.Master(rospy.get_name()).getSystemState()
    resolved = subscriber.resolved_name
    listed = next((len(nodes) for name, nodes in publishers if name == resolved), 0)
    deadline = time.monotonic() + SUBSCRIBE_WAIT_S
    while subscriber.get_num_connections() < listed and time.monotonic() < deadline:
        time.sleep(0.01)
    return subscriber


def action_client(name: str, action: type, timeout_s: float = 30.0) -> Any:
    """A connected :class:`ow_mission.action_client_node.ActionClient` of action ``name`` (see
    :func:`~ow_mission.action_client_node.connect`).

    Raises:
        AssertionError: no server, or no connection, within ``timeout_s`` (wall).
    """
    from ow_mission.action_client_node import connect

    try:
        return connect(name, action, timeout_s)
    except TimeoutError as error:
        raise AssertionError(str(error)) from error


def wait_connected(endpoint: Any, timeout_s: float = 10.0) -> Any:
    """Wait (wall time) until a rospy Publisher or Subscriber has a connection and return it:
    a message published, or one published to a subscriber, before then is lost. A subscriber's
    publishers must write to it on their side too
    (:func:`~ow_mission.connections_node.publishers_send_to`).

    Raises:
        AssertionError: no connection within ``timeout_s``.
    """
    import rospy

    from ow_mission.connections_node import wait_sending

    if isinstance(endpoint, rospy.Subscriber):
        assert wait_sending(endpoint, timeout_s), f"nothing sends {endpoint.name} in {timeout_s} s"
        return endpoint
    deadline = time.monotonic() + timeout_s
    while endpoint.get_num_connections() == 0:
        assert time.monotonic() < deadline, f"nothing connected to {endpoint.name} in {timeout_s} s"
        time.sleep(0.02)
    return endpoint
