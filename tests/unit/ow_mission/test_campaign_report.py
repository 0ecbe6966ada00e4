"""Campaign report: OceanWATERS' statistics and pass rule against hand-computed numbers."""

import json
import math
from types import SimpleNamespace

import pytest

from ow_mission.campaign_report import operation_stats, summarise, write_campaign_report


def step(name, seconds, position, success=True, wh=0.1):
    return {
        "step": name,
        "success": success,
        "sim_time_s": seconds,
        "energy_wh": wh,
        "final_tool_position": position,
    }


def records():
    ok = [
        (0, 10.0, 0.000, 20.0, 0.001),
        (1, 12.0, 0.003, 30.0, 0.003),
        (2, 14.0, 0.006, 40.0, None),
    ]
    out = {
        k: {
            "index": k,
            "seed": 100 + k,
            "success": True,
            "command": f"rosrun ow_mission mission /c/missions/00{k}/mission.yaml",
            "wall_time_s": 30.0,
            "ground_error_m": error,
            "steps": [
                step("dig", dig_s, [1.0, y, 0.0], wh=0.1 * (k + 1)),
                step("stow", stow_s, [0.5, 0.5, 0.5]),
            ],
        }
        for k, dig_s, y, stow_s, error in ok
    }
    out[3] = {
        "index": 3,
        "seed": 103,
        "success": False,
        "failed_step": "stow",
        "error": "step stow (/arm/stow) failed: no plan",
        "command": "rosrun ow_mission mission /c/missions/003/mission.yaml",
        "run_dir": "/c/missions/003/2026-11-30_01-00-00",
        "steps": [step("dig", 99.0, [2.0, 2.0, 2.0]), step("stow", 50.0, None, success=False)],
    }
    out[3]["steps"][0]["success"] = True
    # The runs' sample sections: two ingested a sample, one delivered nothing, one has none.
    for k, volume, top in ((0, 4.0e-4, 0.5), (1, 6.0e-4, 0.25), (3, 0.0, None)):
        out[k]["sample"] = {"ingested": volume > 0, "volume_m3": volume, "top_layer_share": top}
    return out


def test_statistics_by_hand():
    stats = {s.step: s for s in operation_stats([records()[k] for k in range(3)])}
    dig = stats["dig"]
    assert dig.n == 3
    assert dig.duration_mean_s == pytest.approx(12.0)
    assert dig.duration_std_s == pytest.approx(2.0)  # sample std: sqrt((4 + 0 + 4) / 2)
    assert dig.duration_limit_s == pytest.approx(22.0)  # 12 + max(4 * 2, 10)
    assert dig.position_mean == pytest.approx((1.0, 0.003, 0.0))
    assert dig.position_std == pytest.approx((0.0, 0.003, 0.0))
    assert dig.position_tolerance_m == pytest.approx((0.01, 0.012, 0.01))
    assert dig.energy_mean_wh == pytest.approx(0.2)
    assert dig.energy_std_wh == pytest.approx(0.1)
    stow = stats["stow"]
    assert stow.duration_mean_s == pytest.approx(30.0)
    assert stow.duration_std_s == pytest.approx(10.0)
    assert stow.duration_limit_s == pytest.approx(70.0)  # 30 + max(40, 10)


def test_pass_rule_edges():
    dig = {s.step: s for s in operation_stats([records()[k] for k in range(3)])}["dig"]
    assert dig.check(step("dig", 21.9, [1.0, 0.003 + 0.0119, -0.0099])) == []
    reasons = dig.check(step("dig", 22.0, [1.0101, 0.003 - 0.0121, 0.0]))
    assert reasons == [
        "duration 22.0 s >= 22.0 s",
        "final x 1.0101 m is 0.0101 m from 1.0000 m",
        "final y -0.0091 m is 0.0121 m from 0.0030 m",
    ]
    one = operation_stats([records()[0]])[0]
    assert (one.n, one.duration_std_s, one.duration_limit_s) == (1, 0.0, 20.0)


def test_campaign_summary_by_hand():
    summary = summarise(records(), missions=5)
    assert summary["missions_done"] == 4
    assert summary["missions_failed"] == 1
    assert summary["success_rate"] == pytest.approx(0.75)
    # The failed mission's dig succeeded: it counts (4 digs); its stow did not (3 stows).
    ops = {op["step"]: op for op in summary["operations"]}
    assert ops["dig"]["n"] == 4
    assert ops["stow"]["n"] == 3
    # Mission 3's dig (99 s, 1 m off) is outside the rule computed with it.
    assert [(o["index"], o["step"]) for o in summary["outside_pass_rule"]] == [(3, "dig")]
    ground = summary["ground_error_m"]
    assert ground["n"] == 2
    assert ground["mean"] == pytest.approx(0.002)
    assert ground["std"] == pytest.approx(math.sqrt(2) * 0.001)
    # Delivered volume over the three missions with a sample section, the top layer's share
    # over the two that ingested one.
    volume = summary["delivered_volume_m3"]
    assert (volume["n"], volume["values"]) == (3, [4.0e-4, 6.0e-4, 0.0])
    assert volume["mean"] == pytest.approx(1.0e-3 / 3)
    assert summary["top_layer_share"]["values"] == [0.5, 0.25]
    assert summary["missions_with_sample"] == 2
    assert summary["failed"] == [
        {
            "index": 3,
            "seed": 103,
            "failed_step": "stow",
            "error": "step stow (/arm/stow) failed: no plan",
            "command": "rosrun ow_mission mission /c/missions/003/mission.yaml",
            "run_dir": "/c/missions/003/2026-11-30_01-00-00",
        }
    ]


def test_report_files(tmp_path):
    config = SimpleNamespace(name="unit", seed=9, missions=4)
    summary = write_campaign_report(tmp_path, config, records())
    assert json.loads((tmp_path / "report.json").read_text())["success_rate"] == 0.75
    text = (tmp_path / "report.md").read_text()
    assert "3 succeeded, 1 failed (success rate 75.0 %)" in text
    assert "| dig | 4 |" in text
    assert "| 3 | 103 | stow | step stow (/arm/stow) failed: no plan | " in text
    assert "`rosrun ow_mission mission /c/missions/003/mission.yaml`" in text
    assert "- mission 3: `python -m ow_mission.figures /c/missions/003/2026-11-30_01-00-00`" in text
    assert "2 of 3 missions ingested a sample. Volume ingested from the dock: mean 0.000333 m³" in (
        text
    )
    assert "Share of it from the top layer, n = 2: mean 37.5 %, range [25.0, 50.0] %." in text
    assert summary["figures"] == [
        "plots/durations.png",
        "plots/energies.png",
        "plots/ground_error.png",
    ]
    for figure in summary["figures"]:
        assert (tmp_path / figure).stat().st_size > 1000
    empty = write_campaign_report(tmp_path / "empty", config, {})
    assert empty["missions_done"] == 0
    assert empty["delivered_volume_m3"] == {"n": 0, "values": []}
    assert "No mission's report has a sample section." in (tmp_path / "empty/report.md").read_text()
