"""The mission report's regolith figure (ow_mission.regolith_plot): the numbers it is drawn from,
on budgets made here with the generated ow_msgs classes, and the report's regolith.png."""

from __future__ import annotations

from pathlib import Path

import matplotlib
import numpy as np
import pytest
from PIL import Image
from test_report import (
    JOINTS,
    SEGMENTS,
    START_S,
    _document,
    _flat,
    _put_budget,
    _put_terrain,
    _trenched,
    _write_bags,
)

from ow_mission.errors import ReplayError
from ow_mission.regolith_plot import PARTS, plot_regolith, regolith_series
from ow_mission.report import write_run_report
from ow_mission.report_files import image_links
from ow_msgs.msg import RegolithAccount, RegolithBudget
from ow_power.bagwriter import SplitBagWriter
from ow_power.synthetic import BagMessages, write_run

LAYERS = ["irradiated", "pristine"]
#: (step, start s, end s): the steps of a mission that digs, pours and ingests.
WINDOWS = [
    ("unstow", 0.0, 10.0),
    ("dig", 10.0, 20.0),
    ("deliver", 20.0, 30.0),
    ("stow", 30.0, 40.0),
]
#: µm³: the regolith an irradiated cut takes, and what of it is poured where.
CUT = 670_000_000_000_123
IN_DOCK, SPILLED = 640_000_000_000_007, 88_000_001


def _account(um3: int, by_layer: tuple[float, float] = (1.0, 0.0)) -> RegolithAccount:
    """An account of ``um3`` µm³, ``by_layer`` the shares of LAYERS."""
    volume = um3 * 1e-18
    return RegolithAccount(
        volume=volume,
        volume_um3=um3,
        mass=997.0 * volume,
        layer_volumes=[share * volume for share in by_layer],
        material_volumes=[volume],
    )


def _budget(
    in_scoop: int = 0,
    in_dock: int = 0,
    ingested: int = 0,
    spilled: int = 0,
    deposited: int = 0,
    excavated: int | None = None,
) -> RegolithBudget:
    """A budget of these µm³ (excavated: their sum unless given); the ingested sample a third
    from the top layer, all that was excavated from it."""
    parts = in_scoop + in_dock + ingested + spilled + deposited
    return RegolithBudget(
        layers=LAYERS,
        top_layer=LAYERS[0],
        materials=["ICE"],
        excavated=_account(parts if excavated is None else excavated),
        in_scoop=_account(in_scoop),
        in_dock=_account(in_dock),
        ingested=_account(ingested, (1 / 3, 2 / 3)),
        spilled=_account(spilled),
        deposited=_account(deposited),
    )


def _mission() -> list[tuple[int, RegolithBudget]]:
    """(bag time ns, budget) of a dig, a pour (dock, lander, terrain) and an ingestion."""
    rest = CUT - IN_DOCK - SPILLED
    return [
        (0, _budget()),
        (12_500_000_000, _budget(in_scoop=CUT)),
        (22_000_000_000, _budget(in_scoop=CUT - IN_DOCK, in_dock=IN_DOCK)),
        (23_000_000_000, _budget(in_dock=IN_DOCK, spilled=SPILLED, deposited=rest)),
        (31_000_000_000, _budget(ingested=IN_DOCK, spilled=SPILLED, deposited=rest)),
    ]


def test_the_stack_of_the_parts_is_the_excavated_volume_to_the_um3_in_every_budget():
    series = regolith_series(_mission(), WINDOWS)
    assert series.parts_um3.shape == (len(PARTS), 5)
    assert series.tops_um3[-1].tolist() == [0, CUT, CUT, CUT, CUT]
    assert np.array_equal(series.tops_um3[-1], series.excavated_um3)
    assert series.unbalanced == 0
    # the bands in the budget's order: at the end all in the dock was ingested
    assert series.parts_um3[:, -1].tolist() == [0, 0, IN_DOCK, SPILLED, CUT - IN_DOCK - SPILLED]
    assert series.final_cm3("excavated") == pytest.approx(CUT * 1e-12)
    assert series.final_cm3("ingested") == pytest.approx(640.0)


def test_a_budget_whose_parts_miss_one_um3_is_counted_as_not_closing():
    budgets = _mission()
    budgets[2] = (
        budgets[2][0],
        _budget(in_scoop=CUT - IN_DOCK, in_dock=IN_DOCK, excavated=CUT + 1),
    )
    assert regolith_series(budgets, WINDOWS).unbalanced == 1


@pytest.mark.parametrize(
    ("windows", "end_s"),
    [
        (WINDOWS, 40.0),  # the last budget held to the end of the last step
        (WINDOWS[:3], 31.0),  # a budget after the steps ends the axis
        ([], 31.0),
    ],
)
def test_the_steps_and_the_time_axis_come_from_the_windows_and_the_bag_times(windows, end_s):
    series = regolith_series(_mission(), windows)
    assert series.windows == windows
    assert series.t_s == pytest.approx([0.0, 12.5, 22.0, 23.0, 31.0])
    assert series.end_s == pytest.approx(end_s)


def test_the_layer_shares_are_those_of_the_last_budget_and_none_when_empty():
    series = regolith_series(_mission(), WINDOWS)
    assert series.top_layer == "irradiated"
    assert series.layer_shares("ingested") == pytest.approx(
        {"irradiated": 1 / 3, "pristine": 2 / 3}
    )
    assert series.layer_shares("excavated") == pytest.approx({"irradiated": 1.0, "pristine": 0.0})
    nothing = regolith_series(_mission()[:4], WINDOWS)
    assert nothing.layer_shares("ingested") is None


def test_no_budget_is_an_error_naming_the_topic():
    with pytest.raises(ReplayError, match=r"^no /regolith/budget message: no regolith figure$"):
        regolith_series([], WINDOWS)


@pytest.mark.parametrize(
    ("budgets", "size"),
    [
        (_mission(), (1320, 550)),  # with the panel of the layers
        (_mission()[:1], (990, 550)),  # nothing excavated: the accounts alone
    ],
)
def test_the_figure_is_drawn(tmp_path, monkeypatch, budgets, size):
    # At its own size whatever matplotlib's savefig default is: progpy.visualize sets it to 300
    # dpi when imported (a test process that imported it drew 3600 x 1500).
    monkeypatch.setitem(matplotlib.rcParams, "savefig.dpi", 300)
    png = tmp_path / "regolith.png"
    plot_regolith(regolith_series(budgets, WINDOWS), png)
    with Image.open(png) as image:
        assert image.size == size
        pixels = np.asarray(image.convert("RGB"))
    assert len(np.unique(pixels.reshape(-1, 3), axis=0)) > 50  # drawn, not blank
    assert png.stat().st_size > 20_000


# ------------------------------------------------------------------- in the mission report
def _budget_run(directory: Path) -> None:
    """Synthetic bags with a trench and two budgets, 8e-4 of the 1.3e-3 m^3 excavated ingested
    at the end (test_report's sample run)."""
    writer = SplitBagWriter(directory / "bags", split_duration_s=4.0)
    messages = BagMessages()
    _put_terrain(writer, messages, START_S, _flat())
    end = write_run(writer, SEGMENTS, JOINTS, start_s=START_S)
    _put_terrain(writer, messages, end, _trenched(0.16))
    _put_budget(writer, messages, START_S, (0.0, 0.0))
    _put_budget(writer, messages, end, (2.0e-4, 6.0e-4))
    writer.close()


def test_the_report_draws_the_regolith_figure_after_the_trench_profile(tmp_path):
    _budget_run(tmp_path)
    document = write_run_report(tmp_path, _document(), renders=False)
    assert list(document["figures"])[:3] == ["power", "trench_profile", "regolith"]
    assert (tmp_path / "regolith.png").is_file()
    assert "regolith" not in document["figure_notes"]
    markdown = (tmp_path / "report.md").read_text()
    assert "regolith.png" in image_links(markdown)
    assert "the stack's top equals it to the µm³ in every budget: the budget closes" in markdown
    assert "1300 cm³ excavated, 800 cm³ ingested" in markdown


def test_the_numbers_alone_draw_no_regolith_figure_and_note_none(tmp_path):
    _budget_run(tmp_path)
    document = write_run_report(tmp_path, _document(), renders=False, draw=False)
    assert "regolith" not in document["figures"]
    assert "regolith" not in document["figure_notes"]
    assert not (tmp_path / "regolith.png").exists()


def test_a_report_without_budgets_has_a_note_and_no_regolith_figure(tmp_path):
    _write_bags(tmp_path / "bags")
    document = write_run_report(tmp_path, _document(), renders=False)
    note = "no /regolith/budget in the bags: no regolith figure."
    assert document["figure_notes"]["regolith"] == note
    assert "regolith" not in document["figures"]
    assert not (tmp_path / "regolith.png").exists()
    assert f"> {note}" in (tmp_path / "report.md").read_text()
