"""Rostest-style pytest harness: a private ROS master, real nodes started with ``rosrun``.

Use it for the project's own integration tests and for your autonomy tests. In a ``conftest.py``::

    pytest_plugins = ["ow_bringup.testing"]

and in a test module::

    import pytest
    from ow_msgs.srv import Unstow

    @pytest.fixture(scope="module")
    def stack(ros_stack):
        ros_stack.start_node("ow_sim_bullet", "sim", params={"real_time_factor": 0.0},
                             wait_for_services=["/sim/reset"])
        ros_stack.start_node("ow_lander", "arm_services", wait_for_services=[ARM_UNSTOW])
        return ros_stack

    def test_unstow(stack):
        response = stack.service(ARM_UNSTOW, Unstow)(delete_prev_traj=False)
        assert response.success, response.message

Fixtures:
    ros_master (session): a ``rosmaster --core`` on a free port, with ``/use_sim_time`` true, and
        this test process initialised as a rospy node on it. One per pytest process, so files run
        in parallel under pytest-xdist without sharing a master.
    ros_stack (module): a :class:`RosStack` on that master; every node it started is stopped
        (SIGINT, then SIGKILL of its whole process group) when the module ends, and the
        master's parameters are put back as the module found them (:func:`module_stack`), so
        that nothing a module's nodes wrote (the faults it left injected) reaches the next.
    start_lander (module): a function starting the simulation (as fast as it runs, on flat
        ground at the default height unless told otherwise) and the arm services (plan and
        execute) on ``ros_stack``; keyword arguments give each node more parameters.

:func:`wait_connected` waits until a publisher or subscriber of the test is connected.
:func:`tf_buffer` is a tf2 buffer whose listener ends with the module.
:func:`set_terrain` gives the running simulation a new terrain and waits until the arm services
have it: call it at the start of a test whose result must not depend on what earlier tests carved.

Each node's output goes to ``<log_dir>/<name>.log`` (``<name>.1.log`` ... when a later module
starts the name again); a node that dies or never offers its
services raises :class:`HarnessError` with the end of that log.
"""

from __future__ import annotations

import contextlib
import os
import time
from collections.abc import Callable, Generator, Iterable, Iterator, Mapping
from typing import Any

import pytest

from ow_bringup.stack import HarnessError, NodeProcess, RosMaster, RosStack, private_master
from ow_bringup.testing_node import (
    FLAT,
    advertise,
    join_as_test_node,
    leave_as_test_node,
    registered_topics,
    release_topics,
    set_terrain,
    subscribe,
    tf_buffer,
    unregister_endpoints,
    wait_connected,
)
from ow_runtime.names import ARM_UNSTOW, JOINT_STATES

__all__ = [
    "FLAT",
    "HarnessError",
    "NodeProcess",
    "RosMaster",
    "RosStack",
    "advertise",
    "module_stack",
    "ros_master",
    "ros_stack",
    "set_terrain",
    "start_lander",
    "subscribe",
    "tf_buffer",
    "wait_connected",
]


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
        join_as_test_node()
        try:
            yield master
        finally:
            leave_as_test_node()


@contextlib.contextmanager
def module_stack(master: RosMaster) -> Iterator[RosStack]:
    """A :class:`RosStack` on ``master`` for one test module (what :func:`ros_stack` yields).

    On leaving, every node it started is stopped; the subscribers and publishers the test made
    with :func:`subscribe`, :func:`advertise` and :func:`tf_buffer` are unregistered, and so is
    every other publisher and subscriber this process made meanwhile (:func:`release_topics`:
    a ``dynamic_reconfigure`` or action client's); whatever a node killed outside the stack
    left on the master is unregistered (:meth:`~ow_bringup.stack.RosMaster.forget_unreachable`);
    and the master's parameters are put back as they were on entering
    (:meth:`~ow_bringup.stack.RosMaster.restore_params`). Nodes write parameters of their
    own: the ``/faults`` server (dynamic_reconfigure) writes its whole configuration under
    ``/faults`` at start and at every change, and the ``faults`` node reads its launch-time
    faults from there. A fault a module left injected (``ant_pan_joint_locked_failure`` of
    test_monitors_faults) was injected from the start in the next module on that master:
    the camera tests' pan lock set PAN_TILT_EXECUTION_ERROR beside their CAMERA_GOAL_ERROR.
    """
    params = master.param_snapshot()
    topics = registered_topics()
    stack = RosStack(master)
    _STACKS.append(stack)
    try:
        yield stack
    finally:
        _STACKS.remove(stack)
        stack.shutdown()
        unregister_endpoints()
        release_topics(topics)
        master.forget_unreachable()
        master.restore_params(params)


#: the stacks of the modules running now (one: a pytest process runs one module at a time).
_STACKS: list[RosStack] = []

#: lines of each node's log a failed test's report ends with.
LOG_TAIL_LINES = 30


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(
    item: pytest.Item, call: pytest.CallInfo[None]
) -> Generator[None, Any, None]:
    """A test that fails while its module's nodes run reports the end of each node's log
    (whether the node still runs, and its last lines): the logs live in the session's
    temporary directory, gone when a later session ends, and a failure under a loaded CI
    machine is rarely seen twice."""
    outcome = yield
    report = outcome.get_result()
    if not report.failed or not _STACKS:
        return
    for node in list(_STACKS[-1].nodes):
        try:
            lines = node.log().splitlines()[-LOG_TAIL_LINES:]
        except OSError as error:
            lines = [f"(log unreadable: {error})"]
        state = "running" if node.alive() else f"exited {node.proc.returncode}"
        report.sections.append((f"node {node.name} ({state}), log end", "\n".join(lines)))


@pytest.fixture(scope="module")
def ros_stack(ros_master: RosMaster) -> Iterator[RosStack]:
    """Nodes for one test module, all stopped when the module ends, and the master's
    parameters as the module found them (:func:`module_stack`)."""
    with module_stack(ros_master) as stack:
        yield stack


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
        arm_services: Iterable[str] = (ARM_UNSTOW,),
        sim_topics: Iterable[str] = (JOINT_STATES,),
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


def wait_for_server(client: Any, timeout_s: float = 30.0) -> None:
    """Wait, in wall time, until a stock ``actionlib.SimpleActionClient`` is connected to its
    server on all five topics (its own ``wait_for_server`` counts ROS time, which the
    simulation's clock runs many times faster than the wall, or stops).

    Raises:
        AssertionError: not connected within ``timeout_s`` s of wall time.
    """
    from ow_runtime.action_client import server_connected

    deadline = time.monotonic() + timeout_s
    while not server_connected(client.action_client):
        assert time.monotonic() < deadline, f"no {client.action_client.ns} server in {timeout_s} s"
        time.sleep(0.01)


def action_client(name: str, action: type, timeout_s: float = 30.0) -> Any:
    """A connected :class:`ow_runtime.action_client.ActionClient` of action ``name`` (see
    :func:`~ow_runtime.action_client.connect`).

    Raises:
        AssertionError: no server, or no connection, within ``timeout_s`` (wall).
    """
    from ow_runtime.action_client import connect

    try:
        return connect(name, action, timeout_s)
    except TimeoutError as error:
        raise AssertionError(str(error)) from error
