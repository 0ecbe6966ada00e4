"""Guarded move with the force detector (``execution/ground_detector: force``): contact when the
wrist force/torque sensor the simulation publishes at j_dist_pitch rises over its threshold."""

import time

import pytest
import rospy

from ow_bringup.testing import subscribe, wait_connected
from ow_description.description import DEFAULT_GROUND_Z
from ow_lander.config import ExecutionConfig
from ow_msgs.srv import GuardedMove, Unstow
from owl_msgs.msg import ArmEndEffectorForceTorque

GROUND = DEFAULT_GROUND_Z
CONTACT_N = ExecutionConfig().ground_force_threshold_n  # N, the force detector's default


def peak_force(readings: list[tuple[float, float]]) -> float:
    """N, the largest force magnitude of (stamp, |force| squared) readings (0 without any)."""
    return max((force for _, force in readings), default=0.0) ** 0.5


@pytest.fixture(scope="module")
def stack(start_lander):
    ros_stack = start_lander(
        arm={"execution": {"ground_detector": "force"}},
        arm_services=["/arm/guarded_move"],
        sim_topics=["/arm_end_effector_force_torque"],
    )
    response = ros_stack.service("/arm/unstow", Unstow)(delete_prev_traj=False)
    assert response.success, response.message
    return ros_stack


def test_wrist_sensor_reads_zero_in_free_space(stack):
    msg = rospy.wait_for_message(
        "/arm_end_effector_force_torque", ArmEndEffectorForceTorque, timeout=10
    )
    assert msg.header.frame_id == "l_dist"
    force = msg.value.force
    assert abs(force.x) + abs(force.y) + abs(force.z) < 1e-6


def test_force_detector_finds_the_ground(stack):
    readings = []  # (stamp s, |force| squared N^2)
    sub = wait_connected(
        subscribe(
            "/arm_end_effector_force_torque",
            ArmEndEffectorForceTorque,
            lambda m: readings.append(
                (
                    m.header.stamp.to_sec(),
                    m.value.force.x**2 + m.value.force.y**2 + m.value.force.z**2,
                )
            ),
        )
    )
    try:
        response = stack.service("/arm/guarded_move", GuardedMove)(
            use_defaults=False, x=1.7, y=0.0, z=GROUND + 0.2, direction_x=0.0, direction_y=0.0,
            direction_z=1.0, search_distance=0.5,
        )  # fmt: skip
        # This test's readings may lag the arm services' own, and so may its clock (a loaded
        # test process once read a /clock from before the contact): wait for the contact
        # reading itself. Every reading arrives (unbounded queue), so only a sensor that never
        # saw the contact runs into the deadline.
        deadline = time.monotonic() + 20.0
        while peak_force(readings) < CONTACT_N and time.monotonic() < deadline:
            time.sleep(0.01)
    finally:
        sub.unregister()
    assert response.success, response.message
    assert response.ground_found
    assert response.ground_position.z == pytest.approx(GROUND, abs=0.005)
    # The sensor saw the contact: at least the threshold (its free-space tare is zero).
    assert peak_force(readings) >= CONTACT_N
