"""Fixtures of the regolith tests: the scoop and the pour targets read once from the URDF, a
tracker on a flat field."""

from __future__ import annotations

import pytest
from regolith_scenes import field_terrain

from ow_regolith.config import RegolithConfig
from ow_regolith.landing import PourTargets
from ow_regolith.scoop import ScoopGeometry
from ow_regolith.tracker import RegolithTracker


@pytest.fixture(scope="session")
def geometry() -> ScoopGeometry:
    return ScoopGeometry.from_urdf()


@pytest.fixture(scope="session")
def targets() -> PourTargets:
    return PourTargets.from_urdf()


@pytest.fixture
def tracker(geometry: ScoopGeometry, targets: PourTargets) -> RegolithTracker:
    return RegolithTracker(RegolithConfig(), field_terrain(), "europa:1", geometry, targets)
