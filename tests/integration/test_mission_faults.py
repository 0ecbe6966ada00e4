"""A mission file with a fault schedule (issue 15): ``rosrun ow_mission mission <file>`` locks
j_shou_pitch 3 s into the grind; the grind fails naming the joint, the mission ends with a report
whose faults section names the fault and when it was detected, and every bag is readable.

The detection time is checked against the bags read with the ROS ``rosbag`` API: the
detector's first HARDWARE stamp, and the simulation's first /flags/joint_states flag of the joint.
The mission runs once per module (flat ground, renders off).
"""

import subprocess

import pytest
import rosbag
from test_mission import _run_mission

AFTER_S = 3.0  # s of sim time into the grind


@pytest.fixture(scope="module")
def faulted(tmp_path_factory):
    return _run_mission(
        tmp_path_factory.mktemp("faulted"),
        name="faulted",
        terrain="flat:-0.155",
        faults=[
            {
                "at_step": "grind",
                "after_s": AFTER_S,
                "set": {"shou_pitch_joint_locked_failure": True},
            }
        ],
    )


def _first(bags, topic, hit):
    """Header stamp (s) of the first message of ``topic`` for which ``hit(msg)`` holds."""
    for path in bags:
        with rosbag.Bag(str(path)) as bag:
            for _, msg, _ in bag.read_messages(topics=[topic]):
                if hit(msg):
                    return msg.header.stamp.to_sec()
    return None


def test_the_grind_fails_naming_the_locked_joint(faulted):
    assert faulted.returncode == 1, faulted.output
    report = faulted.report
    assert report["failed_step"] == "grind"
    assert [s["step"] for s in report["steps"]] == ["unstow", "guarded_move", "grind"]
    message = faulted.step("grind")["message"]
    assert "j_shou_pitch locked (HARDWARE)" in message
    assert report["faults"]["ended"]["failed_step"] == "grind"


def test_the_fault_is_applied_at_its_time_and_its_detection_is_the_bags(faulted):
    grind = faulted.step("grind")
    (applied,) = faulted.report["fault_schedule"]
    assert applied["error"] == ""
    assert applied["due_s"] == pytest.approx(grind["sim_start_s"] + AFTER_S)
    assert applied["due_s"] <= applied["applied_s"] < grind["sim_end_s"]
    detections = {(d["topic"], d["name"]): d for d in faulted.report["faults"]["detections"]}
    hardware = detections[("/arm_faults_status", "HARDWARE")]
    assert ("/system_faults_status", "ARM_EXECUTION_ERROR") in detections
    from_bags = _first(faulted.bags, "/arm_faults_status", lambda m: m.value & 1)
    assert hardware["set_s"] == pytest.approx(from_bags, abs=1e-6)
    flagged = _first(
        faulted.bags,
        "/flags/joint_states",
        lambda m: m.flags[list(m.name).index("j_shou_pitch")],
    )
    assert flagged is not None and applied["due_s"] <= flagged <= grind["sim_end_s"]
    # The detector takes every flag message: its HARDWARE stamp is the first flag's.
    assert hardware["set_s"] == pytest.approx(flagged, abs=1e-6)


def test_the_report_names_the_fault_its_detection_and_the_battery(faulted):
    md = (faulted.run_dir / "report.md").read_text()
    faults = faulted.report["faults"]
    hardware = next(d for d in faults["detections"] if d["name"] == "HARDWARE")
    assert "## Faults" in md
    assert "shou_pitch_joint_locked_failure: true at grind + 3 s" in md
    assert f"| `/arm_faults_status` | HARDWARE (1) | {hardware['set_s']:.2f} |" in md
    assert "step **grind** failed" in md and "j_shou_pitch" in md
    assert "battery.png" in faulted.report["figures"].values()
    assert 0 < faults["end"]["soc"] < faults["end"]["soc_start"]
    assert faults["end"]["rul_s"] > 0


def test_every_bag_is_readable(faulted):
    assert list((faulted.run_dir / "bags").glob("*.active")) == []
    assert faulted.bags
    for path in faulted.bags:
        info = subprocess.run(["rosbag", "info", str(path)], capture_output=True, text=True)
        assert info.returncode == 0, info.stderr
