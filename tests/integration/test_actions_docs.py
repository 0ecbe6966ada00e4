"""The client of docs/actions.md, run as written against the simulation on flat ground: the
paper's sample collection through the actions, one grind cancelled half-way, every other goal
succeeding (the client stops with the failing goal's text otherwise)."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

from ow_description.description import DEFAULT_GROUND_Z

DOCS = Path(__file__).resolve().parents[2] / "docs" / "actions.md"


def _client_code() -> str:
    text = DOCS.read_text()
    section = text[text.index("## A client: the paper's sample collection") :]
    match = re.search(r"```python\n(.*?)```", section, re.S)
    assert match, "no python block in the client section of docs/actions.md"
    return match.group(1)


@pytest.fixture(scope="module")
def output(start_lander, tmp_path_factory):
    stack = start_lander()
    script = tmp_path_factory.mktemp("docs") / "collect.py"
    script.write_text(_client_code())
    proc = subprocess.run(
        [sys.executable, str(script)],
        env=stack.master.env,
        capture_output=True,
        text=True,
        timeout=900,
        check=False,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr[-3000:]
    return proc.stdout


def test_every_goal_succeeds_but_the_cancelled_grind(output):
    lines = output.splitlines()
    assert lines.count("TaskGrind: cancelled half-way") == 1
    assert lines.count("TaskGrind: succeeded") == 2
    assert lines.count("TaskScoopLinear: succeeded") == 2
    for name in ("TaskDiscardSample", "TaskDeliverSample", "ArmFindSurface", "ArmStow"):
        assert f"{name}: succeeded" in lines, name
    assert lines[-1] == "ArmStow: succeeded"


def test_the_surface_is_the_flat_ground(output):
    z = float(re.search(r"surface at z = (-?[0-9.]+) m", output).group(1))
    assert z == pytest.approx(DEFAULT_GROUND_Z, abs=0.005)
