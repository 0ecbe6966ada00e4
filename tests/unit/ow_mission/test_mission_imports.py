"""What a mission and its report import (no ROS in the check itself: a fresh interpreter per
case). ``rosrun ow_mission mission`` starts the nodes first and imports its ROS side while they
import theirs: a heavy import on the start's path delays every mission. The report and its
figures plan nothing: pinocchio and OMPL there cost memory (their libraries' pages) and time."""

import subprocess
import sys

import pytest

#: Modules the start must not import: rospy and what it pulls in, the planners' libraries, the
#: report's drawing.
HEAVY = ("rospy", "genpy", "actionlib", "pinocchio", "ompl", "pybullet", "pandas", "matplotlib")
#: The planners' libraries.
PLANNERS = ("pinocchio", "ompl")


def _imported(*modules: str) -> set[str]:
    code = f"import sys, {', '.join(modules)}; print(' '.join(sys.modules))"
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=60
    )
    return set(out.stdout.split())


@pytest.mark.parametrize(
    "module",
    [
        "ow_mission.mission_node",
        "ow_mission.mission_config",
        "ow_mission.figures",  # bench/mission.py's: it must not share the stack's pages
        "ow_lander.telemetry_config",
        "ow_lander.workspace",
    ],
)
def test_the_missions_start_imports_nothing_heavy(module):
    imported = _imported(module)
    assert not [name for name in HEAVY if name in imported]


def test_the_mission_and_its_report_import_no_planner():
    imported = _imported(
        "ow_mission.mission_session_node",
        "ow_mission.report",
        "ow_mission.plots",
        "ow_mission.fault_report",
        "ow_power.analysis",
    )
    assert "rospy" in imported  # the check sees what is imported
    assert not [name for name in PLANNERS if name in imported]
