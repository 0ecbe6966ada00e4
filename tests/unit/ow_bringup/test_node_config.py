"""One configuration path: the shipped YAML files load into every node's configuration class,
they hold the built-in defaults, and the mission's layers go on top of them."""

from collections.abc import Callable
from dataclasses import asdict
from typing import Any

import pytest

from ow_bringup.errors import ConfigError
from ow_bringup.node_config import STACK_NODES, merge, shipped_parameters, stack_parameters
from ow_cameras.config import CameraConfig
from ow_faults.injection import FaultSet
from ow_lander.config import ArmServicesConfig
from ow_lander.telemetry.config import TelemetryConfig
from ow_power.config import (
    BATTERY_TOPICS,
    TELEMETRY_TOPICS,
    BatteryConfig,
    PowerConfig,
    RecorderConfig,
)
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
    "camera": CameraConfig.from_dict,
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


def test_a_live_dem_mission_records_its_forces_and_digs_beside_everything_else(tmp_path):
    from ow_mission.mission import node_parameters
    from ow_mission.mission_config import LIVE_DEM_RECORD_TOPICS, MissionConfig
    from ow_runtime.names import MATERIAL_INGESTED, REGOLITH_BUDGET, SIM_DEM_DIGS

    table = set(node_parameters(MissionConfig.from_dict({}), tmp_path)["record"]["topics"])
    live_params = node_parameters(MissionConfig.from_dict({"terrain_forces": "yade"}), tmp_path)
    live = set(live_params["record"]["topics"])
    # The live DEM's topics come on top: the terrain, the regolith, the battery, the faults stay
    # (its record list once replaced the mission's, and its report lost those sections).
    assert live == table | set(LIVE_DEM_RECORD_TOPICS)
    assert {REGOLITH_BUDGET, MATERIAL_INGESTED, "/sim/terrain"} <= live
    assert SIM_DEM_DIGS in live and SIM_DEM_DIGS not in table
    assert live_params["sim"]["tool_state_rate_hz"] == 100.0


def test_the_mission_drains_the_state_topics_it_records_at_their_rates(tmp_path):
    from ow_mission.mission import drain_periods, node_parameters
    from ow_mission.mission_config import MissionConfig

    periods = drain_periods(node_parameters(MissionConfig.from_dict({}), tmp_path))
    assert periods["/joint_states"] == periods["/power"] == 0.0  # one per joint state
    assert {periods[t] for t in TELEMETRY_TOPICS} == {0.1}  # the mission's 10 Hz
    assert {periods[t] for t in BATTERY_TOPICS} == {1.0}  # one battery step per second
    every = {"node_params": {"telemetry": {"rate_hz": 0}, "battery": {"update_rate_hz": 4.0}}}
    periods = drain_periods(node_parameters(MissionConfig.from_dict(every), tmp_path))
    assert {periods[t] for t in TELEMETRY_TOPICS} == {0.0}
    assert {periods[t] for t in BATTERY_TOPICS} == {0.25}
    # Only what is recorded is waited for.
    fewer = {"node_params": {"record": {"topics": ["/joint_states"]}}}
    assert drain_periods(node_parameters(MissionConfig.from_dict(fewer), tmp_path)) == {
        "/joint_states": 0.0
    }


def test_a_topic_is_behind_until_it_has_a_message_within_its_period_of_the_end():
    from ow_mission.mission import topics_behind

    periods = {"/power": 0.0, "/arm_pose": 0.1, "/battery_state": 1.0}
    end = 40.91
    # The 0.35 s of /power a loaded run lost; the battery's last step at 40 s is its last.
    latest = {"/power": 40.56, "/arm_pose": 40.9, "/battery_state": 40.0}
    assert topics_behind(latest, end, periods) == {"/power": 40.56}
    latest["/power"] = 40.91
    assert topics_behind(latest, end, periods) == {}
    latest["/arm_pose"] = 40.8  # 0.11 s before the end: the 40.9 s message is still to come
    assert topics_behind(latest, end, periods) == {"/arm_pose": 40.8}
    # A sum of 0.01 s steps is not exactly the end, and a topic never recorded is not waited for.
    assert topics_behind({"/power": sum([0.01] * 4091)}, end, periods) == {}
    assert topics_behind({}, end, periods) == {}


def test_the_mission_runs_the_monitors_as_components_of_one_node(tmp_path):
    from ow_mission.mission import MONITORS, node_parameters, stack_processes
    from ow_mission.mission_config import MissionConfig

    config = MissionConfig.from_dict({"node_params": {"telemetry": {"rate_hz": 0}}})
    params = node_parameters(config, tmp_path)
    processes = stack_processes(params, "circular")
    assert [p.executable for p in processes] == [
        "record",
        "sim",
        "arm_services",
        "camera",
        "monitors",
    ]
    # Every node of the stack runs: on its own or as a component.
    assert {p.executable for p in processes[:-1]} | set(MONITORS) == set(PARSERS)
    monitors = processes[-1]
    assert monitors.package == "ow_bringup"
    # Each component's parameters in the node's namespace of its name (the detector has none);
    # the fault server and DockIngestSample asked for.
    assert monitors.params == {
        **{c: params[c] for c in ("power", "battery", "telemetry", "viz", "faults")},
        "serve_faults": True,
        "serve_dock_ingest": True,
    }
    assert monitors.params["telemetry"]["rate_hz"] == 0
    assert set(monitors.services) == {"/faults/set_parameters"}
    assert set(monitors.topics) == {
        "/power",
        "/battery_state_of_charge",
        "/robot_description",
        "/arm_joint_positions",
        "/system_faults_status",
        "/faults/parameter_updates",
        "/DockIngestSample/status",
    }
    assert "/arm/dig_circular" in processes[2].services
    assert "/arm/dig_linear" not in processes[2].services
    # The camera node on its own (it renders: a capture must not stall the monitors' streams),
    # ready once its action servers are up, configured from its shipped YAML.
    camera = processes[3]
    assert (camera.package, camera.topics) == ("ow_cameras", ("/CameraCapture/status",))
    assert camera.params == params["camera"]


def test_the_mission_aims_the_mast_at_the_trench_and_keeps_the_papers_power(tmp_path):
    from ow_mission.mission import node_parameters
    from ow_mission.mission_config import MissionConfig
    from ow_mission.workspace_capture import mast_aim

    config = MissionConfig.from_dict({"x": 1.5, "y": -0.6})
    params = node_parameters(config, tmp_path)
    initial = params["sim"]["initial_positions"]
    aim = mast_aim(asdict(config))
    assert (initial["j_ant_pan"], initial["j_ant_tilt"]) == (aim["j_ant_pan"], aim["j_ant_tilt"])
    assert initial["j_shou_yaw"] == stack_parameters()["sim"]["initial_positions"]["j_shou_yaw"]
    lights = CameraConfig.from_dict(params["camera"]).lights
    assert (lights.left, lights.right, lights.power_w) == (0.0, 0.0, 4.8)  # no 9.6 W in P0
    # A mission file may still point the mast elsewhere, or turn the lights on.
    own = {"sim": {"initial_positions": {"j_ant_pan": 0.5}}, "camera": {"lights": {"left": 1}}}
    params = node_parameters(MissionConfig.from_dict({"node_params": own}), tmp_path)
    assert params["sim"]["initial_positions"]["j_ant_pan"] == 0.5
    assert (params["camera"]["lights"]["left"], params["camera"]["lights"]["right"]) == (1, 0.0)


def test_faults_injected_from_the_start_go_to_the_monitors_fault_server(tmp_path):
    from ow_mission.mission import node_parameters, stack_processes
    from ow_mission.mission_config import MissionConfig

    injected = {"ant_pan_joint_locked_failure": True}
    config = MissionConfig.from_dict({"node_params": {"faults": injected}})
    monitors = stack_processes(node_parameters(config, tmp_path), "linear")[-1]
    assert monitors.params["serve_faults"] is True
    assert monitors.params["faults"]["ant_pan_joint_locked_failure"] is True
