"""A lockstep client joining a simulation that runs as fast as it can.

The simulation steps up to its lockstep latency past the registration before the client has the
reply; the joint states of those steps reach the client's callback while it is not yet
registered. The client must acknowledge them once registered: no later joint state comes to
trigger an acknowledgement, and the simulation would wait for one (a loaded ``make test`` once
saw no joint state for 5 s after the arm services joined).
"""

from __future__ import annotations

import time

from sensor_msgs.msg import JointState

from ow_bringup.testing import FLAT, subscribe
from ow_runtime.lockstep_client import LockstepClient, simulation_status

#: s of sim time the simulation must run past the registration, in steps of the latency.
RUN_ON_S = 2.0
REGISTRATIONS = 5


def test_a_client_registering_while_the_simulation_runs_keeps_it_running(ros_stack):
    ros_stack.start_node(
        "ow_sim_bullet",
        "sim",
        params={"real_time_factor": 0.0, "terrain": FLAT},
        wait_for_services=["/sim/lockstep_register"],
        wait_for_topics=["/joint_states"],
    )
    for k in range(REGISTRATIONS):
        client = LockstepClient(f"/test_client_{k}")
        stamps: list[float] = []

        def on_joint_state(msg: JointState, client=client, stamps=stamps) -> None:
            stamps.append(msg.header.stamp.to_sec())
            client.ack(stamps[-1])  # processed: as a node acknowledges each joint state

        sub = subscribe("/joint_states", JointState, on_joint_state)
        try:
            registered_at = client.register(wait_s=10.0)
            deadline = time.monotonic() + 30.0
            while (not stamps or stamps[-1] < registered_at + RUN_ON_S) and (
                time.monotonic() < deadline
            ):
                time.sleep(0.01)
            status = simulation_status()
            assert stamps[-1] >= registered_at + RUN_ON_S, (
                f"registration {k} at t = {registered_at:.2f} s: the simulation stopped at "
                f"t = {status.sim_time:.2f} s waiting for {status.waiting_for!r} "
                f"({status.reason!r})"
            )
        finally:
            client.close()
            sub.unregister()
