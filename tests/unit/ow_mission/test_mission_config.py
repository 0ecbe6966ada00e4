"""Mission files: defaults, validation naming the key, the steps' requests, the report table."""

from pathlib import Path

import pytest

from ow_mission.errors import ConfigError
from ow_mission.mission import STEPS, Ingestion, MissionReport, StepResult, mission_steps
from ow_mission.mission_config import DEFAULT_MISSION_FILE, MissionConfig, config_from_argv


def test_the_shipped_mission_file_is_valid_and_complete():
    config = MissionConfig.load(DEFAULT_MISSION_FILE)
    assert config.trench_depth == pytest.approx(0.10)
    # The file lists every key, so users see all they can change.
    import yaml

    assert set(yaml.safe_load(DEFAULT_MISSION_FILE.read_text())) == set(
        MissionConfig.__dataclass_fields__
    )


@pytest.mark.parametrize(
    ("raw", "match"),
    [
        ({"trench_depth": -0.1}, r"mission/trench_depth = -0.1 m is outside \[0, 0.1\] m"),
        # the scoop digs the trench out: the dig services' limit holds, not the grinder's
        ({"trench_depth": 0.12}, r"mission/trench_depth = 0.12 m is outside \[0, 0.1\] m"),
        ({"trench_length": 1.5}, r"mission/trench_length = 1.5 m is outside \[0.01, 1\] m"),
        ({"x": float("nan")}, "mission/x must be finite"),
        ({"x": "far"}, "mission/x must be a number"),
        ({"dig": "spiral"}, "mission/dig = 'spiral' is not one of linear, circular"),
        ({"figures": "later"}, "mission/figures = 'later' is not one of after_exit, inline, none"),
        ({"discard": [1, 2]}, "mission/discard must be three numbers"),
        ({"discard": [1, 2, "up"]}, r"mission/discard\[2\] must be a number"),
        ({"seed": -3}, r"mission/seed = -3 is outside \[0, inf\]"),
        ({"parallel": "yes"}, "mission/parallel must be true or false"),
        ({"depth": 0.1}, "unknown key 'mission/depth'"),
        ({"node_params": {"sim": 3}}, "mission/node_params must map node names"),
        ({"node_params": {"arm_service": {}}}, "no such node.*did you mean 'arm_services'"),
    ],
)
def test_bad_mission_values_name_the_key(raw, match):
    with pytest.raises(ConfigError, match=match):
        MissionConfig.from_dict(raw)


def test_every_mistake_is_named_at_once_with_suggestions():
    with pytest.raises(ConfigError) as caught:
        MissionConfig.from_dict({"trench_dept": 0.05, "x": 9.0, "dig": "linaer"})
    text = str(caught.value)
    assert text.startswith("3 problems in mission:")
    assert "unknown key 'mission/trench_dept' (did you mean 'trench_depth'?)" in text
    assert "mission/x = 9 m is outside [-3, 3] m" in text
    assert "mission/dig = 'linaer' is not one of linear, circular (did you mean 'linear'?)" in text


def test_missing_and_broken_files(tmp_path: Path):
    with pytest.raises(ConfigError, match="cannot read mission file"):
        MissionConfig.load(tmp_path / "none.yaml")
    bad = tmp_path / "bad.yaml"
    bad.write_text("x: [1,\n")
    with pytest.raises(ConfigError, match="not valid YAML"):
        MissionConfig.load(bad)


def test_the_ground_found_feeds_the_later_steps():
    config = MissionConfig(trench_depth=0.1, bottom_grind_depth=0.04)
    ground = -0.2
    requests = {s.name: s.request(config, ground) for s in STEPS}
    assert [s.name for s in STEPS] == [
        "unstow", "guarded_move", "grind", "dig_spoil", "discard_spoil",
        "grind_bottom", "dig_sample", "deliver_sample", "stow",
    ]  # fmt: skip
    assert requests["grind"]["ground_position"] == ground
    assert requests["dig_spoil"]["ground_position"] == ground
    assert requests["dig_spoil"]["depth"] == pytest.approx(0.1)
    assert requests["grind_bottom"]["ground_position"] == pytest.approx(-0.3)
    assert requests["dig_sample"]["ground_position"] == pytest.approx(-0.3)
    assert requests["dig_sample"]["depth"] == pytest.approx(0.04)
    assert requests["discard_spoil"] == {"x": 1.3, "y": 0.9, "z": 0.4}
    assert requests["deliver_sample"] == {"use_defaults": True}
    assert requests["guarded_move"]["z"] == pytest.approx(config.expected_ground + 0.25)


def test_a_mission_without_a_first_trench_samples_the_surface():
    """trench_depth 0: no first grind, spoil dig or discard; the bottom grind and the sample's
    dig start at the ground found (the top layer the paper's first trench would remove)."""
    config = MissionConfig(trench_depth=0.0, bottom_grind_depth=0.05)
    steps = mission_steps(config)
    assert [s.name for s in steps] == [
        "unstow", "guarded_move", "grind_bottom", "dig_sample", "deliver_sample", "stow",
    ]  # fmt: skip
    requests = {s.name: s.request(config, -0.2) for s in steps}
    assert requests["grind_bottom"]["ground_position"] == pytest.approx(-0.2)
    assert requests["dig_sample"]["ground_position"] == pytest.approx(-0.2)
    assert mission_steps(MissionConfig()) == STEPS


def _all_steps_ok(config: MissionConfig, tmp_path: Path) -> MissionReport:
    report = MissionReport(config, tmp_path)
    for step in mission_steps(config):
        report.steps.append(StepResult(step.name, step.service, {}, success=True))
    return report


def test_a_mission_succeeds_only_with_a_sample_ingested(tmp_path: Path):
    report = _all_steps_ok(MissionConfig(), tmp_path)
    assert not report.success  # the ingestion was not tried
    report.ingestion = Ingestion(True, True, "Sample ingested", 120.0, 0.1)
    assert report.success
    assert "sample: ingested (DockIngestSample: Sample ingested)" in report.table()
    assert report.to_json()["ingestion"] == {
        "sample_ingested": True,
        "succeeded": True,
        "message": "Sample ingested",
        "sim_time_s": 120.0,
        "wall_time_s": 0.1,
    }
    surface = _all_steps_ok(MissionConfig(trench_depth=0.0), tmp_path)
    surface.ingestion = Ingestion(True, True, "Sample ingested")
    assert surface.success


@pytest.mark.parametrize(
    ("ingestion", "reason"),
    [
        (
            Ingestion(False, True, "No sample was present in dock"),
            "DockIngestSample: No sample was present in dock: the delivery left no regolith in "
            "the sample dock",
        ),
        (
            Ingestion(False, False, "Removal service failed: /sim/ingest_sample did not answer"),
            "DockIngestSample failed: Removal service failed: /sim/ingest_sample did not answer",
        ),
    ],
)
def test_a_mission_that_ingests_nothing_fails_saying_why(tmp_path, ingestion, reason):
    report = _all_steps_ok(MissionConfig(), tmp_path)
    report.ingestion = ingestion
    assert ingestion.failure() == reason
    assert not report.success
    assert f"sample: none ingested: {reason}" in report.table()


def test_report_table_says_what_failed(tmp_path: Path):
    report = MissionReport(MissionConfig(), tmp_path)
    report.steps.append(StepResult("unstow", "/arm/unstow", {}, success=True))
    report.steps.append(
        StepResult("guarded_move", "/arm/guarded_move", {}, message="no ground within 0.50 m")
    )
    report.error = "step guarded_move (/arm/guarded_move) failed: no ground within 0.50 m"
    text = report.table()
    assert "FAILED: no ground within 0.50 m" in text
    assert "MISSION STOPPED" in text
    assert not report.success


def test_the_command_line_names_one_file_or_asks_for_help(tmp_path: Path):
    mission = tmp_path / "m.yaml"
    mission.write_text("trench_depth: 0.05\n")
    assert config_from_argv([str(mission), "__name:=mission"]).trench_depth == 0.05
    assert config_from_argv([]) == MissionConfig.load(DEFAULT_MISSION_FILE)
    assert config_from_argv(["--help"]) is None
    assert config_from_argv([str(mission), "--wait-figures"]).trench_depth == 0.05
    with pytest.raises(ConfigError, match="one mission file at most, got 2"):
        config_from_argv(["a.yaml", "b.yaml"])
