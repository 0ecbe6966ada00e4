"""What the mission, its report and its bench import (no ROS in the check itself: a fresh
interpreter per case). The report and its figures plan nothing: pinocchio and OMPL there cost
memory (their libraries' pages) and CPU. bench/mission.py must not import what the stack it
measures maps: a page both map is split between their PSS, and the bench's part is not counted
(it once imported pinocchio through the mission's configuration: the stack's sum ~20 MB short).
"""

import subprocess
import sys

#: Modules the mission's configuration and the bench must not import.
HEAVY = ("rospy", "genpy", "actionlib", "pinocchio", "ompl", "pybullet", "pandas", "matplotlib")
#: The planners' libraries.
PLANNERS = ("pinocchio", "ompl")


def _imported(*modules: str) -> set[str]:
    code = f"import sys, {', '.join(modules)}; print(' '.join(sys.modules))"
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=60
    )
    return set(out.stdout.split())


def test_the_configuration_and_the_bench_import_nothing_heavy():
    imported = _imported(
        "ow_mission.mission_config",
        "ow_mission.figures",  # bench/mission.py's imports
        "ow_lander.telemetry.config",
        "ow_lander.operations.workspace",
    )
    assert not [name for name in HEAVY if name in imported]


def test_the_mission_and_its_report_import_no_planner():
    imported = _imported(
        "ow_mission.mission_node",
        "ow_mission.report",
        "ow_mission.plots",
        "ow_mission.fault_report",
        "ow_power.analysis",
    )
    assert "rospy" in imported  # the check sees what is imported
    assert not [name for name in PLANNERS if name in imported]
