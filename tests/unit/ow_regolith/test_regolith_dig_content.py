"""An outside model of a dig (the live DEM) says what the scoop holds when the dig ends:
``RegolithTracker.set_dig_content`` makes the dig's content that, to the unit. The excess goes
back to the cells the dig cut as loose regolith; a shortfall comes from those cells' loose
regolith, then from their columns cut deeper, within the scoop's capacity. The budget stays exact
and the composition is the ledger's."""

from __future__ import annotations

import numpy as np
import pytest
from regolith_scenes import GROUND_Z, RESOLUTION

from ow_regolith.budget import Account, RegolithBudget
from ow_regolith.errors import BudgetError
from ow_regolith.materials import UNITS_PER_M3, Bulk
from ow_regolith.tracker import RegolithTracker

AREA = RESOLUTION**2
#: Six cells of a row of the field, in row-major order.
CELLS = [(15, c) for c in range(18, 24)]


def lowered(heights: np.ndarray, cells: list[tuple[int, int]], by: float) -> np.ndarray:
    after = heights.copy()
    for cell in cells:
        after[cell] -= by
    return after


def scoop_dig(tracker: RegolithTracker, depth: float, cells: list[tuple[int, int]] = CELLS) -> None:
    """A dig phase in which the scoop cuts ``cells`` ``depth`` m deep."""
    tracker.start_dig()
    heights = tracker.ledger.heightmap.heights
    tracker.terrain_cut("scoop", heights, lowered(heights, cells, depth), scoop_digging=True)


def assert_exact(tracker: RegolithTracker) -> None:
    """The budget holds, and so does the terrain's own account: cut from the column +
    deposited = loose on the terrain + excavated."""
    budget = tracker.budget
    budget.check()
    assert tracker.ledger.removed + budget[Account.DEPOSITED] == (
        tracker.ledger.loose_total() + budget[Account.EXCAVATED]
    )


def test_returning_to_the_ground_lowers_excavated_and_in_scoop_alike():
    budget = RegolithBudget()
    budget.excavate(Bulk.of("irradiated", "ICE", 1000) + Bulk.of("pristine", "ICE", 500))
    budget.pour(Bulk.of("irradiated", "ICE", 300), Account.DEPOSITED)
    budget.return_to_ground(Bulk.of("pristine", "ICE", 200))
    budget.check()
    assert budget.in_scoop == Bulk.of("irradiated", "ICE", 700) + Bulk.of("pristine", "ICE", 300)
    assert budget[Account.EXCAVATED].units == 1300
    assert budget[Account.DEPOSITED].units == 300


def test_returning_more_than_the_scoop_holds_is_refused_and_changes_nothing():
    budget = RegolithBudget()
    budget.excavate(Bulk.of("irradiated", "ICE", 100))
    before = budget.snapshot()
    with pytest.raises(BudgetError, match="cannot give 1 units back to the ground"):
        budget.return_to_ground(Bulk.of("pristine", "ICE", 1))
    assert budget.snapshot() == before


def test_a_smaller_content_returns_the_excess_loose_to_the_cells_the_dig_cut(tracker):
    scoop_dig(tracker, 0.05)  # 6 x 1.6e-3 m^2 x 5 cm = 4.8e-4 m^3, all from the top layer
    took = tracker.budget.in_scoop.units
    target = round(3.0e-4 * UNITS_PER_M3)
    change = tracker.set_dig_content(target)
    assert (change.before_units, change.after_units) == (took, target)
    assert tracker.budget.in_scoop.units == target
    assert tracker.budget[Account.EXCAVATED].units == target
    assert not change.lowered
    # The excess lies loose, undrawn, split evenly over the six cells (within a unit).
    loose = [tracker.ledger.loose(cell).units for cell in CELLS]
    assert sum(loose) == took - target and max(loose) - min(loose) <= 1
    assert all(
        tracker.ledger.undrawn_units(cell) == tracker.ledger.loose(cell).units for cell in CELLS
    )
    assert_exact(tracker)


def test_the_returned_excess_has_the_digs_composition(tracker):
    scoop_dig(tracker, 0.12, CELLS[:3])  # 10 cm of the top layer, 2 cm of pristine ice
    content = tracker.budget.in_scoop
    assert set(content.by_layer()) == {"irradiated", "pristine"}
    tracker.set_dig_content(content.units // 2)
    kept = tracker.budget.in_scoop
    for layer, units in kept.by_layer().items():
        # Well mixed: each layer's share of the content is what it was, within a unit.
        assert units == pytest.approx(content.by_layer()[layer] / 2, abs=1)
    assert kept + tracker.ledger.loose_total() == content
    assert_exact(tracker)


def test_a_larger_content_takes_the_cells_loose_regolith_first(tracker):
    scoop_dig(tracker, 0.02)
    took = tracker.budget.in_scoop.units
    # Grinder cuttings in the dig's third cell, not collected by this dig.
    heights = tracker.ledger.heightmap.heights
    tracker.terrain_cut("grinder", heights, lowered(heights, [CELLS[2]], 0.10), True)
    cuttings = tracker.ledger.loose(CELLS[2])
    more = cuttings.units // 3
    change = tracker.set_dig_content(took + more)
    assert tracker.budget.in_scoop.units == took + more
    assert not change.lowered  # no column was cut deeper
    assert tracker.ledger.loose(CELLS[2]) == cuttings.take(more)[1]
    # The cuttings are 8 cm of the top layer and 2 cm of pristine ice: so is what was taken.
    taken = tracker.budget.in_scoop.by_layer()
    assert taken["pristine"] == pytest.approx(more * 0.2, abs=1)
    assert_exact(tracker)


def test_a_larger_content_without_loose_regolith_cuts_the_columns_deeper(tracker):
    scoop_dig(tracker, 0.08, CELLS[:3])  # 8 cm of the top layer
    took = tracker.budget.in_scoop.units
    more = round(3 * AREA * 0.04 * UNITS_PER_M3)  # 4 cm more under each of the three cells
    change = tracker.set_dig_content(took + more)
    assert change.after_units == tracker.budget.in_scoop.units == took + more
    # The columns were cut evenly 4 cm deeper, and the height map must follow: 2 cm of the top
    # layer, 2 cm of pristine ice under each cell.
    assert sorted(zip(change.lowered.rows, change.lowered.cols, strict=True)) == CELLS[:3]
    assert np.allclose(change.lowered.raise_m, -0.04, atol=1e-12)
    heights = tracker.ledger.heightmap.heights
    assert all(heights[cell] == pytest.approx(GROUND_Z - 0.12) for cell in CELLS[:3])
    assert tracker.budget.in_scoop.by_layer()["pristine"] == pytest.approx(more / 2, abs=3)
    assert_exact(tracker)


def test_a_larger_content_fills_the_scoop_at_most(tracker, geometry):
    scoop_dig(tracker, 0.05)
    change = tracker.set_dig_content(geometry.capacity_units * 2)
    assert change.after_units == tracker.budget.in_scoop.units == geometry.capacity_units
    assert_exact(tracker)


def test_the_same_content_changes_nothing(tracker):
    scoop_dig(tracker, 0.05)
    before = tracker.budget.snapshot()
    loose = tracker.ledger.loose_total()
    heights = tracker.ledger.heightmap.heights
    change = tracker.set_dig_content(before.accounts[Account.IN_SCOOP].units)
    assert change.before_units == change.after_units and not change.lowered
    assert tracker.budget.snapshot() == before
    assert tracker.ledger.loose_total() == loose
    assert np.array_equal(tracker.ledger.heightmap.heights, heights)


def test_only_the_last_digs_content_is_changed(tracker):
    scoop_dig(tracker, 0.02)
    first = tracker.budget.in_scoop.units
    scoop_dig(tracker, 0.02)  # a second dig phase cutting the same cells 2 cm deeper
    second = tracker.budget.in_scoop.units - first
    change = tracker.set_dig_content(0)
    assert change.before_units == second
    assert tracker.budget.in_scoop.units == first
    assert_exact(tracker)
