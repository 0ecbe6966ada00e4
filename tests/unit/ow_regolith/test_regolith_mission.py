"""The paper's digging procedure as the regolith model sees it: grind a 10 cm trench, dig it
out and discard the spoil, grind again at the bottom, dig the sample, deliver it to the dock and
ingest it. The sample's share of irradiated top-layer ice is what the first scoop could not
carry away; skipping the first grind gives a sample of top-layer ice only."""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import pytest
from regolith_scenes import GROUND_Z, field_terrain, scoop_pouring_at, scoop_with_tip_at

from ow_regolith.budget import Account
from ow_regolith.config import RegolithConfig
from ow_regolith.landing import Landing
from ow_regolith.materials import Bulk, LayerColumn, summarize
from ow_regolith.tracker import RegolithTracker

#: The trench: 2 rows x 3 columns of 4 cm cells around x 1.8 m, y 0.02 m (12 x 8 cm).
ROWS, COLS = slice(15, 17), slice(19, 22)
TRENCH_X = (1.76, 1.80, 1.84)
TRENCH_Y = 0.02
#: rad, how far the scoop is tipped to pour (the lander's deliver and discard tilt).
POUR_TILT = math.radians(110.0)
DOCK_ABOVE = np.array([0.555, -0.35, 0.75])
DISCARD_ABOVE = np.array([2.4, 0.4, GROUND_Z + 0.3])


class Mission:
    """A tracker and the simulation's height map it follows."""

    def __init__(self, tracker: RegolithTracker) -> None:
        self.tracker = tracker
        self.heights = field_terrain().heights.copy()

    def grind(self, depth: float, steps: int = 10) -> None:
        """The grinder lowers the trench by ``depth`` m in ``steps`` carve updates."""
        for _ in range(steps):
            before = self.heights.copy()
            self.heights[ROWS, COLS] -= depth / steps
            self.tracker.terrain_cut("grinder", before, self.heights, scoop_digging=False)
            self.check()

    def dig(self) -> None:
        """One pass along the trench, the cutting edge just above its floor, in a dig phase;
        then the scoop is carried out with its lip level."""
        geometry = self.tracker.scoop
        floor = float(self.heights[ROWS, COLS].max())
        upright = geometry.upright()
        for x in TRENCH_X:
            tip = np.array([x, TRENCH_Y, floor + 0.005])
            self.tracker.scoop_moved(scoop_with_tip_at(geometry, upright, tip), digging=True)
            self.check()
        above = np.array([TRENCH_X[-1], TRENCH_Y, GROUND_Z + 0.3])
        self.move(scoop_with_tip_at(geometry, upright, above))

    def pour(self, point: np.ndarray) -> None:
        """Tip the scoop over the edge so that it pours at ``point``."""
        geometry = self.tracker.scoop
        self.move(scoop_pouring_at(geometry, geometry.tilted(POUR_TILT), point))

    def move(self, X_base_scoop: np.ndarray) -> None:
        self.tracker.scoop_moved(X_base_scoop, digging=False).apply(self.heights)
        self.check()

    def check(self) -> None:
        self.tracker.budget.check()
        assert np.array_equal(self.heights, self.tracker.ledger.heightmap.heights)


def units_in_trench(tracker: RegolithTracker, top_m: float, bottom_m: float) -> int:
    """units of the column between two depths under the trench's cells."""
    area = tracker.ledger.area_m2
    per_cell = LayerColumn.units_above(bottom_m, area) - LayerColumn.units_above(top_m, area)
    return 6 * per_cell


def deliver_and_ingest(mission: Mission) -> Bulk:
    mission.pour(DOCK_ABOVE)
    assert mission.tracker.last_landing is Landing.DOCK
    assert mission.tracker.budget.in_scoop.is_empty
    sample = mission.tracker.ingest()
    mission.check()
    return sample


def test_the_papers_procedure_samples_the_top_layer_the_first_dig_left_behind(tracker):
    mission = Mission(tracker)
    capacity = tracker.scoop.capacity_units
    mission.grind(0.10)
    spoil = units_in_trench(tracker, 0.0, 0.10)
    assert tracker.ledger.loose_total().units == spoil
    assert spoil > capacity  # the 12 x 8 x 10 cm trench holds more than one scoop

    mission.dig()
    assert tracker.budget.in_scoop.units == capacity
    assert tracker.budget.in_scoop.layer_share("irradiated") == 1
    mission.pour(DISCARD_ABOVE)
    assert tracker.last_landing is Landing.TERRAIN
    assert tracker.budget[Account.DEPOSITED].units == capacity

    mission.grind(0.03)
    fresh = units_in_trench(tracker, 0.10, 0.13)
    left_on_floor = spoil - capacity
    assert left_on_floor + fresh <= capacity  # the sample fits: the dig takes all that is loose
    mission.dig()
    sample = deliver_and_ingest(mission)

    expected_share = Fraction(left_on_floor, left_on_floor + fresh)
    assert sample.units == left_on_floor + fresh
    assert sample.layer_share("irradiated") == expected_share
    summary = summarize(sample, tracker.database, tracker.column)
    assert summary.top_layer_share == pytest.approx(float(expected_share), abs=1e-12)
    assert summary.composition["SALT"] == pytest.approx(0.05 * float(expected_share), abs=1e-9)
    assert summary.volume_m3 == pytest.approx(sample.units * 1e-18)
    # Budget at the end: everything excavated is ingested or lies on the discard heap.
    budget = tracker.budget
    assert budget[Account.EXCAVATED] == budget[Account.INGESTED] + budget[Account.DEPOSITED]
    assert budget[Account.SPILLED].is_empty and budget.in_dock.is_empty


def test_skipping_the_first_grind_samples_the_top_layer_only(tracker):
    with_first_grind = RegolithTracker(
        RegolithConfig(), field_terrain(), "europa:1", tracker.scoop, tracker.targets
    )
    mission = Mission(with_first_grind)
    mission.grind(0.10)
    mission.dig()
    mission.pour(DISCARD_ABOVE)
    mission.grind(0.03)
    mission.dig()
    share_with = deliver_and_ingest(mission).layer_share("irradiated")

    shortcut = Mission(tracker)
    shortcut.grind(0.03)
    shortcut.dig()
    share_without = deliver_and_ingest(shortcut).layer_share("irradiated")

    assert 0 < share_with < share_without == 1
