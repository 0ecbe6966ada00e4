"""The report of a real mission (``rosrun ow_mission mission <file>``, renders on) run through
OceanWATERS' actions (``interface: actions``): every step succeeds through the actions, the ground
ArmFindSurface found lies on the terrain as made; every image the report links exists, its energies
are the power plot's, the figures made from the bags are there and say what the run did. One
mission run for the whole module (the services' mission is test_mission's)."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path
from typing import Any

import pytest
import yaml
from PIL import Image
from test_mission import STEPS

from ow_mission.report import image_links
from ow_sim_bullet.terrains import parse_terrain_spec

MISSION_TIMEOUT_S = 1200.0  # a hang fails the test instead of blocking the suite
TERRAIN = "europa:7"


@pytest.fixture(scope="module")
def run(tmp_path_factory) -> tuple[int, str, Path, dict[str, Any]]:
    """The default procedure on europa:7 through the actions, renders on, run once."""
    directory = tmp_path_factory.mktemp("report")
    path = directory / "mission.yaml"
    mission = {
        "name": "report test",
        "terrain": TERRAIN,
        "interface": "actions",
        "output_dir": str(directory / "runs"),
    }
    path.write_text(yaml.safe_dump(mission))
    proc = subprocess.run(
        ["rosrun", "ow_mission", "mission", str(path)],
        capture_output=True,
        text=True,
        timeout=MISSION_TIMEOUT_S,
        check=False,
    )
    output = proc.stdout + proc.stderr
    runs = sorted((directory / "runs").iterdir())
    assert len(runs) == 1, output
    report = json.loads((runs[0] / "report.json").read_text())
    return proc.returncode, output, runs[0], report


def test_the_mission_succeeds_and_every_linked_image_exists(run):
    returncode, output, run_dir, report = run
    assert returncode == 0, output
    links = image_links((run_dir / "report.md").read_text())
    for link in links:
        assert (run_dir / link).is_file(), link
    for role in ("power", "trench_profile", "guarded_move", "replay"):
        assert role in report["figures"], report.get("figure_notes")
        assert report["figures"][role] in links
    stills = [f for role, f in report["figures"].items() if role.startswith("still_")]
    assert len(stills) == 4
    for still in stills:
        with Image.open(run_dir / still) as image:
            assert image.size == (1024, 768)
    assert report["figure_notes"] == {}


def test_the_tables_energies_are_the_plots_labels(run):
    _, _, run_dir, report = run
    markdown = (run_dir / "report.md").read_text()
    for step in report["steps"]:
        _, signed, absolute = step["power_plot_label"].split("\n")
        row = next(line for line in markdown.splitlines() if line.startswith(f"| {step['step']} "))
        cells = [c.strip() for c in row.strip("|").split("|")]
        assert f"{cells[4]} J signed" == signed
        assert f"{cells[5]} J |.|" == absolute
        assert step["mechanical_energy_abs_j"] >= abs(step["mechanical_energy_j"]) - 1e-9
        assert step["peak_power_w"] > step["peak_mechanical_power_w"]  # with P0 and without


def test_the_dig_reached_the_requested_depth(run):
    _, _, run_dir, report = run
    assert report["trench"]["worked"], report["trench"]["verdict"]
    assert "The dig worked" in (run_dir / "report.md").read_text()


def test_the_detector_figure_finds_the_contact_the_arm_reported(run):
    _, _, _, report = run
    detector = report["guarded_move_detector"]
    assert detector["contact_s"] is not None
    assert detector["contact_s"] == pytest.approx(detector["result_s"], abs=0.1), detector


def test_the_replay_runs_at_ten_frames_per_second_or_more(run):
    _, _, run_dir, report = run
    replay = report["replay"]
    with Image.open(run_dir / replay["file"]) as gif:
        assert gif.n_frames == replay["frames"] >= 100
        assert gif.info["duration"] <= 100  # ms per frame


def test_every_step_succeeds_through_the_actions(run):
    returncode, output, _, report = run
    assert returncode == 0, output[-3000:]
    assert [s["step"] for s in report["steps"]] == STEPS
    for step in report["steps"]:
        assert step["success"], (step["step"], step["message"])
        assert step["sim_end_s"] > step["sim_start_s"]
        assert step["energy_wh"] > 0.0
    assert report["config"]["interface"] == "actions"
    assert report["steps"][1]["message"].startswith("ArmFindSurface:")


def test_ground_found_lies_on_the_terrain(run):
    _, _, _, report = run
    x, y, z = report["steps"][1]["ground_position"]
    assert report["ground_z"] == pytest.approx(z)
    assert z == pytest.approx(float(parse_terrain_spec(TERRAIN).height_at(x, y)), abs=0.005)
