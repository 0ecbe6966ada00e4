"""The fault set of ow_faults without ROS: OceanWATERS' table (checked against the generated
dynamic_reconfigure config), validation messages, locks, custom power profiles."""

from __future__ import annotations

import pytest

from ow_faults.errors import FaultError
from ow_faults.injection import LOCKABLE_JOINTS, PARAMETERS, FaultSet, read_power_profile


def test_the_table_is_the_generated_server_config():
    from ow_faults.cfg import FaultsConfig

    assert list(FaultsConfig.defaults) == list(PARAMETERS)
    for name, parameter in PARAMETERS.items():
        assert FaultsConfig.defaults[name] == parameter.default, name
        assert (
            FaultsConfig.type[name]
            == {bool: "bool", int: "int", float: "double", str: "str"}[parameter.kind]
        )
        if parameter.minimum is not None:
            assert FaultsConfig.min[name] == parameter.minimum, name
            assert FaultsConfig.max[name] == parameter.maximum, name
    groups = {
        p["name"]: g["name"]
        for g in FaultsConfig.config_description["groups"]
        for p in g["parameters"]
    }
    assert groups == {n: p.group for n, p in PARAMETERS.items()}
    assert FaultSet().as_dict() == {n: p.default for n, p in PARAMETERS.items()}


def test_oceanwaters_ranges_and_the_camera():
    assert (
        PARAMETERS["signal_bias_failure"].minimum,
        PARAMETERS["signal_bias_failure"].maximum,
    ) == (-1, 1)
    assert (PARAMETERS["high_power_draw"].minimum, PARAMETERS["high_power_draw"].maximum) == (
        1,
        360,
    )
    assert PARAMETERS["battery_nodes_to_disconnect"].maximum == 3
    assert [name for name in PARAMETERS if "camera" in name] == ["camera_left_trigger_failure"]
    assert PARAMETERS["camera_left_trigger_failure"].group == "cam_faults"


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        (
            {"elbow_joint_locked_failure": True},
            "unknown fault parameter 'elbow_joint_locked_failure'",
        ),
        (
            {"signal_bias_failure": 1.5},
            "signal_bias_failure = 1.5 N, N m is outside [-1, 1] N, N m",
        ),
        ({"signal_noise_failure": -0.1}, "signal_noise_failure = -0.1 N, N m is outside [0, 1]"),
        ({"high_power_draw": 400.0}, "high_power_draw = 400.0 W is outside [1, 360] W"),
        (
            {"battery_nodes_to_disconnect": 4},
            "battery_nodes_to_disconnect = 4 cells is outside [0, 3]",
        ),
        (
            {"battery_nodes_to_disconnect": 1.5},
            "battery_nodes_to_disconnect = 1.5 must be an integer",
        ),
        ({"thermal_failure": 1}, "thermal_failure = 1 must be a boolean"),
        ({"signal_noise_failure": float("nan")}, "signal_noise_failure = nan"),
        (
            {"activate_custom_fault": True, "custom_fault_profile": "missing.csv"},
            "custom_fault_profile 'missing.csv': cannot read",
        ),
    ],
)
def test_bad_changes_are_refused_naming_the_value_and_the_limit(changes, message):
    with pytest.raises(FaultError, match=None) as error:
        FaultSet().changed(changes)
    assert message in str(error.value)


def test_locks_name_the_urdf_joints():
    faults = FaultSet.from_dict(
        {"shou_pitch_joint_locked_failure": True, "ant_tilt_joint_locked_failure": True}
    )
    assert faults.locked_joints == {"j_shou_pitch", "j_ant_tilt"}
    assert list(LOCKABLE_JOINTS) == sorted(LOCKABLE_JOINTS) and len(LOCKABLE_JOINTS) == 8
    assert faults.active() == {
        "shou_pitch_joint_locked_failure": True,
        "ant_tilt_joint_locked_failure": True,
    }


def test_the_server_config_groups_key_is_ignored_and_ints_become_floats():
    faults = FaultSet.from_dict(
        {"groups": {}, "high_power_draw": 200, "activate_high_power_draw": True}
    )
    assert faults.extra_load_w == 200.0 and isinstance(faults.high_power_draw, float)


def test_wrist_faults_need_enable():
    assert not FaultSet(zero_signal_failure=True).wrist_faulted
    assert FaultSet(enable=True, zero_signal_failure=True).wrist_faulted
    assert FaultSet(enable=True, signal_bias_failure=0.1).wrist_faulted
    assert not FaultSet(enable=True).wrist_faulted


def test_disconnection_is_irreversible():
    faults = FaultSet().changed(
        {"battery_nodes_to_disconnect": 2, "disconnect_battery_nodes": True}
    )
    assert faults.cells_disconnected == 2
    with pytest.raises(FaultError, match="irreversible"):
        faults.changed({"disconnect_battery_nodes": False})
    with pytest.raises(FaultError, match="irreversible"):
        faults.changed({"battery_nodes_to_disconnect": 1})
    assert faults.changed({"battery_nodes_to_disconnect": 3}).cells_disconnected == 3


def test_the_shipped_profile_reads_and_holds_each_row_a_second():
    profile = read_power_profile("example_fault.csv")
    assert len(profile.watts) == 49
    assert profile.load_at(0.0) == profile.watts[0]
    assert profile.load_at(15.5) == profile.watts[15]
    assert profile.load_at(49.0) == 0.0 and profile.load_at(-1.0) == 0.0


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("", "header must be 'Index, wattage', found an empty file"),
        ("time, watts\n0, 1\n", "header must be 'Index, wattage'"),
        ("Index, wattage\n", "no data rows"),
        ("Index, wattage\n0, 10\n2, 10\n", "line 3: Index 2 must be 1"),
        ("Index, wattage\n0, ten\n", "line 2: ['0', 'ten'] is not two numbers"),
        ("Index, wattage\n0, 400\n", "line 2: wattage 400 W is outside [0, 360] W"),
        ("Index, wattage\n0, -1\n", "wattage -1 W is outside"),
    ],
)
def test_malformed_profiles_are_refused_naming_the_line(tmp_path, text, message):
    path = tmp_path / "profile.csv"
    path.write_text(text)
    with pytest.raises(FaultError) as error:
        read_power_profile(str(path))
    assert message in str(error.value)
    with pytest.raises(FaultError):
        FaultSet().changed({"custom_fault_profile": str(path), "activate_custom_fault": True})
