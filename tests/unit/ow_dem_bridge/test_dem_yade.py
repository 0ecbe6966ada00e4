"""A YADE smoke run: a few hundred large spheres, a short scoop dig, the whole table pipeline."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from ow_dem_bridge.make_tables import read_samples, regenerate, smoke_scenario
from ow_dem_bridge.table import load_table

pytestmark = [
    pytest.mark.yade,
    pytest.mark.skipif(
        shutil.which("yade") is None,
        reason="YADE is not installed: apt-get install yade (make setup installs it)",
    ),
]


def test_smoke_regeneration_writes_a_table_that_resists_the_dig(tmp_path: Path) -> None:
    scenario = smoke_scenario()
    out = tmp_path / "smoke.csv"
    record = regenerate(scenario, out, tmp_path / "work", workers=1, plot=None)

    table = load_table(out)
    depth = scenario.scoop_depths[0]
    assert table.tools == ("scoop",)
    assert table.depths("scoop", 1) == (depth,)
    assert json.loads(out.with_suffix(".json").read_text())["runs"].keys() == record["runs"].keys()

    dig = record["runs"][f"dig_scoop_m1_d{depth * 1000:.0f}mm"]
    assert dig["max_depth"] == pytest.approx(depth, abs=1e-3)  # the cut never goes deeper
    assert dig["progress"] > scenario.scoop_motion["linear_length"]
    progress, wrench = read_samples(tmp_path / "work" / f"dig_scoop_m1_d{depth * 1000:.0f}mm.csv")
    assert progress.size > 10 and np.all(np.diff(progress) >= 0)
    # Averaged over the dig, the sand pushes back against the cutting edge (link -x).
    assert wrench[:, 0].mean() < 0
