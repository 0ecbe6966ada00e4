"""The task actions and the guarded arm actions on the simulation: each succeeds and its
result matches where the arm is (forward kinematics of /joint_states). The stack, joint log and
model fixtures are test_actions' (imported: one definition)."""
# ruff: noqa: F811  (pytest passes the imported fixtures as arguments of the same names)

from __future__ import annotations

import numpy as np
from actionlib_msgs.msg import GoalStatus
from geometry_msgs.msg import Point, Pose, Quaternion
from test_actions import joints, model, run, stack, tip  # noqa: F401 (fixtures)

import owl_msgs.msg as owl
from ow_bringup.testing import set_terrain
from ow_description.description import (
    ARM_JOINTS,
    DEFAULT_GROUND_Z,
    SCOOP_ABOVE_GROUND,
    SCOOP_BELOW_GROUND,
)
from ow_lander.actions.owl import quaternion_from_rotation
from ow_lander.operations.planner import DOCK_CENTRE, DOCK_POUR_HEIGHT

GROUND = DEFAULT_GROUND_Z


def _ok(name, goal, timeout=600.0):
    state, result, text = run(name, goal, timeout=timeout)
    assert state == GoalStatus.SUCCEEDED, text
    return result


def test_grind_result_is_the_tool_tip(stack, joints, model):
    set_terrain(stack, f"flat:{GROUND}", lift_arm=True)
    result = _ok("TaskGrind", owl.TaskGrindGoal(1.65, 0.0, 0.05, 0.4, 1.0, GROUND))
    X = tip(model, joints.latest())
    assert np.allclose([result.final.x, result.final.y, result.final.z], X[:3, 3], atol=0.01)


def test_scoop_linear_and_circular(stack):
    set_terrain(stack, f"flat:{GROUND}", lift_arm=True)
    _ok("TaskScoopLinear", owl.TaskScoopLinearGoal(0, False, Point(1.5, 0.0, GROUND), 0.02, 0.1))
    _ok(
        "TaskScoopCircular",
        owl.TaskScoopCircularGoal(0, False, Point(1.65, 0.3, GROUND), 0.02, True),
    )


def test_deliver_and_discard(stack, joints, model):
    _ok("TaskDeliverSample", owl.TaskDeliverSampleGoal())
    dock = np.add(DOCK_CENTRE, [0.0, 0.0, DOCK_POUR_HEIGHT])
    assert np.allclose(tip(model, joints.latest())[:3, 3], dock, atol=0.01)
    _ok("TaskDiscardSample", owl.TaskDiscardSampleGoal(0, False, Point(1.5, 0.8, GROUND), 0.4))
    # OceanWATERS places the l_scoop link's origin (not the tip) at point + height, then tips
    # the scoop about it.
    q = model.q_from(dict(zip(ARM_JOINTS, joints.latest(), strict=True)))
    assert np.allclose(model.position(q, "l_scoop"), [1.5, 0.8, GROUND + 0.4], atol=0.01)
    _ok("ArmStow", owl.ArmStowGoal())


def test_guarded_joint_move_stops_on_the_ground(stack, joints, model):
    set_terrain(stack, f"flat:{GROUND}", lift_arm=True)
    above = [SCOOP_ABOVE_GROUND[j] for j in ARM_JOINTS]
    _ok("ArmMoveJoints", owl.ArmMoveJointsGoal(False, above))
    below = [SCOOP_BELOW_GROUND[j] for j in ARM_JOINTS]
    result = _ok("ArmMoveJointsGuarded", owl.ArmMoveJointsGuardedGoal(False, below, 10.0, 10.0))
    joints.wait_sim(1.0)  # back at, and holding, the breach position
    z = tip(model, joints.latest())[2, 3]
    assert GROUND - 0.02 < z < GROUND + 0.01  # stopped at the surface, not 5 cm under it
    assert not np.allclose(result.final_angles, below, atol=0.02)
    assert np.allclose(result.final_angles, joints.latest(), atol=0.005)


def test_guarded_cartesian_move_stops_on_the_ground(stack, joints, model):
    set_terrain(stack, f"flat:{GROUND}", lift_arm=True)
    above = [SCOOP_ABOVE_GROUND[j] for j in ARM_JOINTS]
    _ok("ArmMoveJoints", owl.ArmMoveJointsGoal(False, above))
    X = tip(model, joints.latest())
    target = Pose(
        Point(*(X[:3, 3] - [0.0, 0.0, 0.1])), Quaternion(*quaternion_from_rotation(X[:3, :3]))
    )
    goal = owl.ArmMoveCartesianGuardedGoal(0, False, target, 10.0, 10.0)
    result = _ok("ArmMoveCartesianGuarded", goal)
    joints.wait_sim(1.0)
    p = result.final_pose.position
    assert GROUND - 0.02 < p.z < GROUND + 0.01
    assert np.allclose([p.x, p.y, p.z], tip(model, joints.latest())[:3, 3], atol=0.01)
    assert result.final_force > 10.0 or result.final_torque > 10.0  # what stopped it
