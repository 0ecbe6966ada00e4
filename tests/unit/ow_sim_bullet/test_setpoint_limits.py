"""Recovery from any state the simulation can reach: set-points beyond a joint's limits are
clipped onto it, non-finite ones ignored, a joint resting on its limit can be planned from, and
absurd terrain heights are refused (no ROS)."""

from __future__ import annotations

import math
import threading

import numpy as np
import pinocchio as pin
import pytest

from ow_description.description import (
    ARM_JOINTS,
    DEFAULT_GROUND_Z,
    EUROPA_GRAVITY,
    STOWED,
    UNSTOWED,
    URDF_PATH,
)
from ow_description.model import LanderModel
from ow_description.terrain import HeightMap
from ow_lander.config import PlannerConfig
from ow_lander.errors import PlanningError
from ow_lander.operations.planner import Operations
from ow_lander.planning.planner import ArmPlanner
from ow_lander.planning.validity import START_LIMIT_TOLERANCE_RAD
from ow_sim_bullet.config import SimConfig
from ow_sim_bullet.errors import CommandError, TerrainSpecError
from ow_sim_bullet.joint_control import ClippedSetpoint, JointController
from ow_sim_bullet.outputs import SimOutputs
from ow_sim_bullet.runner import SimRunner
from ow_sim_bullet.sim_core import BulletSim
from ow_sim_bullet.terrains import MAX_TERRAIN_HEIGHT_M, flat, load_file, parse_terrain_spec
from ow_sim_bullet.trajectory import JointTrajectory
from ow_sim_bullet.urdf import physical_inertias, read_urdf_joints

DT = 0.01
SHOU_YAW_LIMITS = (-1.8, 1.8)  # rad, the URDF's


def controller() -> JointController:
    text, _ = physical_inertias(URDF_PATH.read_text())
    model = pin.buildModelFromXML(text)
    model.gravity.linear = np.array([0.0, 0.0, -EUROPA_GRAVITY])
    return JointController(model, read_urdf_joints(text), SimConfig().gains, DT, True)


def stowed(ctrl: JointController) -> np.ndarray:
    return np.array([STOWED.get(j, 0.0) for j in ctrl.names])


# ---------------------------------------------------------------------------- set-points
@pytest.mark.parametrize(
    ("joint", "requested", "applied"),
    [
        ("j_shou_yaw", -1e9, -1.8),
        ("j_shou_yaw", 1e300, 1.8),
        ("j_shou_yaw", -1.8000001, -1.8),
        ("j_shou_pitch", -0.5, -0.4),
        ("j_ant_tilt", 4.0, 3.1416),
        ("j_grinder", -3.5, -3.2),
    ],
)
def test_a_setpoint_beyond_a_limit_is_clipped_onto_it(joint, requested, applied):
    ctrl = controller()
    ctrl.reset(stowed(ctrl))
    clipped = ctrl.set_setpoint(joint, requested)
    assert clipped == ClippedSetpoint(
        joint,
        requested,
        applied,
        *(float(b[ctrl.names.index(joint)]) for b in (ctrl.lower, ctrl.upper)),
    )
    assert ctrl.setpoint[ctrl.names.index(joint)] == applied
    assert f"set-point {requested:.6g} rad for {joint} is beyond its limits" in clipped.describe()
    assert f"clipped to {applied:.4g} rad" in clipped.describe()


@pytest.mark.parametrize("value", [-1.8, 0.0, 1.8, 1.7999])
def test_a_setpoint_within_the_limits_is_kept_exactly(value):
    ctrl = controller()
    assert ctrl.set_setpoint("j_shou_yaw", value) is None
    assert ctrl.setpoint[ctrl.names.index("j_shou_yaw")] == value


@pytest.mark.parametrize("value", [math.nan, math.inf, -math.inf])
def test_a_non_finite_setpoint_is_ignored(value):
    ctrl = controller()
    ctrl.reset(stowed(ctrl))
    before = ctrl.setpoint
    with pytest.raises(CommandError, match="not finite; command ignored"):
        ctrl.set_setpoint("j_shou_yaw", value)
    assert np.array_equal(ctrl.setpoint, before)


def test_trajectory_points_beyond_a_limit_are_followed_on_the_limit():
    ctrl = controller()
    q = stowed(ctrl)
    ctrl.reset(q)
    k = ctrl.names.index("j_shou_yaw")
    trajectory = JointTrajectory.build(
        ["j_shou_yaw", "j_hand_yaw"],
        0.0,
        [1.0, 2.0, 3.0],
        [[-1.7, 0.1], [-5.0, 0.2], [-1.6, 0.3]],
        [[0.0, 0.0], [-1.0, 0.0], [0.0, 0.0]],
        ctrl.names,
    )
    clipped = ctrl.set_trajectory(trajectory, 0.0)
    assert clipped == [ClippedSetpoint("j_shou_yaw", -5.0, -1.8, -1.8, 1.8)]
    lowest, moving_below = np.inf, 0
    for step in range(400):
        v_set = ctrl.follow(step * DT)
        lowest = min(lowest, float(ctrl.setpoint[k]))
        if ctrl.setpoint[k] == -1.8 and v_set[k] != 0.0:
            moving_below += 1
    assert lowest == -1.8  # reached the limit, never beyond
    assert moving_below == 0  # held on the limit, the set-point velocity is 0
    assert ctrl.setpoint[k] == pytest.approx(-1.6)  # the trajectory's end, within the limits


def test_a_trajectory_within_the_limits_reports_nothing():
    ctrl = controller()
    trajectory = JointTrajectory.build(["j_shou_yaw"], 0.0, [1.0], [[-1.8]], None, ctrl.names)
    assert ctrl.set_trajectory(trajectory, 0.0) == []


class _NoOutputs(SimOutputs):
    def __init__(self) -> None:  # nothing to publish to
        pass

    def publish(self, force: bool = False) -> None:
        pass

    def after_step(self, lockstep: bool = False) -> None:
        pass

    def publish_standing(self, terrain: bool = True) -> None:
        pass

    def flush(self, only=None) -> None:
        pass

    def publish_terrain_if_due(self) -> None:
        pass


@pytest.fixture(scope="module")
def sim():
    simulation = BulletSim(SimConfig(), flat(DEFAULT_GROUND_Z))
    yield simulation
    simulation.close()


def test_the_runner_reports_what_it_did_with_each_command(sim):
    runner = SimRunner(sim, _NoOutputs(), 0.0, True, lambda: False)
    warnings: list[str] = []
    applied: list[float | None] = []
    runner.command_setpoint("j_shou_yaw", math.nan, warnings.append, applied.append)
    runner.command_setpoint("j_shou_yaw", -1e9, warnings.append, applied.append)
    runner.command_setpoint("j_shou_yaw", -1.5, warnings.append, applied.append)
    receipts: list[float | None] = []
    runner.command_trajectory(
        lambda now, names: JointTrajectory.build(["j_elbow"], now, [1.0], [[0.0]], None, names),
        warnings.append,
        receipts.append,
    )
    runner.command_trajectory(
        lambda now, names: JointTrajectory.build(
            ["j_shou_pitch"], now, [1.0], [[9.0]], None, names
        ),
        warnings.append,
        receipts.append,
    )
    thread = threading.Thread(target=runner.run, daemon=True)
    thread.start()
    runner.step_paused(1)  # the commands run before the step
    runner.stop()
    thread.join(timeout=10.0)
    assert len(warnings) == 4
    assert "set-point nan for j_shou_yaw is not finite; command ignored" in warnings[0]
    assert "set-point -1e+09 rad for j_shou_yaw is beyond its limits [-1.8, 1.8] rad" in warnings[1]
    assert "trajectory ignored: trajectory names unknown joint(s) ['j_elbow']" in warnings[2]
    assert warnings[3].startswith("trajectory set-point 9 rad for j_shou_pitch is beyond")
    # The receipts: None for the ignored one, the start (the paused clock) for the queued one.
    assert receipts == [None, sim.time - sim.dt]
    # The set-points': None for the ignored one, the paused clock for the clipped and the other.
    assert applied == [None, sim.time - sim.dt, sim.time - sim.dt]
    sim.reset()


def test_a_huge_setpoint_drives_the_joint_onto_its_limit_and_no_further(sim):
    """The hostile test's command, 1e9 rad on the shoulder yaw (+: at -1.8 rad the planner's
    collision model puts the proximal link inside the lander body, see docs/simulation.md). The
    joint stops on its limit, not pressed beyond it by a saturated motor, and the planner plans
    from there."""
    sim.reset()
    for joint, value in UNSTOWED.items():
        sim.set_setpoint(joint, value)
    for _ in range(round(20.0 / sim.dt)):
        sim.step()
    k = sim.names.index("j_shou_yaw")
    assert sim.set_setpoint("j_shou_yaw", 1e9) is not None
    for _ in range(round(25.0 / sim.dt)):
        sim.step()
    position = float(sim.sample.position[k])
    assert position == pytest.approx(1.8, abs=0.01)
    assert sim.sample.setpoint[k] == 1.8
    model = LanderModel()
    q = model.q_from(dict(zip(sim.names, sim.sample.position.tolist(), strict=True)))
    plan = Operations(ArmPlanner(model, PlannerConfig())).plan(
        "stow", q, HeightMap.flat(DEFAULT_GROUND_Z)
    )
    assert plan.segments[0].waypoints[0][ARM_JOINTS.index("j_shou_yaw")] <= 1.8
    sim.reset()


# ---------------------------------------------------------------------------- planning start
@pytest.fixture(scope="module")
def planner():
    return ArmPlanner(LanderModel(), PlannerConfig())


@pytest.mark.parametrize(
    ("measured", "start"),
    [
        (1.8, 1.8),
        (1.8003, 1.8),  # resting on the hard stop, a hair beyond
        (1.8 + START_LIMIT_TOLERANCE_RAD, 1.8),
        (1.83, 1.8),
        (1.5, 1.5),  # within the limits: unchanged
    ],
)
def test_a_start_a_hair_beyond_a_limit_is_planned_from_the_limit(planner, measured, start):
    q = planner.model.q_from({**UNSTOWED, "j_shou_yaw": measured})
    arm = planner.arm(q)
    assert arm[ARM_JOINTS.index("j_shou_yaw")] == start
    assert planner.within_limits(arm)
    ops = Operations(planner)
    plan = ops.plan("stow", q, HeightMap.flat(DEFAULT_GROUND_Z))
    assert plan.segments[0].waypoints[0][ARM_JOINTS.index("j_shou_yaw")] == start


def test_a_start_well_beyond_a_limit_is_still_refused_with_the_reason(planner):
    q = planner.model.q_from({**UNSTOWED, "j_shou_yaw": 1.8 + 2 * START_LIMIT_TOLERANCE_RAD})
    ops = Operations(planner)
    with pytest.raises(PlanningError, match=r"j_shou_yaw=1.900 rad is outside \[-1.800, 1.800\]"):
        ops.plan("stow", q, HeightMap.flat(DEFAULT_GROUND_Z))


# ---------------------------------------------------------------------------- terrain specs
@pytest.mark.parametrize(
    ("spec", "message"),
    [
        ("flat:1e308", "height 1e+308 m is outside the sane range [-10, 10] m"),
        ("flat:-10.5", "height -10.5 m is outside the sane range [-10, 10] m"),
        ("flat:11", "height 11 m is outside the sane range [-10, 10] m"),
        ("flat:nan", "flat height 'nan' is not a finite number"),
        ("flat:-inf", "flat height '-inf' is not a finite number"),
    ],
)
def test_absurd_flat_heights_are_refused_naming_value_and_limit(spec, message):
    with pytest.raises(TerrainSpecError) as error:
        parse_terrain_spec(spec)
    assert message in str(error.value)
    assert spec in str(error.value)


@pytest.mark.parametrize("z", [-MAX_TERRAIN_HEIGHT_M, -0.155, 0.0, MAX_TERRAIN_HEIGHT_M])
def test_sane_flat_heights_are_accepted(z):
    assert np.all(parse_terrain_spec(f"flat:{z}").heights == z)


@pytest.mark.parametrize(
    ("bad", "message"),
    [
        (1e308, "height 1e+308 m at cell (2, 3) is outside the sane range [-10, 10] m"),
        (-12.0, "height -12 m at cell (2, 3) is outside the sane range [-10, 10] m"),
        (math.nan, "non-finite height"),
    ],
)
def test_files_with_absurd_heights_are_refused(tmp_path, bad, message):
    heights = np.full((5, 6), -0.155)
    heights[2, 3] = bad
    path = tmp_path / "map.npy"
    np.save(path, heights)
    with pytest.raises(TerrainSpecError) as error:
        load_file(path, 0.04, (1.5, 0.0), (-1.0, 1.0))
    assert f"terrain file {path}: " in str(error.value)
    assert message in str(error.value)
