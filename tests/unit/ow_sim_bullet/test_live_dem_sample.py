"""With the live DEM (``terrain_forces: yade``) the particles in the scoop when a dig ends are the
sample: the simulation makes the scoop's content for that dig the DEM sample's bulk volume (the
spheres' volume over the bed's solid fraction), to the unit and within the scoop's capacity,
and the regolith budget stays exact.

The real arm follows a planned ``dig_linear`` in process with the real YADE model (marked
``yade``, skipped without YADE). Coarse grains (2 cm radius: the bed settles in seconds and a few
spheres end in the scoop) keep the dig's ~1000 exchanges to about a minute; the accounting does
not depend on the grain size.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest

from ow_dem_bridge.api import LIVE_MODEL_NAME
from ow_dem_bridge.live import LiveDemModel
from ow_dem_bridge.models import make_model
from ow_description.description import DEFAULT_GROUND_Z, UNSTOWED
from ow_description.model import LanderModel
from ow_lander.config import PlannerConfig, TimingConfig
from ow_lander.operations.planner import Operations
from ow_lander.planning.planner import ArmPlanner
from ow_regolith.budget import Account
from ow_regolith.materials import units_from_m3
from ow_sim_bullet.config import SimConfig
from ow_sim_bullet.sim_core import BulletSim
from ow_sim_bullet.terrains import flat
from ow_sim_bullet.trajectory import JointTrajectory

GROUND = DEFAULT_GROUND_Z
CONFIG = SimConfig(
    initial_positions={**SimConfig().initial_positions, **UNSTOWED}, terrain_material=1
)
#: A short dig (its dig phase lasts ~20 s of sim time).
DIG = {"x": 1.65, "y": 0.0, "depth": 0.05, "length": 0.05, "ground_position": GROUND}
#: Coarse grains, 2.5 times the default's.
COARSE = {"particle_radius": 0.02, "fallback": "none"}


@pytest.mark.yade
@pytest.mark.skipif(
    shutil.which("yade") is None,
    reason="YADE is not installed: apt-get install yade (make setup installs it)",
)
# One to three minutes of wall time (a thousand exchanges), beside make test's 10: make
# test-dem-live runs it; the accounting itself is make test's (tests/unit/ow_regolith).
@pytest.mark.skipif(
    not os.environ.get("OW_DEM_LIVE_TESTS"),
    reason="a live DEM dig in process: set OW_DEM_LIVE_TESTS=1 (make test-dem-live) to run it",
)
def test_the_scoop_holds_the_dem_sample_when_a_live_dig_ends(tmp_path: Path):
    live = make_model(LIVE_MODEL_NAME, {**COARSE, "cache_dir": str(tmp_path)})
    assert isinstance(live, LiveDemModel)
    sim = BulletSim(CONFIG, flat(GROUND), live)
    try:
        ops = Operations(ArmPlanner(LanderModel(), PlannerConfig()))
        q = ops.model.q_from(dict(zip(sim.names, sim.sample.position.tolist(), strict=True)))
        timed = ops.plan("dig_linear", q, sim.heightmap, DIG).timed(
            TimingConfig(), ops.planner.velocity_limits
        )
        sim.set_trajectory(JointTrajectory.from_plan(timed, sim.time, sim.names))
        budget = sim.regolith.tracker.budget
        geometric = 0
        while not sim.finished_dem_digs and sim.time < timed.duration:
            if sim.dig_phase.digging:
                geometric = budget[Account.EXCAVATED].units  # the geometric cut so far
            sim.step()
        (_, summary), *_ = sim.finished_dem_digs
        (dig,) = live.digs
    finally:
        sim.close()
        live.close()
    assert summary["error"] is None and dig.sample is not None
    assert dig.sample["sample_particles"] >= 1
    bulk_m3 = dig.sample["sample_volume_m3"] / dig.solid_fraction
    assert dig.sample["sample_bulk_volume_m3"] == pytest.approx(bulk_m3, rel=1e-12)
    # The dig began with an empty scoop: all that was excavated is the dig's content, which is
    # now the DEM's sample in bulk (or a full scoop), to the unit.
    capacity = sim.regolith.tracker.scoop.capacity_units
    expected = min(units_from_m3(bulk_m3), capacity)
    assert abs(budget[Account.EXCAVATED].units - expected) <= 1
    record = summary["regolith"]
    assert record["before_m3"] == pytest.approx(geometric * 1e-18, abs=1e-18)
    assert record["after_m3"] == pytest.approx(expected * 1e-18, abs=1e-18)
    assert geometric > 0 and record["before_m3"] != record["after_m3"]
    budget.check()
    # The terrain's own account holds too: cut from the column + deposited = loose + excavated.
    ledger = sim.regolith.tracker.ledger
    assert ledger.removed + budget[Account.DEPOSITED] == (
        ledger.loose_total() + budget[Account.EXCAVATED]
    )
