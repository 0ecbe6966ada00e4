"""The arm services joining the simulation's lockstep while a mission's first request comes.

They join on a thread of their own, after they offer their services. A request that came first
was planned and executed outside the lockstep: nothing released the hold the simulation starts
with for them, and the simulation and the arm services waited for each other. A request now
waits for the join.
"""

from __future__ import annotations

import rospy
from std_srvs.srv import Trigger

from ow_bringup.stack import wait_until
from ow_bringup.testing import FLAT
from ow_msgs.srv import Unstow
from ow_runtime.lockstep_client import simulation_status
from ow_runtime.names import JOINT_STATES


def test_a_step_called_before_the_arm_services_joined_the_lockstep_waits_for_them(ros_stack):
    """The arm services join the lockstep on a thread of their own, after they offer their
    services. A request that came first was planned and executed outside the lockstep: nothing
    released the hold the simulation starts with for them, and the simulation and the arm
    services waited for each other (a mission whose stack was ready sooner called its first
    step 0.3 s before the join). A request now waits for the join."""
    ros_stack.start_node(  # first: they join once the simulation offers its lockstep
        "ow_lander",
        "arm_services",
        params={
            "plan_and_execute": True,
            "execution": {"lockstep": True, "lockstep_hold": True},
        },
        wait_for_services=["/arm/unstow"],
    )
    ros_stack.start_node(
        "ow_sim_bullet",
        "sim",
        params={
            "real_time_factor": 0.0,
            "terrain": FLAT,
            "start_paused": True,
            "lockstep_clients": ["/arm_services"],
        },
        wait_for_services=["/sim/resume"],
    )
    # The arm services get the state it starts from (as a mission waits). Only their own
    # topics: a subscriber another module of this process left (an open dynamic_reconfigure
    # client of a PID server the simulation offers once it is up) once made the wait pass
    # before the simulation had offered that server, and the check after it fail.
    arm_topics = ros_stack.master.subscribed_by("/arm_services")
    assert JOINT_STATES in arm_topics
    if not wait_until(lambda: not ros_stack.master.unconnected(arm_topics), 30.0):
        raise AssertionError(f"unconnected: {ros_stack.master.unconnected(arm_topics)}")
    assert rospy.ServiceProxy("/sim/resume", Trigger)().success
    response = ros_stack.service("/arm/unstow", Unstow)()  # at once, as a mission calls it
    assert response.success, response.message
    status = simulation_status()
    assert status.clients == ["/arm_services"]
    assert status.sim_time > 10.0  # the unstow ran in the simulation
