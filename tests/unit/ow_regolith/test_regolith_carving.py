"""The terrain's ledger and the tracker's hooks: cuts by layer, grinder cuttings left loose and
collected by a later dig, a full scoop leaving the rest, deposits raising the terrain."""

from __future__ import annotations

import numpy as np
import pytest
from regolith_scenes import BOTTOM_DOWN, GROUND_Z, RESOLUTION, field_terrain, scoop_with_tip_at

from ow_regolith.budget import Account
from ow_regolith.carving_ledger import CarvingLedger
from ow_regolith.config import DEFAULT_COLUMN
from ow_regolith.errors import CarvingError
from ow_regolith.materials import UNITS_PER_M3, Bulk

AREA = RESOLUTION**2
CELL = (15, 20)  # x 1.8 m, y 0.0 m


def lowered(heights: np.ndarray, cells: list[tuple[int, int]], by: float) -> np.ndarray:
    after = heights.copy()
    for cell in cells:
        after[cell] -= by
    return after


def test_a_cut_takes_the_column_between_the_old_and_new_depth():
    ledger = CarvingLedger(field_terrain(), DEFAULT_COLUMN)
    before = ledger.heightmap.heights
    after = lowered(before, [CELL], 0.06)
    first = ledger.cut(before, after)
    deeper = lowered(after, [CELL], 0.10)
    second = ledger.cut(after, deeper)
    assert list(first) == [CELL] and list(second) == [CELL]
    assert first[CELL].by_layer() == {"irradiated": round(0.06 * AREA * UNITS_PER_M3)}
    # 6 -> 16 cm: 4 cm of the top layer, 6 cm of pristine ice.
    assert second[CELL].by_layer()["irradiated"] == pytest.approx(0.04 * AREA * UNITS_PER_M3, abs=1)
    assert second[CELL].by_layer()["pristine"] == pytest.approx(0.06 * AREA * UNITS_PER_M3, abs=1)
    assert ledger.removed == first[CELL] + second[CELL]
    assert ledger.solid_top(CELL) == pytest.approx(GROUND_Z - 0.16)


def test_a_cut_of_a_window_lands_on_its_cells():
    ledger = CarvingLedger(field_terrain(), DEFAULT_COLUMN)
    window = ledger.heightmap.heights[10:13, 18:22]
    removed = ledger.cut(window, window - 0.01, offset=(10, 18))
    assert sorted(removed) == [(r, c) for r in range(10, 13) for c in range(18, 22)]


@pytest.mark.parametrize(
    ("before", "after", "offset", "match"),
    [
        (np.zeros((2, 2)), np.zeros((2, 3)), (0, 0), r"does not fit the terrain of \(31, 41\)"),
        (np.zeros((2, 2)), np.zeros((2, 2)), (30, 0), "does not fit"),
        (np.zeros((2, 2)), np.full((2, 2), 0.01), (3, 4), r"raised cell \(3, 4\)"),
    ],
)
def test_a_cut_the_ledger_cannot_account_for_is_refused(before, after, offset, match):
    ledger = CarvingLedger(field_terrain(), DEFAULT_COLUMN)
    with pytest.raises(CarvingError, match=match):
        ledger.cut(before, after, offset)


def test_grinder_cuttings_stay_loose_and_a_digging_scoop_collects_them(tracker, geometry):
    heights = field_terrain().heights
    after = lowered(heights, [CELL], 0.05)
    tracker.terrain_cut("grinder", heights, after, scoop_digging=True)
    cut = tracker.ledger.loose(CELL)
    assert cut.units == round(0.05 * AREA * UNITS_PER_M3)
    assert tracker.budget[Account.EXCAVATED].is_empty
    # The trench shows its floor; the cuttings fill it back to the original surface.
    assert tracker.ledger.undrawn_units(CELL) == cut.units
    assert tracker.ledger.loose_top(CELL) == pytest.approx(GROUND_Z)
    # Not digging: nothing is collected; digging with the edge in the cuttings: all of it.
    tip = np.array([1.8, 0.0, GROUND_Z - 0.04])
    tracker.scoop_moved(scoop_with_tip_at(geometry, BOTTOM_DOWN, tip), digging=False)
    assert tracker.budget.in_scoop.is_empty
    tracker.scoop_moved(
        scoop_with_tip_at(geometry, BOTTOM_DOWN, tip + np.array([0.0, 0.0, 0.06])), True
    )
    assert tracker.budget.in_scoop.is_empty  # the edge above the heap
    tracker.scoop_moved(scoop_with_tip_at(geometry, BOTTOM_DOWN, tip), digging=True)
    assert tracker.budget.in_scoop == cut
    assert tracker.ledger.loose(CELL).is_empty
    tracker.budget.check()


def test_a_full_scoop_leaves_the_rest_of_its_cut_loose(tracker, geometry):
    heights = field_terrain().heights
    cells = [(15, c) for c in range(18, 24)]
    # 6 cells x 1.6e-3 m^2 x 8 cm = 7.7e-4 m^3, more than the scoop's 6.7e-4.
    after = lowered(heights, cells, 0.08)
    tracker.terrain_cut("scoop", heights, after, scoop_digging=True)
    capacity = geometry.capacity_units
    assert tracker.budget.in_scoop.units == capacity
    assert tracker.budget[Account.EXCAVATED].units == capacity
    left = tracker.ledger.loose_total()
    assert left.units + capacity == tracker.ledger.removed.units
    # Cells are filled in row-major order: the last one keeps what did not fit.
    assert tracker.ledger.loose(cells[-1]).units > 0
    assert tracker.ledger.loose(cells[0]).is_empty
    tracker.budget.check()


def test_a_scoop_cut_outside_a_dig_leaves_its_cut_loose(tracker):
    heights = field_terrain().heights
    tracker.terrain_cut("scoop", heights, lowered(heights, [CELL], 0.01), scoop_digging=False)
    assert tracker.budget.in_scoop.is_empty
    assert tracker.ledger.loose(CELL) == tracker.ledger.removed


def test_a_deposit_raises_the_terrain_by_its_volume_and_is_dug_again():
    ledger = CarvingLedger(field_terrain(), DEFAULT_COLUMN)
    bulk = Bulk.of("irradiated", "SALT", 4 * 10**14)  # 0.4 l
    change = ledger.deposit(1.8, 0.0, bulk, radius_m=0.1)
    assert len(change.rows) == 21  # cell centres within 10 cm on a 4 cm grid
    assert float(np.sum(change.raise_m)) * AREA == pytest.approx(bulk.volume_m3, rel=1e-12)
    assert ledger.loose_total() == bulk
    heights = field_terrain().heights
    change.apply(heights)
    assert np.array_equal(heights, ledger.heightmap.heights)
    # The heap is drawn: a cut through it takes nothing from the column, and leaves the cut
    # part of the heap loose and undrawn.
    assert ledger.undrawn_units(CELL) == 0
    cut = ledger.cut(heights, lowered(heights, [CELL], change.raise_m[10] / 2))
    assert cut[CELL].is_empty and ledger.removed.is_empty
    assert ledger.undrawn_units(CELL) == pytest.approx(ledger.loose(CELL).units / 2, abs=1)


def test_a_deposit_beyond_the_terrain_changes_nothing():
    ledger = CarvingLedger(field_terrain(), DEFAULT_COLUMN)
    assert not ledger.deposit(5.0, 0.0, Bulk.of("pristine", "ICE", 10), 0.1)
    assert ledger.loose_total().is_empty


def test_loose_regolith_is_taken_well_mixed(tracker):
    ledger = tracker.ledger
    ledger.add_loose(CELL, Bulk.of("irradiated", "ICE", 300) + Bulk.of("pristine", "ICE", 100))
    taken = ledger.take_undrawn(CELL, 200)
    assert taken == Bulk.of("irradiated", "ICE", 150) + Bulk.of("pristine", "ICE", 50)
    assert ledger.loose(CELL).units == 200
