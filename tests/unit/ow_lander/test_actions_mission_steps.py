"""The mission's steps mapped onto OceanWATERS' actions (ow_mission.action_steps, no ROS)."""

import math

import pytest

import owl_msgs.msg as owl
from ow_lander.actions.owl import to_request, validate_goal
from ow_lander.conversions import fill_fields, goal_to_dict
from ow_lander.operations.workspace import GRIND_PASS_SHIFT, shoulder_yaw_for
from ow_mission.action_steps import action_goal, step_response
from ow_mission.errors import ConfigError
from ow_mission.mission import STEPS
from ow_mission.mission_config import MissionConfig

GROUND = -0.155
ACTIONS = {
    "unstow": "ArmUnstow",
    "guarded_move": "ArmFindSurface",
    "grind": "TaskGrind",
    "dig_spoil": "TaskScoopLinear",
    "discard_spoil": "TaskDiscardSample",
    "grind_bottom": "TaskGrind",
    "dig_sample": "TaskScoopLinear",
    "deliver_sample": "TaskDeliverSample",
    "stow": "ArmStow",
}


@pytest.mark.parametrize("dig", ["linear", "circular"])
def test_every_step_has_a_valid_goal(dig):
    config = MissionConfig(dig=dig)
    for step in STEPS:
        action, fields = action_goal(step.name, step.request(config, GROUND), dig)
        expected = ACTIONS[step.name]
        if dig == "circular":
            expected = expected.replace("Linear", "Circular")
        assert action == expected
        goal = fill_fields(getattr(owl, f"{action}Goal")(), fields)
        validate_goal(action, goal_to_dict(goal))


def _operation(step, config, dig="linear"):
    """The service request the action server makes of the step's goal (tool pose unused)."""
    import numpy as np

    action, fields = action_goal(step.name, step.request(config, GROUND), dig)
    goal = goal_to_dict(fill_fields(getattr(owl, f"{action}Goal")(), fields))
    return to_request(action, goal, np.zeros(6), np.eye(4))


def test_the_search_is_the_services():
    config = MissionConfig()
    steps = {s.name: s for s in STEPS}
    search = _operation(steps["guarded_move"], config).request
    service = steps["guarded_move"].request(config, GROUND)
    for key in ("x", "y", "z", "direction_x", "direction_y", "direction_z", "search_distance"):
        assert search[key] == pytest.approx(service[key]), key


@pytest.mark.parametrize("step", ["grind", "grind_bottom"])
def test_the_grind_is_the_services(step):
    config = MissionConfig()
    steps = {s.name: s for s in STEPS}
    grind = _operation(steps[step], config).request
    service = steps[step].request(config, GROUND)
    # The first pass's start, from the centre as the grind operation places it.
    yaw = shoulder_yaw_for(grind["x"], grind["y"], -math.pi, math.pi)
    heading = (math.cos(yaw), math.sin(yaw))
    right = (math.sin(yaw), -math.cos(yaw))
    along, shift = (heading, (-right[0], -right[1])) if grind["parallel"] else (right, heading)
    start = [
        c - a * grind["length"] / 2 - s * GRIND_PASS_SHIFT / 2
        for c, a, s in zip((grind["x"], grind["y"]), along, shift, strict=True)
    ]
    assert start == pytest.approx([service["x"], service["y"]], abs=1e-3)


def test_the_actions_do_what_the_services_did():
    config = MissionConfig()
    steps = {s.name: s for s in STEPS}
    dig = _operation(steps["dig_spoil"], config).request
    service = steps["dig_spoil"].request(config, GROUND)
    # TaskScoopLinear's point is the middle of the cut; the service's (x, y) is its start.
    yaw = shoulder_yaw_for(dig["x"], dig["y"], -math.pi, math.pi)
    start = (
        dig["x"] - dig["length"] / 2 * math.cos(yaw),
        dig["y"] - dig["length"] / 2 * math.sin(yaw),
    )
    assert start == pytest.approx((service["x"], service["y"]), abs=1e-4)
    for key in ("depth", "length", "ground_position"):
        assert dig[key] == pytest.approx(service[key], abs=1e-4), key
    discard = _operation(steps["discard_spoil"], config)
    assert discard.operation == "discard"
    assert [discard.request[k] for k in "xyz"] == pytest.approx(list(config.discard))
    grind = _operation(steps["grind_bottom"], config)
    assert grind.request["ground_position"] == pytest.approx(GROUND - config.trench_depth)
    assert grind.request["parallel"] is config.parallel


def test_ground_comes_from_find_surface_final_pose():
    result = owl.ArmFindSurfaceResult()
    result.final_pose.position.x, result.final_pose.position.z = 1.65, -0.158
    response = step_response("ArmFindSurface", True, "ground found", result)
    assert response.success and response.ground_found
    assert (response.ground_position.x, response.ground_position.z) == (1.65, -0.158)
    failed = step_response("ArmFindSurface", False, "No surface was found", None)
    assert not failed.success and not failed.ground_found
    assert failed.message == "ArmFindSurface: No surface was found"
    # OceanWATERS ends a search without contact SUCCEEDED: still no ground.
    nothing = step_response("ArmFindSurface", True, "No surface was found", result)
    assert nothing.success and not nothing.ground_found


def test_interface_key():
    assert MissionConfig.from_dict({}).interface == "services"
    assert MissionConfig.from_dict({"interface": "actions"}).interface == "actions"
    with pytest.raises(ConfigError, match="interface"):
        MissionConfig.from_dict({"interface": "topics"})
    with pytest.raises(ConfigError, match="no action"):
        action_goal("dance", {}, "linear")
