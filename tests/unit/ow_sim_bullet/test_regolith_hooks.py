"""The simulation's regolith hooks (docs/regolith.md, "Integration"): the carver tells each cut's
window and raises cells under deposits, the simulation feeds the regolith at each carve update
(only while the scoop digs or holds regolith), the budget goes out at each change, and a dig, a
spill and a pour into the dock keep the budget exact, the same in two runs."""

from __future__ import annotations

import math

import numpy as np
import pybullet as pb
import pytest

from ow_description.description import DEFAULT_GROUND_Z, UNSTOWED
from ow_description.model import LanderModel
from ow_description.terrain import HeightMap
from ow_lander.config import PlannerConfig, TimingConfig
from ow_lander.operations.planner import Operations
from ow_lander.planning.planner import ArmPlanner
from ow_msgs.msg import RegolithBudget
from ow_regolith.budget import Account
from ow_regolith.materials import Bulk
from ow_sim_bullet.carving import TerrainCarver
from ow_sim_bullet.config import SimConfig
from ow_sim_bullet.errors import ConfigError
from ow_sim_bullet.outputs import WIRE_TOPICS, SimOutputs
from ow_sim_bullet.sim_core import BulletSim
from ow_sim_bullet.terrains import flat
from ow_sim_bullet.trajectory import JointTrajectory

GROUND = DEFAULT_GROUND_Z
#: The simulation starting unstowed (a dig is planned from there).
CONFIG = SimConfig(initial_positions={**SimConfig().initial_positions, **UNSTOWED})
#: m, base_link: above the middle of the sample dock's box (0.555, -0.35, 0.65; 5 cm tall).
ABOVE_DOCK = np.array([0.555, -0.35, 0.70])


# ------------------------------------------------------------------------------ the carver
class FakeSurface:
    """Records the carver's refreshes of the simulator's surface."""

    floor = GROUND - 0.5

    def __init__(self) -> None:
        self.refreshed: list[tuple[tuple[int, int], tuple[int, int]]] = []

    def refresh(self, heights: np.ndarray, rows: tuple[int, int], cols: tuple[int, int]) -> int:
        self.refreshed.append((rows, cols))
        return 1

    def remove(self) -> None:
        """Nothing to remove."""


def plate() -> np.ndarray:
    """(3, n) m, a 10 cm square plate of points (z = 0 in its own frame)."""
    axis = np.arange(-0.05, 0.05 + 1e-9, 0.01)
    x, y = np.meshgrid(axis, axis)
    return np.stack((x.ravel(), y.ravel(), np.zeros(x.size)))


@pytest.fixture()
def carver() -> tuple[TerrainCarver, FakeSurface]:
    surface = FakeSurface()
    ground = HeightMap(np.full((51, 76), GROUND), 0.04, -0.5, -0.8)
    return TerrainCarver(ground, SimConfig(), {"scoop": plate()}, lambda _: surface), surface


def test_a_cut_tells_the_window_it_lowered_before_and_after(carver):
    terrain, _ = carver
    before = terrain.heightmap.heights
    window = terrain.cut("scoop", np.eye(3), np.array([1.0, 0.2, GROUND]), 50.0, True)
    after = terrain.heightmap.heights
    assert window is not None
    (r0, c0), (h, w) = window.offset, window.before.shape
    assert np.array_equal(window.before, before[r0 : r0 + h, c0 : c0 + w])
    assert np.array_equal(window.after, after[r0 : r0 + h, c0 : c0 + w])
    changed = np.argwhere(after != before)
    assert len(changed) and changed.min(axis=0).tolist() == [r0, c0]
    assert changed.max(axis=0).tolist() == [r0 + h - 1, c0 + w - 1]
    assert np.all(window.after <= window.before)
    assert np.allclose(window.after.min(), GROUND - SimConfig().carve_step)


def test_a_tool_that_cuts_nothing_tells_no_window(carver):
    terrain, surface = carver
    assert terrain.cut("scoop", np.eye(3), np.array([1.0, 0.2, GROUND + 0.2]), 50.0, True) is None
    # On solid ground (not digging) a tool resting on it cuts nothing either.
    assert terrain.cut("scoop", np.eye(3), np.array([1.0, 0.2, GROUND]), 50.0, False) is None
    assert not terrain.commit() and not surface.refreshed


def test_raised_cells_rise_and_reach_the_surface_at_commit(carver):
    terrain, surface = carver
    version = terrain.version
    point = np.array([0.5, 0.0, GROUND + 0.01])
    assert terrain.above(point)
    terrain.raise_cells(
        np.array([20, 20, 21]), np.array([25, 25, 30]), np.array([0.01, 0.01, 0.02])
    )
    heights = terrain.heightmap.heights
    assert heights[20, 25] == pytest.approx(GROUND + 0.02)  # two raises of one cell add up
    assert heights[21, 30] == pytest.approx(GROUND + 0.02)
    assert np.count_nonzero(heights != GROUND) == 2
    assert not terrain.above(point)  # the bound above the terrain rose with it
    assert terrain.commit() and terrain.version == version + 1
    assert surface.refreshed == [((20, 21), (25, 30))]


@pytest.mark.parametrize(
    ("rows", "cols", "raise_m", "match"),
    [
        ([1, 2], [1], [0.01], r"2 rows, 1 columns and 1 raises differ"),
        ([51], [0], [0.01], r"rows 51\.\.51, columns 0\.\.0 are not all within the 51 x 76"),
        ([0], [-1], [0.01], r"within the 51 x 76 height map"),
        ([0, 1], [0, 0], [0.01, -0.02], r"finite and >= 0 m, got -0\.02 m"),
        ([0], [0], [math.nan], r"got nan m"),
    ],
)
def test_a_bad_raise_is_refused_naming_it(carver, rows, cols, raise_m, match):
    terrain, _ = carver
    with pytest.raises(ValueError, match=match):
        terrain.raise_cells(np.array(rows), np.array(cols), np.array(raise_m))
    assert np.all(terrain.heightmap.heights == GROUND) and not terrain.commit()


def test_lowered_cells_fall_and_reach_the_surface_at_commit(carver):
    terrain, surface = carver
    terrain.lower_cells(np.array([20, 21]), np.array([25, 30]), np.array([0.01, 0.03]))
    heights = terrain.heightmap.heights
    assert heights[20, 25] == pytest.approx(GROUND - 0.01)
    assert heights[21, 30] == pytest.approx(GROUND - 0.03)
    assert np.count_nonzero(heights != GROUND) == 2
    assert terrain.commit() and surface.refreshed == [((20, 21), (25, 30))]


@pytest.mark.parametrize(
    ("lower_m", "match"),
    [
        (-0.01, r"a lowering must be finite and >= 0 m, got -0\.01 m"),
        (0.6, r"a lowering of up to 0\.6 m goes below the floor"),
    ],
)
def test_a_bad_lowering_is_refused_naming_it(carver, lower_m, match):
    terrain, _ = carver
    with pytest.raises(ValueError, match=match):
        terrain.lower_cells(np.array([3]), np.array([4]), np.array([lower_m]))
    assert np.all(terrain.heightmap.heights == GROUND) and not terrain.commit()


# ------------------------------------------------------------------------- the simulation
class Budgets:
    """Records the budget messages the outputs publish."""

    def __init__(self) -> None:
        self.messages: list[RegolithBudget] = []

    def publish(self, msg: RegolithBudget) -> None:
        self.messages.append(msg)


class Dropping:
    """A wire publisher without subscribers."""

    def publish(self, serialize, *args) -> None:
        """Nothing built."""

    def flush(self, only=None) -> None:
        """Nothing queued."""


def outputs_of(sim: BulletSim, budgets: Budgets) -> SimOutputs:
    publishers = {topic: Dropping() for topic, _ in WIRE_TOPICS}
    return SimOutputs(sim, sim.config, publishers, Budgets(), [], budget=budgets)


def pouring_over(sim: BulletSim, point: np.ndarray) -> np.ndarray:
    """``X_base_scoop`` tipped a right angle (it keeps nothing) pouring at ``point``."""
    geometry = sim.regolith.tracker.scoop
    X = np.eye(4)
    X[:3, :3] = geometry.tilted(math.pi / 2)
    X[:3, 3] = point - geometry.pour_point(X)
    return X


def test_the_budget_goes_out_at_start_and_at_each_change_only():
    sim = BulletSim(SimConfig(), flat(GROUND))
    try:
        budgets = Budgets()
        outputs = outputs_of(sim, budgets)
        for _ in range(20):
            sim.step()
            outputs.publish()
        assert len(budgets.messages) == 1  # the first publication
        sample = Bulk.of("irradiated", "ICE", 3 * 10**12) + Bulk.of("pristine", "SALT", 10**12)
        sim.regolith.tracker.budget.excavate(sample)  # as a dig would have
        assert sim.regolith.scoop_moved(pouring_over(sim, ABOVE_DOCK), False).rows.size == 0
        outputs.publish()
        outputs.publish()
        assert len(budgets.messages) == 2
        assert sim.regolith.ingest() == sample
        assert sim.regolith.ingest() == Bulk()  # nothing left: no change
        outputs.publish_budget_if_changed()
        assert len(budgets.messages) == 3
        first, poured, ingested = budgets.messages
        assert first.excavated.volume_um3 == 0
        assert (poured.in_dock.volume_um3, poured.in_scoop.volume_um3) == (4 * 10**12, 0)
        assert poured.excavated.volume_um3 == 4 * 10**12
        assert ingested.in_dock.volume_um3 == 0
        assert ingested.ingested.volume == pytest.approx(4e-6)
        assert (ingested.layers, ingested.top_layer) == (["irradiated", "pristine"], "irradiated")
        assert ingested.materials == ["ICE", "MG_HYDRATES", "SALT"]
        assert ingested.ingested.layer_volumes == pytest.approx([3e-6, 1e-6])
        assert ingested.ingested.material_volumes == pytest.approx([3e-6, 0.0, 1e-6])
        assert ingested.ingested.mass == pytest.approx(3e-6 * 997.0 + 1e-6 * 2160.0)
        assert ingested.header.stamp.to_sec() == pytest.approx(sim.time)
    finally:
        sim.close()


def test_nothing_digging_and_an_empty_scoop_leave_the_regolith_alone(monkeypatch):
    """Off the hot path: holding the arm, the regolith is not even asked."""
    sim = BulletSim(SimConfig(), flat(GROUND))
    try:
        calls: list[str] = []
        for hook in ("scoop_moved", "terrain_cut"):
            monkeypatch.setattr(sim.regolith, hook, lambda *_, h=hook: calls.append(h))
        for _ in range(200):
            sim.step()
        assert calls == []
        assert sim.regolith.version == 0
    finally:
        sim.close()


def test_a_regolith_scoop_link_the_urdf_lacks_is_a_config_error():
    config = SimConfig.from_dict({"regolith": {"scoop": {"link": "l_spoon"}}})
    with pytest.raises(ConfigError, match=r"regolith/scoop/link 'l_spoon' is not a link"):
        BulletSim(config, flat(GROUND))


def test_a_bad_regolith_parameter_is_named_with_the_sims_key():
    with pytest.raises(ConfigError, match=r"sim/regolith/deposit_radius = 0 m is outside"):
        SimConfig.from_dict({"regolith": {"deposit_radius": 0.0}})


# ------------------------------------------------------------------ a dig on the real arm
@pytest.fixture(scope="module")
def ops() -> Operations:
    return Operations(ArmPlanner(LanderModel(), PlannerConfig()))


def _follow(sim: BulletSim, ops: Operations, name: str, request: dict) -> None:
    """Plan ``name`` from where the simulated arm is and follow it to its end (+1 s)."""
    q = ops.model.q_from(dict(zip(sim.names, sim.sample.position.tolist(), strict=True)))
    plan = ops.plan(name, q, sim.heightmap, request)
    timed = plan.timed(TimingConfig(), ops.planner.velocity_limits)
    sim.set_trajectory(JointTrajectory.from_plan(timed, sim.time, sim.names))
    for _ in range(round((timed.duration + 1.0) / sim.dt)):
        sim.step()


def dig_and_spill(ops: Operations) -> tuple[dict[Account, Bulk], np.ndarray, list[float]]:
    """A linear dig 5 cm deep on flat ground: (the budget's accounts after it, the height map,
    the z a ray meets at every carve update where the terrain rose)."""
    sim = BulletSim(CONFIG, flat(GROUND))
    try:
        request = dict(x=1.65, y=0.0, depth=0.05, length=0.2, ground_position=GROUND)
        _follow(sim, ops, "dig_linear", request)
        sim.regolith.tracker.budget.check()
        ledger = sim.regolith.tracker.ledger.heightmap.heights
        assert np.array_equal(ledger, sim.heightmap.heights)  # the two maps in step, exactly
        heights = sim.heightmap.heights
        r, c = np.unravel_index(np.argmax(heights), heights.shape)
        hm = sim.heightmap
        x, y = hm.origin_x + c * hm.resolution, hm.origin_y + r * hm.resolution
        hit = pb.rayTest([x, y, 1.0], [x, y, -1.0], physicsClientId=sim.client)[0]
        return sim.regolith.snapshot().accounts, heights, [hit[3][2], float(heights[r, c])]
    finally:
        sim.close()


@pytest.fixture(scope="module")
def dug(ops):
    return dig_and_spill(ops)


def test_a_dig_fills_the_scoop_from_the_trench_and_what_spills_heaps_on_the_terrain(dug):
    accounts, heights, (ray_z, top_z) = dug
    excavated = accounts[Account.EXCAVATED]
    capacity = 6.68e-4  # m^3, the scoop's cavity (docs/regolith.md)
    # The 20 cm cut 5 cm deep is more than the scoop holds: it filled up.
    assert excavated.volume_m3 == pytest.approx(capacity, rel=0.01)
    # All of it from the irradiated top layer (the cut is 5 cm deep of its 10 cm), by its
    # composition.
    assert excavated.by_layer().keys() == {"irradiated"}
    shares = {name: float(share) for name, share in excavated.composition().items()}
    assert shares == pytest.approx({"ICE": 0.85, "MG_HYDRATES": 0.10, "SALT": 0.05}, abs=1e-9)
    # The dig ends with the scoop curled level: the wedge it cannot keep (its lip plane is
    # pitched 2 degrees, docs/regolith.md) spilled beside the trench.
    held, deposited = accounts[Account.IN_SCOOP], accounts[Account.DEPOSITED]
    assert held.units + deposited.units == excavated.units
    assert 0 < deposited.units < excavated.units
    assert accounts[Account.IN_DOCK].is_empty and accounts[Account.SPILLED].is_empty
    # The heap raised the terrain (the trench is lower), and Bullet's surface is the raised one.
    assert heights.max() > GROUND and heights.min() < GROUND - 0.04
    assert ray_z == pytest.approx(top_z, abs=1e-6)


def test_the_same_dig_gives_the_same_budget_and_terrain_to_the_unit(dug, ops):
    accounts, heights, _ = dug
    again, heights_again, _ = dig_and_spill(ops)
    assert again == accounts
    assert np.array_equal(heights_again, heights)
