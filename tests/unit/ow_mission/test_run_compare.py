"""Whether two runs are the same run (ow_mission.run_compare), on bags written in tmp_path."""

from __future__ import annotations

import io
import json
from pathlib import Path

import genpy

from ow_mission.run_compare import differences
from ow_power.bagwriter import SplitBagWriter
from owl_msgs.msg import ArmFaultsStatus

TOPIC = "/arm_faults_status"


def _run(directory: Path, statuses: list[tuple[int, float, int]]) -> Path:
    """A run directory whose bag holds ``statuses``: (header seq, stamp s, value), latched."""
    (directory / "bags").mkdir(parents=True)
    (directory / "report.json").write_text(json.dumps({"sim_time_s": 1.0}))
    bags = SplitBagWriter(directory / "bags", prefix="run")
    for seq, stamp_s, value in statuses:
        msg = ArmFaultsStatus(value=value)
        msg.header.stamp = genpy.Time.from_sec(stamp_s)
        msg.header.frame_id = "world"
        buffer = io.BytesIO()
        msg.header.seq = seq
        msg.serialize(buffer)
        bags.write(
            TOPIC,
            msg._type,
            msg._md5sum,
            msg._full_text,
            int(stamp_s * 1e9) or 1,
            buffer.getvalue(),
            latching=True,
        )
    bags.close()
    return directory


def test_runs_that_differ_only_in_header_seq_are_the_same_run(tmp_path: Path):
    # rospy numbers a latched message again for each subscriber that connects: a recorder that
    # connected second gets seq 2 for the same message.
    a = _run(tmp_path / "a", [(1, 0.0, 0), (3, 39.81, 1)])
    b = _run(tmp_path / "b", [(2, 0.0, 0), (4, 39.81, 1)])
    assert differences(a, b, [TOPIC]) == []


def test_a_different_stamp_or_value_is_a_different_run(tmp_path: Path):
    a = _run(tmp_path / "a", [(1, 0.0, 0), (2, 39.81, 1)])
    stamp = _run(tmp_path / "stamp", [(1, 0.0, 0), (2, 39.82, 1)])
    value = _run(tmp_path / "value", [(1, 0.0, 0), (2, 39.81, 3)])
    assert differences(a, stamp, [TOPIC]) == [f"{TOPIC}: message 1 differs"]
    assert differences(a, value, [TOPIC]) == [f"{TOPIC}: message 1 differs"]


def test_a_run_is_the_same_before_and_after_its_figures_are_drawn(tmp_path: Path):
    """The figures are made from the bags after the run: the numbers they add (the replay's
    frames) and the wall-clock ones are no part of the run; any other number is."""
    a = _run(tmp_path / "a", [(1, 0.0, 0)])
    b = _run(tmp_path / "b", [(1, 0.0, 0)])
    drawn = {"sim_time_s": 1.0, "replay": {"frames": 40, "fps": 8.0}, "figures_seconds": 3.2}
    (b / "report.json").write_text(json.dumps(drawn))
    assert differences(a, b, [TOPIC]) == []
    (b / "report.json").write_text(json.dumps({**drawn, "sim_time_s": 1.01}))
    assert differences(a, b, [TOPIC]) == ["report.sim_time_s: 1.0 != 1.01"]
