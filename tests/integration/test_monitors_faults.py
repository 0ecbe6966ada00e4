"""``rosrun ow_mission monitors _serve_faults:=true``: the ``/faults`` server as a component of the
monitors (as the mission runs it), on a real master: the ``faults`` node's services, topics and
launch-time parameters, and its refusals."""

from __future__ import annotations

import pytest
import rospy
from dynamic_reconfigure import DynamicReconfigureCallbackException
from dynamic_reconfigure.client import Client
from dynamic_reconfigure.encoding import decode_config

from ow_bringup.stack import HarnessError
from ow_faults.protocol import CHANGES_TOPIC
from ow_msgs.msg import FaultChange


@pytest.fixture(scope="module")
def stack(ros_stack):
    ros_stack.start_node(
        "ow_bringup",
        "monitors",
        params={"serve_faults": True, "faults": {"ant_pan_joint_locked_failure": True}},
        wait_for_services=["/faults/set_parameters"],
        wait_for_topics=["/faults/parameter_updates", "/system_faults_status"],
    )
    ros_stack.client = Client("/faults", timeout=30)
    return ros_stack


def test_the_faults_injected_at_launch_are_served_under_faults(stack):
    config = stack.client.get_configuration(timeout=10)
    assert config["ant_pan_joint_locked_failure"] is True
    # The server's configuration is on the parameter server, as the faults node's (the
    # session's master may hold other values an earlier module's server left).
    for name in ("ant_pan_joint_locked_failure", "high_power_draw"):
        assert rospy.get_param(f"/faults/{name}") == config[name]
    first = rospy.wait_for_message(CHANGES_TOPIC, FaultChange, timeout=10)  # latched
    assert decode_config(first.config)["ant_pan_joint_locked_failure"] is True


def test_a_change_is_published_and_a_bad_one_refused_naming_it(stack):
    stack.client.update_configuration({"ant_tilt_joint_locked_failure": True})
    try:
        change = rospy.wait_for_message(CHANGES_TOPIC, FaultChange, timeout=10)
        assert change.version >= 1
        assert decode_config(change.config)["ant_tilt_joint_locked_failure"] is True
        before = stack.client.get_configuration(timeout=10)["high_power_draw"]
        with pytest.raises(DynamicReconfigureCallbackException) as error:
            stack.client.update_configuration({"high_power_draw": 500.0})
        assert "high_power_draw = 500.0 W is outside [1, 360] W" in str(error.value.__context__)
        assert stack.client.get_configuration(timeout=10)["high_power_draw"] == before
    finally:
        stack.client.update_configuration({"ant_tilt_joint_locked_failure": False})


@pytest.mark.parametrize(
    ("params", "named"),
    [
        ({"serve_faults": True, "faults": {"no_such_fault": True}}, "no_such_fault"),
        ({"faults": {"ant_pan_joint_locked_failure": True}}, "serve_faults"),
        ({"serve_faults": "yes"}, "serve_faults"),
    ],
)
def test_a_bad_fault_server_parameter_stops_the_node_naming_it(ros_stack, params, named):
    # A name of its own each: the parameters of an earlier one stay on the master.
    with pytest.raises(HarnessError, match=named):
        ros_stack.start_node(
            "ow_bringup",
            "monitors",
            name=f"monitors_bad_{len(ros_stack.nodes)}",
            params=params,
            wait_for_topics=["/never"],
            timeout_s=30.0,
        )
