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

Each node's output goes to ``<log_dir>/<name>.log``; a node that dies or never offers its
services raises :class:`HarnessError` with the end of that log.
"""

from __future__ import annotations

import os
from collections.abc import Iterator

import pytest

from ow_mission.stack import HarnessError, NodeProcess, RosMaster, RosStack, private_master

__all__ = ["HarnessError", "NodeProcess", "RosMaster", "RosStack", "ros_master", "ros_stack"]


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
