"""Recovery from a hostile command: a set-point far beyond a joint's limit, sent on the command
topic of the real simulation, leaves the arm on the limit, from where the arm services move it
again (plan and execute).

Before the fix the simulation drove the shoulder yaw onto its hard stop with a saturated motor,
a hair beyond its limit, and every operation was refused ("the arm's current configuration is
invalid: j_shou_yaw=-1.800 rad ...") for good.
"""

from __future__ import annotations

import time

import numpy as np
import pytest
import rospy
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64

from ow_bringup.testing import advertise, wait_connected
from ow_description.description import ARM_JOINTS, UNSTOWED
from ow_msgs.srv import Unstow

#: rad, the shoulder yaw's URDF limits.
SHOU_YAW_LIMITS = (-1.8, 1.8)
#: rad, how close to its goal a joint ends after an executed unstow.
END_TOLERANCE = 0.03
#: s of wall time to wait for the joint to reach its limit (seconds of sim time as fast as it runs).
WAIT_S = 60.0


@pytest.fixture(scope="module")
def stack(start_lander):
    return start_lander()


def arm_state() -> dict[str, float]:
    msg = rospy.wait_for_message("/joint_states", JointState, timeout=10)
    return {name: float(p) for name, p in zip(msg.name, msg.position, strict=True)}


def drive_onto_limit(setpoint: float, limit: float) -> float:
    """Command j_shou_yaw to ``setpoint`` on its topic; wait until it rests on ``limit``."""
    publisher = advertise("/shou_yaw_position_controller/command", Float64, queue_size=1)
    wait_connected(publisher, WAIT_S)
    publisher.publish(Float64(setpoint))
    deadline = time.monotonic() + WAIT_S
    last = np.inf
    while True:
        position = arm_state()["j_shou_yaw"]
        if abs(position - limit) < 0.005 and abs(position - last) < 1e-4:
            return position
        assert time.monotonic() < deadline, f"j_shou_yaw stopped at {position:.4f} rad"
        last = position
        time.sleep(0.2)


def unstow_and_check(stack) -> None:
    response = stack.service("/arm/unstow", Unstow)(delete_prev_traj=False)
    assert response.success, response.message
    time.sleep(0.5)
    state = arm_state()
    for joint in ARM_JOINTS:
        assert state[joint] == pytest.approx(UNSTOWED[joint], abs=END_TOLERANCE), joint


def test_a_huge_setpoint_leaves_the_joint_on_its_upper_limit_and_the_arm_recovers(stack):
    unstow_and_check(stack)
    position = drive_onto_limit(1e9, SHOU_YAW_LIMITS[1])
    assert position <= SHOU_YAW_LIMITS[1] + 0.005  # on the limit, not pushed beyond it
    unstow_and_check(stack)


def test_a_huge_negative_setpoint_leaves_the_joint_on_its_lower_limit_and_the_arm_recovers(
    stack,
):
    """At -1.8 rad the planner's model has l_prox inside the lander body (the simulation has no
    arm-lander contacts): the unstow starts with an escape towards the unstowed pose."""
    unstow_and_check(stack)
    position = drive_onto_limit(-1e9, SHOU_YAW_LIMITS[0])
    assert position >= SHOU_YAW_LIMITS[0] - 0.005
    unstow_and_check(stack)
