"""Two runs of the simulation node with the same seed and commands give identical joint states."""

from __future__ import annotations

import time

import numpy as np
import rospy
from sensor_msgs.msg import JointState
from std_msgs.msg import Header
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from ow_bringup.testing import advertise, subscribe, wait_connected
from ow_msgs.srv import StepSimulation

#: rad, an arm pose in front of the lander, reached from the stowed pose by a trajectory.
TARGET = {"j_shou_yaw": 0.2, "j_shou_pitch": 1.2, "j_prox_pitch": -2.0, "j_dist_pitch": 1.0}


def run_once(ros_stack) -> np.ndarray:
    node = ros_stack.start_node(
        "ow_sim_bullet",
        "sim",
        params={"real_time_factor": 0.0, "terrain": "europa:3", "start_paused": True},
        wait_for_services=["/sim/step"],
    )
    rows: list[list[float]] = []
    sub = subscribe(
        "/joint_states",
        JointState,
        lambda m: rows.append([m.header.stamp.to_sec(), *m.position, *m.velocity, *m.effort]),
    )
    receipts: list[Header] = []
    receipt_sub = subscribe("/sim/trajectory_received", Header, receipts.append)
    commands = advertise("/sim/joint_trajectory", JointTrajectory, queue_size=1)
    try:
        deadline = time.monotonic() + 10.0
        while commands.get_num_connections() == 0 and time.monotonic() < deadline:
            time.sleep(0.02)
        wait_connected(sub)  # the simulation writes to it: none of its states is lost
        wait_connected(receipt_sub)
        msg = JointTrajectory(joint_names=list(TARGET))
        msg.header.frame_id = "determinism"
        msg.points = [
            JointTrajectoryPoint(
                positions=list(TARGET.values()), time_from_start=rospy.Duration.from_sec(4.0)
            )
        ]
        commands.publish(msg)
        # Queued while the simulation is paused at t = 0, before the first step.
        deadline = time.monotonic() + 10.0
        while not receipts and time.monotonic() < deadline:
            time.sleep(0.02)
        assert [r.frame_id for r in receipts] == ["determinism"]
        assert receipts[0].stamp.to_sec() == 0.0
        response = ros_stack.service("/sim/step", StepSimulation)(600)
        assert response.success, response.message
        deadline = time.monotonic() + 10.0
        while (
            not rows or rows[-1][0] < response.sim_time - 0.0105
        ) and time.monotonic() < deadline:
            time.sleep(0.02)
    finally:
        sub.unregister()
        receipt_sub.unregister()
        commands.unregister()
        node.stop()
    return np.array(rows)


def test_same_seed_and_commands_give_bit_identical_joint_states(ros_stack):
    first = run_once(ros_stack)
    second = run_once(ros_stack)
    assert len(first) >= 599
    # Compare the common stamps (the first message may be published before the subscription).
    common = np.intersect1d(first[:, 0], second[:, 0])
    assert len(common) >= 599
    a = first[np.isin(first[:, 0], common)]
    b = second[np.isin(second[:, 0], common)]
    assert np.array_equal(a, b)
    # The arm really moved, so the comparison covers dynamics, not a resting arm.
    assert np.ptp(a[:, 1:10], axis=0).max() > 0.5
