"""An outside model of a dig (the live DEM) says what the terrain's surface became:
``RegolithTracker.reshape_terrain`` moves the terrain's material towards it within the terrain.
Falling cells give up what lies above their target into a pool, rising cells receive from it
(all scaled down alike when it is short), the rest lies loose in the fallen cells; the budget's
accounts do not change and the terrain's own account stays exact."""

from __future__ import annotations

import numpy as np
import pytest
from regolith_scenes import GROUND_Z, RESOLUTION, field_terrain
from test_regolith_dig_content import CELLS, assert_exact, scoop_dig

from ow_regolith.config import RegolithConfig
from ow_regolith.errors import CarvingError
from ow_regolith.materials import UNITS_PER_M3
from ow_regolith.tracker import RegolithTracker

AREA = RESOLUTION**2
#: A berm beside the dig's row.
BERM = [(16, c) for c in range(18, 24)]
FLOOR = GROUND_Z - 1.0


def heights(tracker: RegolithTracker, cells: list[tuple[int, int]]) -> np.ndarray:
    return np.array([tracker.ledger.heightmap.heights[cell] for cell in cells])


def dug(tracker: RegolithTracker) -> RegolithTracker:
    """A dig 5 cm deep along CELLS; the scoop keeps what it took."""
    scoop_dig(tracker, 0.05)
    return tracker


def test_targets_equal_to_the_heights_change_nothing(tracker):
    dug(tracker)
    cells = CELLS + BERM
    before_map = tracker.ledger.heightmap.heights
    budget = tracker.budget.snapshot()
    move = tracker.reshape_terrain(cells, heights(tracker, cells), FLOOR)
    assert not move.change and move.moved_units == move.raised_units == 0
    assert np.array_equal(tracker.ledger.heightmap.heights, before_map)
    assert tracker.budget.snapshot() == budget
    assert move.record() == {
        "cells": 0,
        "shown_m3": 0.0,
        "moved_m3": 0.0,
        "raised_m3": 0.0,
        "largest_m": 0.0,
    }


def test_a_berm_is_built_from_the_trench_floor_without_touching_the_budget(tracker):
    dug(tracker)
    budget = tracker.budget.snapshot()
    # The trench floor falls 1 cm more; the berm beside it rises 1 cm: the same volume.
    cells = CELLS + BERM
    targets = np.concatenate([heights(tracker, CELLS) - 0.01, heights(tracker, BERM) + 0.01])
    move = tracker.reshape_terrain(cells, targets, FLOOR)
    assert tracker.budget.snapshot() == budget
    assert_exact(tracker)
    assert np.allclose(heights(tracker, CELLS), GROUND_Z - 0.06)
    # Each fallen cell gave round(1 cm x area) units (column); the berm took them all.
    per_cell = round(0.01 * AREA * UNITS_PER_M3)
    assert move.moved_units == pytest.approx(6 * per_cell, abs=6)
    assert move.raised_units == move.moved_units
    assert np.allclose(heights(tracker, BERM), GROUND_Z + 0.01, atol=1e-12)
    berm_loose = sum(tracker.ledger.loose(cell).units for cell in BERM)
    assert berm_loose == move.raised_units
    # The berm shows its regolith (drawn): none of it is undrawn.
    assert all(tracker.ledger.undrawn_units(cell) == 0 for cell in BERM)
    assert move.record()["cells"] == 12
    assert move.record()["largest_m"] == pytest.approx(0.01)


def test_a_short_pool_is_shared_alike_and_never_overdrawn(tracker):
    dug(tracker)
    budget = tracker.budget.snapshot()
    # The trench falls 2 mm, the berm asks 1 cm: it gets a fifth of what it asks, cell by cell.
    cells = BERM + CELLS  # any order: visited row-major
    targets = np.concatenate([heights(tracker, BERM) + 0.01, heights(tracker, CELLS) - 0.002])
    move = tracker.reshape_terrain(cells, targets, FLOOR)
    assert move.raised_units == move.moved_units > 0
    rises = heights(tracker, BERM) - GROUND_Z
    assert np.allclose(rises, 0.002, atol=2 / UNITS_PER_M3 / AREA)
    assert tracker.budget.snapshot() == budget
    assert_exact(tracker)


def test_what_the_pool_keeps_lies_loose_and_undrawn_in_the_fallen_cells(tracker):
    dug(tracker)
    loose_before = tracker.ledger.loose_total().units
    targets = heights(tracker, CELLS) - 0.01  # nothing rises
    move = tracker.reshape_terrain(CELLS, targets, FLOOR)
    assert move.raised_units == 0 and move.moved_units > 0
    loose = [tracker.ledger.loose(cell).units for cell in CELLS]
    assert sum(loose) - loose_before == move.moved_units and max(loose) - min(loose) <= 2
    assert all(
        tracker.ledger.undrawn_units(cell) == tracker.ledger.loose(cell).units for cell in CELLS
    )
    assert_exact(tracker)


def test_a_rising_cell_first_shows_the_loose_regolith_it_holds_unseen(tracker):
    dug(tracker)
    # The outside model kept a third of what the geometric dig took: the rest lies loose and
    # undrawn in the trench (docs/regolith.md), which the target asks to fill back up.
    tracker.set_dig_content(tracker.budget.in_scoop.units // 3)
    undrawn = sum(tracker.ledger.undrawn_units(cell) for cell in CELLS)
    loose, removed = tracker.ledger.loose_total(), tracker.ledger.removed
    budget = tracker.budget.snapshot()
    move = tracker.reshape_terrain(CELLS, np.full(len(CELLS), GROUND_Z), FLOOR)
    assert move.shown_units == undrawn and move.moved_units == 0
    assert np.allclose(heights(tracker, CELLS), GROUND_Z - 0.05 * 1 / 3, atol=1e-9)
    assert all(tracker.ledger.undrawn_units(cell) == 0 for cell in CELLS)
    assert tracker.ledger.loose_total() == loose and tracker.ledger.removed == removed
    assert tracker.budget.snapshot() == budget
    assert_exact(tracker)


def test_no_cell_falls_below_the_floor(tracker):
    dug(tracker)
    floor = GROUND_Z - 0.08
    move = tracker.reshape_terrain(CELLS, heights(tracker, CELLS) - 1.0, floor)
    assert np.allclose(heights(tracker, CELLS), floor)
    assert np.allclose(move.change.raise_m, floor - (GROUND_Z - 0.05))
    assert_exact(tracker)


def test_a_fall_through_a_deposit_takes_its_drawn_regolith_first(tracker):
    dug(tracker)
    # The berm first rises 1 cm from the trench (drawn loose regolith), then falls back 5 mm.
    tracker.reshape_terrain(
        CELLS + BERM,
        np.concatenate([heights(tracker, CELLS) - 0.01, heights(tracker, BERM) + 0.01]),
        FLOOR,
    )
    removed = tracker.ledger.removed
    berm_loose = sum(tracker.ledger.loose(cell).units for cell in BERM)
    move = tracker.reshape_terrain(BERM, heights(tracker, BERM) - 0.005, FLOOR)
    assert tracker.ledger.removed == removed  # no column was cut: the berm's loose moved
    assert move.moved_units == pytest.approx(berm_loose / 2, abs=6)
    assert sum(tracker.ledger.loose(cell).units for cell in BERM) == berm_loose
    assert_exact(tracker)


def test_reshaping_is_deterministic(geometry, targets):
    results = []
    for _ in range(2):
        tracker = dug(
            RegolithTracker(RegolithConfig(), field_terrain(), "europa:1", geometry, targets)
        )
        cells = BERM + CELLS
        wanted = np.concatenate(
            [heights(tracker, BERM) + 0.003, heights(tracker, CELLS) - np.linspace(0, 0.01, 6)]
        )
        move = tracker.reshape_terrain(cells, wanted, FLOOR)
        loose = {cell: tracker.ledger.loose(cell) for cell in cells}
        results.append((move.moved_units, move.raised_units, move.change.raise_m.tolist(), loose))
    assert results[0] == results[1]


@pytest.mark.parametrize(
    ("cells", "targets", "message"),
    [
        ([(0, 0), (0, 0)], [GROUND_Z, GROUND_Z], "distinct"),
        ([(0, 99)], [GROUND_Z], "within"),
        ([(0, 0)], [np.nan], "finite"),
        ([(0, 0)], [GROUND_Z, GROUND_Z], "as many"),
    ],
)
def test_bad_cells_or_targets_are_refused(tracker, cells, targets, message):
    with pytest.raises(CarvingError, match=message):
        tracker.reshape_terrain(cells, np.array(targets), FLOOR)
