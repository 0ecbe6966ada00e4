"""The report's faults section and battery figure (ow_mission.fault_report) from hand-made bags."""

from __future__ import annotations

from datetime import datetime
from pathlib import Path

import pytest
from rosbags.typesys import get_types_from_msg

from ow_mission.fault_report import (
    FaultRecording,
    FaultReportError,
    bit_names,
    detections,
    fault_summary,
    markdown_lines,
    read_fault_recording,
)
from ow_mission.report import write_run_report
from ow_mission.report_files import image_links
from ow_power.bagwriter import SplitBagWriter
from ow_power.synthetic import BagMessages, ow_typestore
from owl_msgs.msg import ArmFaultsStatus, SystemFaultsStatus

OWL_MSGS_DIR = Path(__file__).resolve().parents[3] / "src" / "owl_msgs" / "msg"
TYPES = {
    "/arm_faults_status": "ArmFaultsStatus",
    "/system_faults_status": "SystemFaultsStatus",
    "/battery_state_of_charge": "BatteryStateOfCharge",
    "/battery_remaining_useful_life": "BatteryRemainingUsefulLife",
}
APPLIED_S = 43.4
HARDWARE_S = 43.6  # the detector's stamp of the first flagged joint
STEPS = [
    ("unstow", 0.0, 17.0, True),
    ("guarded_move", 17.0, 40.0, True),
    ("grind", 40.0, 44.5, False),
]
FAILED = "arm execution error: j_shou_pitch locked (HARDWARE)"


def _messages() -> BagMessages:
    store = ow_typestore()
    for name in sorted(set(TYPES.values())):
        text = (OWL_MSGS_DIR / f"{name}.msg").read_text()
        store.register(get_types_from_msg(text, f"owl_msgs/msg/{name}"))
    return BagMessages(store)


def _write_bags(directory: Path, battery: bool = True) -> list[Path]:
    """Status as the detector publishes it (a latched zero at stamp 0, the lock, its release);
    SOC and RUL at 1 Hz."""
    writer = SplitBagWriter(directory, split_duration_s=20.0, start=datetime(2025, 1, 2, 3, 4, 5))
    messages = _messages()

    def put(topic: str, t_s: float, value: float, stamp_s: float | None = None) -> None:
        stamp = round((t_s if stamp_s is None else stamp_s) * 1e9)
        ros1_type, md5, msgdef, data = messages.serialize(
            f"owl_msgs/msg/{TYPES[topic]}", header=messages.header(stamp, "world"), value=value
        )
        writer.write(topic, ros1_type, md5, msgdef, round(t_s * 1e9), data)

    put("/arm_faults_status", 0.1, 0, stamp_s=0.0)
    put("/system_faults_status", 0.1, 0, stamp_s=0.0)
    if battery:
        for k in range(45):
            put("/battery_state_of_charge", float(k), 0.95 - 1e-4 * k)
            put("/battery_remaining_useful_life", float(k), 39000 - 10 * k)
    put("/arm_faults_status", HARDWARE_S, ArmFaultsStatus.HARDWARE)
    put("/system_faults_status", HARDWARE_S, SystemFaultsStatus.ARM_EXECUTION_ERROR)
    put("/system_faults_status", 44.0, 6)  # + ARM_GOAL_ERROR: the grind's goal aborted
    put("/arm_faults_status", 44.4, 0)
    return writer.close()


def _document() -> dict:
    steps = [
        {
            "step": name,
            "service": f"/arm/{name}",
            "request": {},
            "success": ok,
            "message": "done" if ok else FAILED,
            "planning_time_s": 0.01,
            "wall_time_s": 0.1,
            "sim_start_s": start,
            "sim_end_s": end,
            "mechanical_energy_j": 10.0,
            "energy_wh": 0.1,
            "peak_power_w": 40.0,
        }
        for name, start, end, ok in STEPS
    ]
    return {
        "success": False,
        "error": f"step grind (/arm/grind) failed: {FAILED}",
        "failed_step": "grind",
        "wall_time_s": 5.0,
        "sim_time_s": 44.5,
        "real_time_factor": 8.9,
        "peak_memory_mb": 1.0,
        "ground_z": -0.155,
        "config": {"name": "faulted", "terrain": "flat:-0.155", "x": 1.65, "y": 0.0},
        "steps": steps,
        "fault_schedule": [
            {
                "index": 0,
                "description": "shou_pitch_joint_locked_failure: true at grind + 3.4 s",
                "changes": {"shou_pitch_joint_locked_failure": True},
                "due_s": APPLIED_S,
                "applied_s": APPLIED_S,
                "error": "",
            },
            {
                "index": 1,
                "description": "high_power_draw: 200.0 at stow + 0 s",
                "changes": {"high_power_draw": 200.0},
                "due_s": None,
                "applied_s": None,
                "error": "",
            },
        ],
    }


def test_bit_names_come_from_the_messages_constants():
    assert bit_names(ArmFaultsStatus)[1] == "HARDWARE"
    assert bit_names(ArmFaultsStatus)[128] == "NO_FORCE_DATA"
    assert 0 not in bit_names(SystemFaultsStatus)
    assert bit_names(SystemFaultsStatus)[4] == "ARM_EXECUTION_ERROR"


def test_detections_are_the_first_stamp_each_bit_was_set_and_when_it_cleared(tmp_path):
    recording = read_fault_recording(_write_bags(tmp_path / "bags"))
    found = [(d.topic, d.name, d.set_s, d.cleared_s) for d in detections(recording)]
    assert found == [
        ("/arm_faults_status", "HARDWARE", pytest.approx(HARDWARE_S), pytest.approx(44.4)),
        ("/system_faults_status", "ARM_EXECUTION_ERROR", pytest.approx(HARDWARE_S), None),
        ("/system_faults_status", "ARM_GOAL_ERROR", pytest.approx(44.0), None),
    ]


def test_an_unreadable_bag_is_an_error_naming_it(tmp_path):
    bags = _write_bags(tmp_path / "bags")
    junk = tmp_path / "bags" / "junk.bag"
    junk.write_bytes(b"not a bag")
    with pytest.raises(FaultReportError, match=r"cannot read .*junk\.bag"):
        read_fault_recording([*bags, junk])


def test_the_summary_names_the_fault_its_detection_the_failed_step_and_the_end(tmp_path):
    recording = read_fault_recording(_write_bags(tmp_path / "bags"))
    faults = fault_summary(_document(), recording)
    hardware = faults["detections"][0]
    assert hardware["name"] == "HARDWARE"
    assert hardware["after_injection_s"] == pytest.approx(HARDWARE_S - APPLIED_S)
    assert faults["ended"] == {
        "success": False,
        "failed_step": "grind",
        "message": FAILED,
        "error": f"step grind (/arm/grind) failed: {FAILED}",
    }
    end = faults["end"]
    assert end["energy_wh"] == pytest.approx(0.3)
    assert end["mechanical_energy_j"] == pytest.approx(30.0)
    assert end["soc_start"] == pytest.approx(0.95)
    assert end["soc"] == pytest.approx(0.95 - 44e-4)
    assert end["rul_s"] == 39000 - 440
    text = "\n".join(markdown_lines(faults))
    assert (
        "| shou_pitch_joint_locked_failure: true at grind + 3.4 s | 43.40 | 43.40 | applied |"
        in (text)
    )
    assert "not applied: the mission ended first" in text
    assert "| `/arm_faults_status` | HARDWARE (1) | 43.60 | 0.20 | 44.40 |" in text
    assert f"step **grind** failed: {FAILED}" in text
    assert "state of charge 0.9456 (at the start 0.9500)" in text


def test_a_run_without_faults_says_so():
    document = {**_document(), "fault_schedule": [], "success": True, "error": ""}
    for step in document["steps"]:
        step["success"] = True
    text = "\n".join(markdown_lines(fault_summary(document, FaultRecording())))
    assert "No fault was scheduled" in text
    assert "No fault bit was set on any status topic." in text
    assert "Ended: every step succeeded." in text
    assert "state of charge - (at the start -)" in text


def test_the_report_has_the_faults_section_and_links_the_battery_figure(tmp_path):
    _write_bags(tmp_path / "bags")
    document = write_run_report(tmp_path, _document(), renders=False)
    md = (tmp_path / "report.md").read_text()
    assert "## Faults" in md and "HARDWARE (1)" in md
    assert "battery.png" in image_links(md)
    assert (tmp_path / "battery.png").stat().st_size > 10_000
    assert document["faults"]["detections"][0]["name"] == "HARDWARE"
    assert "battery" not in document["figure_notes"]


def test_missing_battery_data_gives_a_note_not_a_crash(tmp_path):
    _write_bags(tmp_path / "bags", battery=False)
    document = write_run_report(tmp_path, _document(), renders=False)
    md = (tmp_path / "report.md").read_text()
    assert "battery.png" not in image_links(md)
    assert "no /battery_state_of_charge or /battery_remaining_useful_life" in md
    assert "## Faults" in md and "HARDWARE (1)" in md
    assert document["faults"]["end"]["soc"] is None
