"""The sample-collection mission through OceanWATERS' actions (``interface: actions``): every
step succeeds, with the same report fields as through the services; the ground found by
ArmFindSurface lies on the terrain as made."""

import json
import subprocess

import pytest
import yaml

from ow_sim_bullet.terrains import parse_terrain_spec

TERRAIN = "europa:7"
STEPS = [
    "unstow",
    "guarded_move",
    "grind",
    "dig_spoil",
    "discard_spoil",
    "grind_bottom",
    "dig_sample",
    "deliver_sample",
    "stow",
]


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    directory = tmp_path_factory.mktemp("mission_actions")
    mission = {
        "name": "mission through the actions",
        "terrain": TERRAIN,
        "interface": "actions",
        "output_dir": str(directory / "runs"),
        "renders": False,
    }
    path = directory / "mission.yaml"
    path.write_text(yaml.safe_dump(mission))
    proc = subprocess.run(
        ["rosrun", "ow_mission", "mission", str(path)],
        capture_output=True,
        text=True,
        timeout=1500,
        check=False,
    )
    output = proc.stdout + proc.stderr
    runs = sorted((directory / "runs").iterdir())
    assert len(runs) == 1, output
    return proc.returncode, output, json.loads((runs[0] / "report.json").read_text())


def test_every_step_succeeds_through_the_actions(run):
    returncode, output, report = run
    assert returncode == 0, output[-3000:]
    assert [s["step"] for s in report["steps"]] == STEPS
    for step in report["steps"]:
        assert step["success"], (step["step"], step["message"])
        assert step["sim_end_s"] > step["sim_start_s"]
        assert step["energy_wh"] > 0.0
    assert report["config"]["interface"] == "actions"
    assert report["steps"][1]["message"].startswith("ArmFindSurface:")


def test_ground_found_lies_on_the_terrain(run):
    _, _, report = run
    x, y, z = report["steps"][1]["ground_position"]
    assert report["ground_z"] == pytest.approx(z)
    assert z == pytest.approx(float(parse_terrain_spec(TERRAIN).height_at(x, y)), abs=0.005)
