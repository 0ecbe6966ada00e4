"""Campaign files: validation naming the key, seed derivation, sampling, resume bookkeeping."""

from pathlib import Path

import numpy as np
import pytest
import yaml

from ow_mission.campaign import (
    CampaignConfig,
    mission_label,
    mission_yaml,
    parse_selection,
    sample_mission,
)
from ow_mission.campaign_run import (
    Progress,
    append_result,
    main,
    missing,
    prepare,
    read_results,
    replay_command,
)
from ow_mission.errors import ConfigError
from ow_mission.mission_config import MissionConfig

SHIPPED = Path(__file__).resolve().parents[3] / "src/ow_mission/config/campaign.yaml"


def config(tmp_path: Path, **raw) -> CampaignConfig:
    return CampaignConfig.from_dict(raw, tmp_path, tmp_path / "campaign")


def test_the_shipped_campaign_file_is_valid():
    c = CampaignConfig.load(SHIPPED)
    assert c.missions == 20
    assert c.engine == "local"
    assert [r.key for r in c.randomize] == ["bottom_grind_depth", "dig", "trench_depth", "x", "y"]


@pytest.mark.parametrize(
    ("raw", "match"),
    [
        ({"missions": 0}, r"campaign/missions = 0 is outside \[1, "),
        ({"missions": -4}, r"campaign/missions = -4 is outside"),
        ({"seeed": 1}, r"unknown key 'campaign/seeed' \(did you mean 'seed'\?\)"),
        ({"engine": "spark"}, "campaign/engine = 'spark' is not one of local, ray"),
        ({"randomize": {"x": [1.5, 9.0]}}, r"campaign/randomize/x = 9.0: mission/x = 9 m is out"),
        (
            {"randomize": {"trench_depth": [0.05, 0.12]}},
            r"campaign/randomize/trench_depth = 0.12: mission/trench_depth = 0.12 m is outside",
        ),
        ({"randomize": {"x": [1.8, 1.5]}}, r"campaign/randomize/x = \[1.8, 1.5\] must be .*low"),
        ({"randomize": {"x": 1.5}}, "campaign/randomize/x must be a range"),
        ({"randomize": {"dig": {"linear": 1.2, "circular": 0.3}}}, r"dig/linear = 1.2 is out"),
        ({"randomize": {"dig": {"linear": -0.1, "circular": 1.1}}}, r"dig/linear = -0.1 is out"),
        ({"randomize": {"dig": {"linear": 0.5, "circular": 0.4}}}, "sum to 0.9, not 1"),
        ({"randomize": {"dig": ["linear", "spiral"]}}, "dig = 'spiral': mission/dig = 'spiral'"),
        ({"randomize": {"trench_dept": [0.05, 0.1]}}, "did you mean 'trench_depth'"),
        ({"randomize": {"seed": [1, 5]}}, "campaign/randomize/seed: set by the campaign"),
        ({"mission": {"trench_depth": 0.3}}, "campaign/mission: mission/trench_depth = 0.3 m"),
        ({"mission": {"output_dir": "x"}}, "campaign/mission/output_dir: set by the campaign"),
        ({"mission": {"figures": "after_exit"}}, "campaign/mission/figures: set by the campaign"),
        ({"base": "nowhere.yaml"}, "cannot read base mission .*nowhere.yaml"),
        ({"engine": "ray", "address": "ray://head"}, "campaign/address = 'ray://head' is not"),
        ({"workers": -1}, r"campaign/workers = -1 is outside"),
        ({"figures": "after_exit"}, "campaign/figures = 'after_exit' is not one of none, inline"),
    ],
)
def test_bad_campaign_values_name_the_key(tmp_path, raw, match):
    with pytest.raises(ConfigError, match=match):
        config(tmp_path, **raw)


def test_every_mistake_is_named_at_once(tmp_path):
    with pytest.raises(ConfigError) as caught:
        config(tmp_path, missions=0, seeed=1, randomize={"x": [1.0, 9.0]})
    assert str(caught.value).startswith("3 problems in campaign:")


def test_a_mission_k_is_the_same_alone_or_in_its_campaign(tmp_path):
    raw = {
        "seed": 11,
        "missions": 6,
        "randomize": {"x": [1.5, 1.8], "dig": {"linear": 0.5, "circular": 0.5}},
    }
    c = config(tmp_path, **raw)
    together = [mission_yaml(sample_mission(c, k)) for k in range(6)]
    # Alone: a fresh configuration, only mission 4 sampled; and within a larger campaign.
    alone = mission_yaml(sample_mission(config(tmp_path, **raw), 4))
    assert alone == together[4]
    bigger = config(tmp_path, **{**raw, "missions": 9})
    assert [mission_yaml(sample_mission(bigger, k)) for k in range(6)] == together
    assert len(set(together)) == 6


def test_seeds_come_from_the_campaign_seeds_children(tmp_path):
    c = config(tmp_path, seed=2026, missions=3, randomize={"x": [1.5, 1.8]})
    child = np.random.SeedSequence(2026, spawn_key=(2,))
    assert c.mission_seed(2) == int(child.generate_state(1)[0]) & 0x7FFFFFFF
    assert np.random.SeedSequence(2026).spawn(3)[2].spawn_key == child.spawn_key
    mission = sample_mission(c, 2)
    expected_x = round(float(np.random.default_rng(child).uniform(1.5, 1.8)), 6)
    assert mission["x"] == expected_x
    assert mission["seed"] == c.mission_seed(2)
    assert mission["output_dir"] == str(tmp_path / "campaign" / "missions" / "002")
    # Its run is complete when it exits (the shipped base mission says after_exit): the
    # numbers only, unless the campaign asks for every mission's figures.
    assert mission["figures"] == "none"
    assert sample_mission(config(tmp_path, figures="inline"), 2)["figures"] == "inline"
    assert MissionConfig.from_dict(mission).x == expected_x
    assert config(tmp_path, seed=2027, missions=3).mission_seed(2) != c.mission_seed(2)


def test_choices_follow_their_probabilities(tmp_path):
    c = config(tmp_path, missions=400, randomize={"dig": {"linear": 0.8, "circular": 0.2}})
    digs = [sample_mission(c, k)["dig"] for k in range(400)]
    assert 0.74 < digs.count("linear") / 400 < 0.86
    never = config(tmp_path, missions=20, randomize={"dig": {"linear": 0.0, "circular": 1.0}})
    assert {sample_mission(never, k)["dig"] for k in range(20)} == {"circular"}


FAULT = {"at_step": "grind", "set": {"shou_pitch_joint_locked_failure": True}}


def test_fault_schedules_are_drawn_with_their_probabilities(tmp_path):
    raw = {"seed": 5, "missions": 300, "randomize": {"x": [1.5, 1.8]}}
    faults = [
        {"probability": 0.3, **FAULT, "after_s": [1.0, 5.0]},
        {"probability": 0.0, "at_time_s": 10.0, "set": {"high_power_draw": 50.0}},
    ]
    c = config(tmp_path, **raw, faults=faults)
    missions = [sample_mission(c, k) for k in range(300)]
    got = [m["faults"] for m in missions]
    assert 0.22 < sum(1 for f in got if f) / 300 < 0.38
    assert all(len(f) <= 1 and (not f or f[0]["at_step"] == "grind") for f in got)
    delays = [f[0]["after_s"] for f in got if f]
    assert min(delays) < 1.5 and max(delays) > 4.5
    # The randomized keys are drawn first: adding faults leaves them as they were.
    plain = config(tmp_path, **raw)
    assert [m["x"] for m in missions[:20]] == [sample_mission(plain, k)["x"] for k in range(20)]
    assert len(MissionConfig.from_dict(next(m for m in missions if m["faults"])).faults) == 1


@pytest.mark.parametrize(
    ("fault", "match"),
    [
        ({"probability": 1.5, **FAULT}, r"campaign/faults\[0\]/probability = 1.5 is outside"),
        ({"probability": -0.1, **FAULT}, r"campaign/faults\[0\]/probability = -0.1 is outside"),
        (FAULT, r"campaign/faults\[0\] must be a mapping with a probability"),
        (
            {"probability": 0.5, "at_step": "grnd", "set": FAULT["set"]},
            r"campaign/faults\[0\]: mission/faults\[0\]/at_step.*did you mean 'grind'",
        ),
        (
            {"probability": 0.5, "at_step": "grind", "set": {"shou_pitch_joint_locked": True}},
            r"campaign/faults\[0\]: mission/faults\[0\]/set",
        ),
        ({"probability": 0.5, **FAULT, "after_s": [5, 1]}, r"after_s = \[5, 1\] must be"),
    ],
)
def test_bad_fault_schedules_name_the_entry(tmp_path, fault, match):
    with pytest.raises(ConfigError, match=match):
        config(tmp_path, faults=[fault])


def test_labels_and_selection():
    assert mission_label(7, 20) == "007"
    assert mission_label(7, 20000) == "00007"
    assert parse_selection("0, 2-4", 6) == [0, 2, 3, 4]
    with pytest.raises(ConfigError, match=r"--missions: 7 is outside \[0, 5\]"):
        parse_selection("7", 6)
    with pytest.raises(ConfigError, match="'x' is not a number"):
        parse_selection("x", 6)


def test_results_are_appended_and_a_cut_line_is_ignored(tmp_path):
    append_result(tmp_path, {"index": 0, "success": True})
    with (tmp_path / "results.jsonl").open("a") as f:
        f.write('{"index": 1, "succ')  # a crash in the middle of a write
    append_result(tmp_path, {"index": 2, "success": False})
    results = read_results(tmp_path)
    assert sorted(results) == [0, 2]
    assert read_results(tmp_path / "nowhere") == {}


def test_prepare_writes_each_mission_once_and_refuses_another_campaign(tmp_path):
    c = config(tmp_path, seed=3, missions=2, randomize={"x": [1.5, 1.8]})
    files = prepare(c, "seed: 3\n")
    assert files[1] == tmp_path / "campaign/missions/001/mission.yaml"
    assert yaml.safe_load(files[1].read_text()) == sample_mission(c, 1)
    assert prepare(c, "seed: 3\n") == files  # resuming: same files
    other = config(tmp_path, seed=4, missions=2, randomize={"x": [1.5, 1.8]})
    with pytest.raises(ConfigError, match="holds mission 0 of another campaign"):
        prepare(other, "seed: 4\n")


def test_resume_runs_only_missing_missions(tmp_path):
    for k in (1, 2):
        append_result(tmp_path, {"index": k, "success": k == 1})
    done = read_results(tmp_path)
    assert missing(done, range(4)) == [0, 3]  # a failed mission has its result: done
    assert missing(done, [2, 3]) == [3]
    # A mission that wrote no report (crashed, timed out, stopped) has no result: run again.
    append_result(tmp_path, {"index": 0, "success": False, "crashed": True})
    append_result(tmp_path, {"index": 3, "success": True})
    assert missing(read_results(tmp_path), range(4)) == [0]
    append_result(tmp_path, {"index": 0, "success": True})
    assert missing(read_results(tmp_path), range(4)) == []


def test_bad_input_is_refused_before_anything_starts(tmp_path, capsys):
    path = tmp_path / "c.yaml"
    path.write_text("missions: 0\nengine: ray\naddress: 127.0.0.1:1\n")
    assert main([str(path)]) == 2
    assert "campaign/missions = 0" in capsys.readouterr().err
    assert not (tmp_path / "campaigns").exists()


def test_an_unreachable_ray_address_is_named(tmp_path, capsys):
    pytest.importorskip("ray")
    path = tmp_path / "c.yaml"
    path.write_text(
        f"missions: 1\nengine: ray\naddress: ray://127.0.0.1:1\ndirectory: {tmp_path}\n"
    )
    assert main([str(path)]) == 2
    err = capsys.readouterr().err
    assert "campaign/address = 'ray://127.0.0.1:1': cannot connect to 127.0.0.1:1" in err
    assert read_results(tmp_path) == {}


def test_progress_line_counts_and_eta():
    progress = Progress(total=10, done=4, to_run=6, parallel=2)
    assert progress.line().endswith("4/10 done (0 failed this run), 2 running, 4 waiting, ETA ?")
    progress.started -= 60.0
    line = progress.update({"success": False})
    assert "5/10 done (1 failed this run), 2 running, 3 waiting, ETA 5 min 0 s" in line


def test_replay_command():
    assert replay_command("/c/missions/007/mission.yaml") == (
        "rosrun ow_mission mission /c/missions/007/mission.yaml"
    )
