"""The mission's sample (issue 38, items 4 and 5): after the delivery the mission sends
OceanWATERS' DockIngestSample, its success requires a sample ingested, and its report gives the
sample's volume, composition and the share of it from the top (irradiated) layer.

Two missions run at once, as a user runs them (``rosrun ow_mission mission <file>``, the harness
of test_mission): the default mission (the paper's procedure: the top 10 cm ground, dug out and
discarded before the sample is dug from below), and the same mission without the first trench
(``trench_depth: 0``: the sample ground and dug from the surface). The seed's reason for the two
grinds is that the top 10 cm is irradiated and poor: the second sample must have a measurably
larger share of it. The checks read the runs' bags with the ROS ``rosbag`` API, independently of
the report: the ingestion's ground truth (``/ground_truth/material_ingested``) and the last
regolith budget.
"""

from concurrent.futures import ThreadPoolExecutor

import pytest
from test_mission import Run, _default_mission, _messages, _run_mission, demo_mission, run_once

from ow_runtime.names import MATERIAL_INGESTED, REGOLITH_BUDGET

#: How much larger the top layer's share of the surface sample must be: the default mission's
#: sample is what its first dig left of the top layer plus ice from below it; the surface
#: sample is all from the top layer.
SHARE_MARGIN = 0.1


@pytest.fixture(scope="module")
def missions(tmp_path_factory) -> tuple[Run, Run]:
    """(the default mission as ``make demo`` runs it, the same without the first trench), run
    at once. The default run is the session's (test_mission's :func:`run_once`): whichever of
    the two modules asks first makes it, and the other reads it."""
    # Its sample's numbers are checked, not its figures: none drawn.
    surface = {
        **_default_mission(),
        "name": "no first grind",
        "trench_depth": 0.0,
        "figures": "none",
    }
    surface_dir = tmp_path_factory.mktemp("surface")  # here: the factory is not thread-safe
    with ThreadPoolExecutor(max_workers=2) as pool:
        runs = [
            pool.submit(run_once, tmp_path_factory, **demo_mission()),
            pool.submit(_run_mission, surface_dir, **surface),
        ]
        return runs[0].result(), runs[1].result()


def _last(run: Run, topic: str):
    messages = [msg for msg, _ in _messages(run.bags, topic)]
    assert messages, f"{topic} is not in the bags of {run.run_dir}"
    return messages[-1]


def test_the_default_mission_ingests_a_sample_and_reports_it(missions):
    run, _ = missions
    assert run.returncode == 0, run.output
    report = run.report
    assert report["success"], report["error"]
    ingestion = report["ingestion"]
    assert (ingestion["sample_ingested"], ingestion["message"]) == (True, "Sample ingested")
    delivered = next(s for s in report["steps"] if s["step"] == "deliver_sample")
    assert ingestion["sim_time_s"] == pytest.approx(delivered["sim_end_s"])
    sample = report["sample"]
    assert sample["ingested"] and sample["volume_m3"] > 0.0
    # The ground truth OceanWATERS publishes for the ingestion, read from the bags.
    truth = _last(run, MATERIAL_INGESTED)
    assert truth.volume == pytest.approx(sample["volume_m3"], rel=1e-12)
    assert {c.name: c.proportion for c in truth.composition} == pytest.approx(
        sample["composition"], abs=1e-6
    )
    # The budget: what was ingested is no longer in the dock, and it came from the terrain.
    budget = _last(run, REGOLITH_BUDGET)
    assert budget.ingested.volume == pytest.approx(sample["volume_m3"], rel=1e-12)
    assert budget.in_dock.volume_um3 == 0
    assert budget.excavated.volume_um3 == sum(
        getattr(budget, a).volume_um3
        for a in ("in_scoop", "in_dock", "ingested", "spilled", "deposited")
    )
    top = budget.layers.index(budget.top_layer)
    assert sample["top_layer_share"] == pytest.approx(
        budget.ingested.layer_volumes[top] / budget.ingested.volume
    )
    text = (run.run_dir / "report.md").read_text()
    assert "## Sample" in text and f"from the top layer `{budget.top_layer}`" in text
    assert "sample: ingested (DockIngestSample: Sample ingested)" in run.output


def test_skipping_the_first_grind_samples_more_of_the_irradiated_top_layer(missions):
    default, surface = missions
    assert surface.returncode == 0, surface.output
    report = surface.report
    assert report["success"], report["error"]
    assert [s["step"] for s in report["steps"]] == [
        "unstow",
        "guarded_move",
        "grind_bottom",
        "dig_sample",
        "deliver_sample",
        "stow",
    ]
    surface_share = report["sample"]["top_layer_share"]
    default_share = default.report["sample"]["top_layer_share"]
    # Ground and dug 5 cm each from the surface: all of it from the 10 cm top layer.
    assert surface_share == pytest.approx(1.0, abs=1e-9)
    assert surface_share > default_share + SHARE_MARGIN, (surface_share, default_share)
