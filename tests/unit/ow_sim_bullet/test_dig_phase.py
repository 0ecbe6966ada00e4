"""When the terrain gives way (issue "Arm compatibility", item 4): the scoop's dig phase from its
tip's pose and motion (OceanWATERS' DigStateMachine, spec 14.2), the grinder grinding, and the
simulation carving only under a tool that digs: a dig cuts its trench, a tool pressed into the
ground elsewhere meets solid ground."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pinocchio as pin
import pybullet as pb
import pytest

from ow_dem_bridge.api import Wrench
from ow_description.description import DEFAULT_GROUND_Z, EUROPA_GRAVITY, UNSTOWED, URDF_PATH
from ow_description.model import LanderModel
from ow_description.terrain import HeightMap
from ow_lander.config import PlannerConfig, TimingConfig
from ow_lander.operations.planner import Operations
from ow_lander.planning.planner import ArmPlanner
from ow_sim_bullet.carving import TerrainCarver
from ow_sim_bullet.config import SimConfig
from ow_sim_bullet.sim_core import BulletSim
from ow_sim_bullet.terrains import flat
from ow_sim_bullet.tool_forces import ToolForces
from ow_sim_bullet.tool_tracking import (
    MOTION_WINDOW_S,
    DigPhase,
    ScoopDigDetector,
    ToolTracker,
)
from ow_sim_bullet.trajectory import JointTrajectory

GROUND = DEFAULT_GROUND_Z
CONFIG = SimConfig()
DT = CONFIG.carve_period  # s, the detector is updated at each carve update
NOT, SINKING, PLOWING, RETRACTING = DigPhase


class FakeSurface:
    floor = -1.0

    def refresh(self, heights: np.ndarray, rows: tuple[int, int], cols: tuple[int, int]) -> int:
        return 0

    def remove(self) -> None:
        """Nothing to remove."""


@pytest.fixture()
def terrain() -> TerrainCarver:
    ground = HeightMap.flat(GROUND, half_extent=3.0, resolution=0.04)
    return TerrainCarver(ground, CONFIG, {}, lambda _: FakeSurface())


def scoop(pitch: float) -> np.ndarray:
    """(3, 3) orientation of l_scoop_tip with its mouth (+x) along base x pitched down by
    ``pitch`` rad and its bottom (+z) perpendicular to it, facing down (0: a level scoop)."""
    forward = np.array([math.cos(pitch), 0.0, -math.sin(pitch)])
    bottom = np.array([-math.sin(pitch), 0.0, -math.cos(pitch)])
    return np.column_stack([forward, np.cross(bottom, forward), bottom])


def path(*corners: tuple[float, float], speed: float = 0.04) -> list[np.ndarray]:
    """Tip positions every DT along straight lines through the corners (x, height above the
    ground) m at ``speed`` m/s, at y = 0."""
    points = [np.array([corners[0][0], 0.0, GROUND + corners[0][1]])]
    for (x0, h0), (x1, h1) in itertools.pairwise(corners):
        a, b = np.array([x0, 0.0, GROUND + h0]), np.array([x1, 0.0, GROUND + h1])
        n = max(1, round(float(np.linalg.norm(b - a)) / (speed * DT)))
        points += [a + (b - a) * (i / n) for i in range(1, n + 1)]
    return points


def run(
    detector: ScoopDigDetector,
    terrain: TerrainCarver,
    rotation: np.ndarray,
    points: list[np.ndarray],
    start: float = 0.0,
) -> list[tuple[float, DigPhase, float]]:
    """(time s, phase, tip height above the ground m) after each update along ``points``."""
    return [
        (start + k * DT, detector.update(start + k * DT, rotation, p, terrain), p[2] - GROUND)
        for k, p in enumerate(points)
    ]


def phases(trace: list[tuple[float, DigPhase, float]]) -> list[DigPhase]:
    """The phases of a trace in order, each once per stay."""
    out: list[DigPhase] = []
    for _, phase, _ in trace:
        if not out or out[-1] is not phase:
            out.append(phase)
    return out


@pytest.mark.parametrize("pitch_deg", [15, 30, 45])
def test_a_linear_dig_sinks_plows_retracts_and_ends_out_of_the_ground(terrain, pitch_deg):
    """The arm's linear dig: mouth pitched down, in at 45 degrees from 5 cm above the ground
    to 5 cm below, a 15 cm cut, out at 45 degrees, then straight up."""
    detector = ScoopDigDetector(CONFIG)
    corners = ((1.5, 0.05), (1.6, -0.05), (1.75, -0.05), (1.85, 0.05), (1.85, 0.25))
    trace = run(detector, terrain, scoop(math.radians(pitch_deg)), path(*corners))
    assert phases(trace) == [NOT, SINKING, PLOWING, RETRACTING, NOT]
    # The dig starts at the ground (within dig_exit_clearance above it), not in the air...
    start = next(height for _, phase, height in trace if phase is SINKING)
    assert 0.0 < start <= CONFIG.dig_exit_clearance + 0.04 * DT
    # ...and ends once the tip has left it.
    ends = zip(trace[1:], trace, strict=False)
    end = next(h for (_, phase, h), (_, before, _) in ends if phase is NOT and before.digging)
    assert end > CONFIG.dig_exit_clearance
    plowing = [height for _, phase, height in trace if phase is PLOWING]
    assert max(plowing) < 0.0  # the cut


NO_DIG = [
    # A level scoop pushed straight down (a guarded move, ArmFindSurface).
    ("bottom_first", 0.0, ((1.6, 0.1), (1.6, -0.1))),
    # The tip stabbed straight down with the bottom vertical (the unstowed scoop moved down):
    # OceanWATERS' 90 degree sink angle would take it for a dig, and a scoop 0.1 degree off
    # vertical too.
    ("stab", math.pi / 2, ((1.6, 0.1), (1.6, -0.1))),
    # Mouth first into the ground, but backwards: dragged against its mouth.
    ("dragged_backwards", math.radians(30), ((1.8, 0.05), (1.7, -0.05), (1.5, -0.05))),
    # Mouth first as in a dig, but in the air.
    ("in_the_air", math.radians(30), ((1.5, 0.3), (1.7, 0.1), (1.9, 0.1))),
]


@pytest.mark.parametrize(("name", "pitch", "corners"), NO_DIG, ids=[c[0] for c in NO_DIG])
def test_motions_that_are_no_dig_leave_the_terrain_solid(terrain, name, pitch, corners):
    trace = run(ScoopDigDetector(CONFIG), terrain, scoop(pitch), path(*corners))
    assert phases(trace) == [NOT]


def test_a_dig_stopped_in_the_ground_ends_after_the_timeout(terrain):
    detector = ScoopDigDetector(CONFIG)
    rotation = scoop(math.radians(30))
    trace = run(detector, terrain, rotation, path((1.5, 0.05), (1.6, -0.05), (1.65, -0.05)))
    assert trace[-1][1] is PLOWING
    stopped = trace[-1][0]
    here = path((1.65, -0.05))[0]
    # A pause shorter than dig_timeout: the cut goes on when the scoop moves again.
    pause = run(detector, terrain, rotation, [here] * 40, stopped + DT)
    assert phases(pause) == [PLOWING]
    resumed = run(detector, terrain, rotation, path((1.65, -0.05), (1.7, -0.05)), pause[-1][0])
    assert phases(resumed) == [PLOWING]
    # Standing still for dig_timeout: no dig. The tip's velocity is its displacement over
    # MOTION_WINDOW_S, so it reads still a window after it stopped.
    stopped = resumed[-1][0]
    still = run(detector, terrain, rotation, [path((1.7, -0.05))[0]] * 200, stopped + DT)
    ended = next(t for t, phase, _ in still if phase is NOT)
    expected = CONFIG.dig_timeout + MOTION_WINDOW_S - DT
    assert ended - stopped == pytest.approx(expected, abs=DT + 1e-9)
    detector.reset()
    assert detector.phase is NOT


def test_the_thresholds_come_from_the_config(terrain):
    """With a 90 degree sink angle (OceanWATERS') the stab is a dig."""
    stab = path((1.6, 0.1), (1.6, -0.1))
    tilted = scoop(math.pi / 2 - 0.002)  # the bottom 0.1 degree from vertical, facing down
    assert phases(run(ScoopDigDetector(CONFIG), terrain, tilted, stab)) == [NOT]
    oceanwaters = SimConfig(dig_sink_angle=math.pi / 2)
    assert SINKING in phases(run(ScoopDigDetector(oceanwaters), terrain, tilted, stab))


# ---------------------------------------------------------------------- the grinder and the sim
@pytest.fixture(scope="module")
def ops() -> Operations:
    return Operations(ArmPlanner(LanderModel(), PlannerConfig()))


def test_the_grinder_grinds_pointing_down_and_moving(ops):
    model = pin.buildModelFromUrdf(str(URDF_PATH))
    model.gravity.linear = np.array([0.0, 0.0, -EUROPA_GRAVITY])
    ground = HeightMap.flat(GROUND, half_extent=3.0, resolution=0.04)
    tracker = ToolTracker(
        model,
        ToolForces({"scoop": 10, "grinder": 11}),
        {"scoop": np.zeros(3), "grinder": np.zeros(3)},
        TerrainCarver(ground, CONFIG, {}, lambda _: FakeSurface()),
        CONFIG,
        frames=[frame.name for frame in model.frames],
    )
    q0 = ops.model.q_from(UNSTOWED)
    request = dict(x=1.65, y=0.0, depth=0.05, length=0.3, parallel=True, ground_position=GROUND)
    plan = ops.plan_grind(q0, ground, request)
    pass_1 = next(s for s in plan.segments if s.label == "pass_1").waypoints
    moving = np.linspace(pass_1[0], pass_1[-1], 40)  # 1 cm per update: 0.2 m/s
    still = [pass_1[-1]] * 10
    # The scoop's cut of a linear dig: the grinder moves along, pointing 64 degrees up.
    dig = ops.plan_dig_linear(q0, ground, {k: v for k, v in request.items() if k != "parallel"})
    cut = next(s for s in dig.segments if s.label == "cut").waypoints
    grinding = []
    for k, arm in enumerate([*moving, *still, *np.linspace(cut[0], cut[-1], 40)]):
        tracker.update_digging(ops.planner.full(arm, q0), k * DT)
        grinding.append((tracker.grinding, tracker.digs("grinder"), tracker.digs("scoop")))
    assert all(g == (True, True, False) for g in grinding[1:40])
    window = math.ceil(MOTION_WINDOW_S / DT)
    assert all(g == (False, False, False) for g in grinding[40 + window : 50])
    assert not any(g for g, _, _ in grinding[50:])  # moving, but not pointing down


def _execute(sim: BulletSim, ops: Operations, name: str, request: dict | None = None) -> float:
    """Plan ``name`` from where the simulated arm is, follow it; the trajectory's duration s."""
    q = ops.model.q_from(dict(zip(sim.names, sim.sample.position.tolist(), strict=True)))
    plan = ops.plan(name, q, sim.heightmap, request or {})
    trajectory = plan.timed(TimingConfig(), ops.planner.velocity_limits)
    sim.set_trajectory(JointTrajectory.from_plan(trajectory, sim.time, sim.names))
    return trajectory.duration


def test_a_linear_dig_cuts_its_trench_and_carves_only_while_digging(ops):
    sim = BulletSim(CONFIG, flat(GROUND))
    try:
        for _ in range(round(_execute(sim, ops, "unstow") / sim.dt)):
            sim.step()
        request = dict(x=1.65, y=0.0, depth=0.05, length=0.2, ground_position=GROUND)
        seen, carved_while = [], set()
        for _ in range(round((_execute(sim, ops, "dig_linear", request) + 1.0) / sim.dt)):
            version, before = sim.terrain_version, sim.heightmap.heights
            sim.step()
            # Lowered: regolith the scoop spills on the terrain after the dig raises it.
            if sim.terrain_version != version and np.any(sim.heightmap.heights < before):
                carved_while.add(sim.dig_phase)
            if not seen or seen[-1] is not sim.dig_phase:
                seen.append(sim.dig_phase)
        assert seen == [NOT, SINKING, PLOWING, RETRACTING, NOT]
        assert carved_while and not any(phase is NOT for phase in carved_while)
        # The trench is at the requested depth along the cut, and it stays: Bullet's surface is
        # the carved one.
        cut = [sim.terrain_height(x, 0.0) for x in np.linspace(1.67, 1.83, 9)]
        assert np.allclose(cut, GROUND - 0.05, atol=0.005)
        hit = pb.rayTest([1.75, 0.0, 1.0], [1.75, 0.0, -1.0], physicsClientId=sim.client)[0]
        assert hit[3][2] == pytest.approx(sim.terrain_height(1.75, 0.0), abs=0.005)
    finally:
        sim.close()


class EndRecordingLiveModel:
    """A live (lockstep) terrain-force model that answers no force and records when it was
    asked and when the simulation told it the dig ended (the simulation's time and phase)."""

    def __init__(self) -> None:
        self.sim: BulletSim | None = None
        self.asked: list[tuple[float, bool]] = []
        self.ended: list[tuple[float, DigPhase]] = []
        self._finished: list[dict] = []
        self._terrain = None

    def attach(self, terrain, step_s, loose_top=None) -> None:
        self._terrain = terrain

    def material_top(self, x: float, y: float) -> float:
        return self._terrain.height_at(x, y)

    def wrench(self, state):
        self.asked.append((state.time, bool(state.digging)))
        return Wrench(np.zeros(3), np.zeros(3))

    def dig_ended(self) -> None:
        assert self.sim is not None
        self.ended.append((self.sim.time, self.sim.dig_phase))
        self._finished.append({"start_time": 0.0, "ended_at": self.sim.time})

    def take_finished(self) -> list[dict]:
        done, self._finished = self._finished, []
        return done

    def close(self) -> None:
        """Nothing runs beside."""


def test_a_live_model_is_told_once_when_the_dig_phase_ends(ops):
    """The live DEM counts its sample when the scoop's dig phase ends (not at the next dig's
    start, which a mission's last dig never has): the simulation tells it once per dig, at
    the carve update where the phase turned NOT_DIGGING, after every state it was asked about
    in the dig."""
    live = EndRecordingLiveModel()
    sim = BulletSim(CONFIG, flat(GROUND), force_model=live)
    live.sim = sim
    try:
        for _ in range(round(_execute(sim, ops, "unstow") / sim.dt)):
            sim.step()
        assert live.ended == []
        request = dict(x=1.65, y=0.0, depth=0.05, length=0.2, ground_position=GROUND)
        turned = []
        for _ in range(round((_execute(sim, ops, "dig_linear", request) + 1.0) / sim.dt)):
            before = sim.dig_phase
            sim.step()
            if before.digging and not sim.dig_phase.digging:
                turned.append(sim.time)
        assert len(turned) == 1
        assert live.ended == [(turned[0], NOT)]
        digging = [t for t, d in live.asked if d]
        assert digging and max(digging) < turned[0]
        # The dig it finished waits, stamped at that carve update, for the outputs to publish
        # (/sim/dem_digs); the model gives each once.
        assert sim.finished_dem_digs == [(turned[0], {"start_time": 0.0, "ended_at": turned[0]})]
        assert live.take_finished() == []
    finally:
        sim.close()
