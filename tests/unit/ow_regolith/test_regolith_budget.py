"""The regolith budget is exact at every moment: excavated = in scoop + in dock + ingested +
spilled + deposited, component by component, under seeded random sequences of operations (on
the budget alone, and through the tracker's hooks as a simulation would call them)."""

from __future__ import annotations

import random

import numpy as np
import pytest
from regolith_scenes import GROUND_Z, field_terrain, pose

from ow_regolith.budget import HOLDING_ACCOUNTS, Account, RegolithBudget
from ow_regolith.errors import BudgetError
from ow_regolith.materials import Bulk, total

COMPONENTS = [
    ("irradiated", "ICE"),
    ("irradiated", "MG_HYDRATES"),
    ("irradiated", "SALT"),
    ("pristine", "ICE"),
]
POURS = [Account.IN_DOCK, Account.SPILLED, Account.DEPOSITED]


def random_bulk(rng: random.Random) -> Bulk:
    return Bulk({key: rng.randrange(0, 10 ** rng.randrange(1, 15)) for key in COMPONENTS})


def assert_balanced(budget: RegolithBudget) -> None:
    budget.check()
    snapshot = budget.snapshot()
    assert snapshot.imbalance_units() == 0
    held = total(snapshot.accounts[a] for a in HOLDING_ACCOUNTS)
    assert held == snapshot.accounts[Account.EXCAVATED]


@pytest.mark.parametrize("seed", range(5))
def test_random_transfers_keep_the_budget_exact(seed):
    rng = random.Random(seed)
    budget = RegolithBudget()
    for _ in range(400):
        operation = rng.choice(["excavate", "pour", "pour", "overdraw", "ingest"])
        if operation == "excavate":
            budget.excavate(random_bulk(rng))
        elif operation == "pour":
            part, _ = budget.in_scoop.take(rng.randrange(0, budget.in_scoop.units + 1))
            budget.pour(part, rng.choice(POURS))
        elif operation == "overdraw":
            before = budget.snapshot()
            too_much = budget.in_scoop + Bulk.of("pristine", "ICE", 1)
            with pytest.raises(BudgetError, match=r"cannot move \d+ units from in_scoop"):
                budget.pour(too_much, rng.choice(POURS))
            assert budget.snapshot() == before
        else:
            in_dock = budget.in_dock
            assert budget.ingest() == in_dock
            assert budget.in_dock.is_empty
        assert_balanced(budget)


def test_regolith_is_poured_only_where_it_can_land():
    budget = RegolithBudget()
    budget.excavate(Bulk.of("pristine", "ICE", 5))
    with pytest.raises(BudgetError, match="lands in deposited, in_dock, spilled, not in ingested"):
        budget.pour(Bulk.of("pristine", "ICE", 5), Account.INGESTED)


def random_rotation(rng: random.Random) -> np.ndarray:
    w, x, y, z = (rng.gauss(0.0, 1.0) for _ in range(4))
    n = (w * w + x * x + y * y + z * z) ** 0.5
    w, x, y, z = w / n, x / n, y / n, z / n
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def random_place(rng: random.Random) -> np.ndarray:
    where = rng.choice(["field", "field", "field", "dock", "deck", "beyond"])
    if where == "field":
        return np.array([rng.uniform(1.6, 2.0), rng.uniform(-0.2, 0.2), GROUND_Z - 0.1])
    if where == "dock":
        return np.array([rng.uniform(0.50, 0.61), rng.uniform(-0.5, -0.2), 0.9])
    if where == "deck":
        return np.array([rng.uniform(-0.3, 0.3), rng.uniform(-0.3, 0.3), 1.0])
    return np.array([4.0, 0.0, 0.3])


@pytest.mark.parametrize("seed", range(3))
def test_random_digs_spills_and_ingestions_keep_budget_and_terrain_exact(tracker, seed):
    """A simulation's calls in random order: cuts by either tool, scoop moves in and out of
    digs at random poses over the field, the dock, the deck and beyond the terrain, ingestions.
    After each: the budget balances, the scoop never holds more than its capacity, the terrain's
    heights are the simulation's, and the terrain's own account holds: what was cut from the
    column plus what was deposited = what lies loose plus what was excavated."""
    rng = random.Random(seed)
    heights = field_terrain().heights.copy()
    capacity = tracker.scoop.capacity_units
    ingested = Bulk()
    for _ in range(300):
        operation = rng.choice(["cut", "cut", "dig", "dig", "move", "move", "ingest"])
        if operation == "cut":
            r, c = rng.randrange(12, 18), rng.randrange(16, 24)
            before = heights.copy()
            heights[r : r + 2, c : c + 3] -= rng.uniform(0.0, 0.03)
            tool = rng.choice(["scoop", "grinder"])
            tracker.terrain_cut(tool, before, heights, scoop_digging=rng.random() < 0.7)
        elif operation in ("dig", "move"):
            X = pose(random_rotation(rng), random_place(rng))
            tracker.scoop_moved(X, digging=operation == "dig").apply(heights)
        else:
            ingested += tracker.ingest()
        assert_balanced(tracker.budget)
        budget = tracker.budget
        assert budget.in_scoop.units <= capacity
        assert np.array_equal(heights, tracker.ledger.heightmap.heights)
        ledger = tracker.ledger
        assert ledger.removed + budget[Account.DEPOSITED] == (
            ledger.loose_total() + budget[Account.EXCAVATED]
        )
    assert ingested == tracker.budget[Account.INGESTED]
    # The sequence went everywhere: every account saw regolith.
    for account in (Account.EXCAVATED, Account.INGESTED, Account.SPILLED, Account.DEPOSITED):
        assert not tracker.budget[account].is_empty, account
