"""One configuration path: the shipped YAML files load into every node's configuration class,
they hold the built-in defaults, and the mission's layers go on top of them."""

from collections.abc import Callable
from typing import Any

import pytest

from ow_faults.injection import FaultSet
from ow_lander.config import ArmServicesConfig
from ow_lander.telemetry import TelemetryConfig
from ow_mission.errors import ConfigError
from ow_mission.node_config import STACK_NODES, merge, shipped_parameters, stack_parameters
from ow_power.config import BatteryConfig, PowerConfig, RecorderConfig
from ow_sim_bullet.config import SimConfig
from ow_viz.config import VizConfig

PARSERS: dict[str, Callable[[Any], Any]] = {
    "sim": SimConfig.from_dict,
    "arm_services": ArmServicesConfig.from_dict,
    "power": PowerConfig.from_dict,
    "battery": BatteryConfig.from_dict,
    "record": RecorderConfig.from_dict,
    "viz": VizConfig.from_dict,
    "telemetry": TelemetryConfig.from_dict,
    "faults": FaultSet.from_dict,
    "detector": dict,  # no parameters
}


def test_every_stack_node_has_a_parser():
    assert {n.executable for n in STACK_NODES} == set(PARSERS)


@pytest.mark.parametrize("node", STACK_NODES, ids=lambda n: n.executable)
def test_shipped_yaml_loads_and_holds_the_defaults(node):
    parse = PARSERS[node.executable]
    from_yaml = parse(shipped_parameters(node))
    # The files say they list the built-in defaults: a stack started from them (launch files,
    # mission) is configured exactly as a node started bare.
    assert from_yaml == parse({})


def test_layers_go_on_top_in_order_and_merge_nested_keys():
    params = stack_parameters(
        {"sim": {"terrain": "flat:-0.2"}, "arm_services": {"execution": {"settle_timeout_s": 3.0}}},
        {"sim": {"terrain": "europa:3"}},
    )
    assert params["sim"]["terrain"] == "europa:3"
    assert params["sim"]["gains"]["j_shou_yaw"]["p"] == pytest.approx(1000.0)  # pid.yaml kept
    execution = params["arm_services"]["execution"]
    assert execution["settle_timeout_s"] == 3.0
    assert execution["ground_detector"] == "velocity"  # the rest of the section kept


def test_an_unknown_node_is_refused_by_name():
    with pytest.raises(ConfigError, match="no node 'arm' in the stack"):
        stack_parameters({"arm": {"plan_and_execute": True}})


def test_merge_replaces_lists_and_leaves_its_inputs_alone():
    base = {"topics": ["/a"], "nested": {"x": 1, "y": 2}}
    merged = merge(base, {"topics": ["/b"], "nested": {"y": 3}})
    assert merged == {"topics": ["/b"], "nested": {"x": 1, "y": 3}}
    assert base == {"topics": ["/a"], "nested": {"x": 1, "y": 2}}


def test_the_mission_runs_in_lockstep_unless_node_params_turn_it_off(tmp_path):
    from ow_mission.mission import node_parameters
    from ow_mission.mission_config import MissionConfig

    params = node_parameters(MissionConfig.from_dict({}), tmp_path)
    assert params["sim"]["lockstep_clients"] == ["/arm_services"]
    assert params["arm_services"]["execution"]["lockstep"] is True
    assert params["arm_services"]["execution"]["lockstep_hold"] is True
    off = {"node_params": {"arm_services": {"execution": {"lockstep": False}}}}
    params = node_parameters(MissionConfig.from_dict(off), tmp_path)
    # Else the simulation would wait at t = 0 for arm services that never register.
    assert params["sim"]["lockstep_clients"] == []
    assert params["arm_services"]["execution"]["lockstep_hold"] is False
