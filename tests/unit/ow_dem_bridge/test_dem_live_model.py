"""The live DEM (``terrain_forces: yade``): a YADE process digging in lockstep with the caller.

The YADE tests (marked ``yade``, skipped without YADE) drive the model with a scripted cut: the
scoop at the mission's cutting attitude, its tip 4 cm deep in flat ground, moving forward at
10 cm/s; a small
bed of large spheres (about 250) keeps each run to seconds of DEM time. The template bed is
settled once per test session into a temporary cache.
"""

from __future__ import annotations

import math
import os
import shutil
import signal
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from ow_dem_bridge.api import LIVE_MODEL_NAME, LockstepModel, ToolState
from ow_dem_bridge.errors import ConfigError, DemRunError
from ow_dem_bridge.geometry import load_tool
from ow_dem_bridge.live import LiveDemModel
from ow_dem_bridge.live_bed import quaternion
from ow_dem_bridge.live_config import MATERIALS, LiveConfig, steps_per_exchange
from ow_dem_bridge.models import make_model
from ow_description.description import URDF_PATH

#: Skips a test that runs YADE where it is not installed (such tests are also marked ``yade``).
needs_yade = pytest.mark.skipif(
    shutil.which("yade") is None,
    reason="YADE is not installed: apt-get install yade (make setup installs it)",
)
GROUND = -0.155
STEP_S = 0.01
#: Exchanges of the scripted cut (0.4 s: 4 cm of travel).
EXCHANGES = 40
#: A small bed of large spheres: ~250 spheres, 61 DEM steps per 10 ms exchange.
SMALL = {
    "particle_radius": 0.015,
    "bed_length": 0.3,
    "bed_behind": 0.06,
    "bed_width": 0.16,
    "bed_height": 0.12,
    "floor_depth": 0.07,
}
#: l_scoop in base_link at the mission's cutting attitude: +x (cutting edge first) pitched 30
#: degrees down, the bottom's normal (+z) down and back, as a linear dig holds it.
R_CUT = np.array(
    [
        [math.cos(math.radians(30)), 0.0, -math.sin(math.radians(30))],
        [0.0, -1.0, 0.0],
        [-math.sin(math.radians(30)), 0.0, -math.cos(math.radians(30))],
    ]
)
SCOOP = load_tool(URDF_PATH, "l_scoop")


class FlatGround:
    """The terrain as the live model reads it: flat at ``GROUND``."""

    def height_at(self, x: float, y: float) -> float:
        return GROUND


def cut_state(k: int, start: float = 0.0, depth: float = 0.04, speed: float = 0.1) -> ToolState:
    """The scoop ``k`` steps into a straight cut at ``depth`` m, tip moving +x at ``speed`` m/s."""
    tip = np.array([1.7 + speed * STEP_S * k, 0.0, GROUND - depth])
    pose = np.eye(4)
    pose[:3, :3] = R_CUT
    pose[:3, 3] = tip - R_CUT @ SCOOP.tip
    return ToolState(
        tool="scoop",
        material=1,
        depth=depth,
        progress=depth + speed * STEP_S * k,
        velocity=R_CUT.T @ np.array([speed, 0.0, 0.0]),
        angular_velocity=np.zeros(3),
        time=start + STEP_S * k,
        pose=pose,
        digging=True,
    )


@pytest.fixture(scope="module")
def cache_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("dem_live_cache")


def live_model(cache_dir: Path, **params: object) -> LiveDemModel:
    model = make_model(LIVE_MODEL_NAME, {**SMALL, "cache_dir": str(cache_dir), **params})
    assert isinstance(model, LiveDemModel)
    model.attach(FlatGround(), STEP_S)
    return model


def dig(model: LiveDemModel, steps: int) -> np.ndarray:
    """(steps, 6) the wrenches of ``steps`` exchanges of the scripted cut."""
    rows = []
    for k in range(steps):
        wrench = model.wrench(cut_state(k))
        rows.append(np.concatenate([wrench.force, wrench.torque]))
    return np.array(rows)


# ------------------------------------------------------------------ without YADE
def test_the_dem_step_divides_the_simulation_step_within_the_stability_bound():
    config = LiveConfig()
    for material, soil in MATERIALS.items():
        count, dt = steps_per_exchange(0.01, config, soil)
        assert count * dt == pytest.approx(0.01, rel=1e-12), material
        # Within 30 % of the smallest sphere's Rayleigh step, and the fewest steps that are.
        radius = config.particle_radius * (1 - config.radius_fuzz)
        bound = (
            config.dt_safety
            * (math.pi * radius * math.sqrt(soil.density / soil.shear_modulus))
            / (0.1631 * soil.poisson + 0.8766)
        )
        assert dt <= bound < 0.01 / (count - 1)
    # Sand at the default radius: 91 steps of 0.11 ms per 10 ms physics step.
    assert steps_per_exchange(0.01, config, MATERIALS[1])[0] == 91


def test_quaternions_sent_to_yade_are_pinocchios():
    rng = np.random.default_rng(3)
    for _ in range(50):
        R = pin.exp3(rng.normal(size=3) * 2.0)
        w, x, y, z = quaternion(R)
        q = pin.Quaternion(R)
        assert np.allclose([w, x, y, z], [q.w, q.x, q.y, q.z]) or np.allclose(
            [w, x, y, z], [-q.w, -q.x, -q.y, -q.z]
        )
        assert w >= 0


@pytest.mark.parametrize(
    ("params", "match"),
    [
        ({"bed_width": -0.1}, r"yade/bed_width = -0\.1 m is outside \(0, inf\] m"),
        ({"bed_behind": 0.6}, r"bed_behind = 0\.6 m must be less than yade/bed_length = 0\.5 m"),
        ({"floor_depth": 0.3}, r"floor_depth = 0\.3 m must be less than yade/bed_height"),
        ({"material": 3}, r"yade/material = 3 is not one of \[1, 2\]"),
        ({"fallback": "bridge"}, r"yade/fallback = 'bridge' is not one of none, table, balovnev"),
        ({"bed_lenght": 0.4}, r"unknown key 'yade/bed_lenght' \(did you mean 'bed_length'\?\)"),
    ],
)
def test_a_bad_parameter_is_named(params, match):
    with pytest.raises(ConfigError, match=match):
        LiveConfig.from_dict(params)


def test_the_terrain_takes_the_dem_surface_only_when_asked():
    assert not LiveConfig.from_dict({}).terrain_from_dem
    assert LiveConfig.from_dict({"terrain_from_dem": True}).terrain_from_dem
    with pytest.raises(ConfigError, match="terrain_from_dem"):
        LiveConfig.from_dict({"terrain_from_dem": "sometimes"})


def test_without_yade_the_model_names_the_debian_package():
    with pytest.raises(DemRunError, match=r"install the Debian package 'yade'"):
        make_model(LIVE_MODEL_NAME, {"yade": "no-such-yade-launcher"})


def test_the_grinder_and_a_scoop_outside_a_dig_get_the_fallback_without_starting_yade():
    # material 0: no template is settled at start, so no process runs until a dig.
    model = make_model(
        LIVE_MODEL_NAME, {"yade": shutil.which("true") or "/bin/true", "material": 0}
    )
    assert isinstance(model, LockstepModel) and isinstance(model, LiveDemModel)
    model.attach(FlatGround(), STEP_S)
    table = make_model("table")
    touching = cut_state(3)
    not_digging = ToolState(**{**touching.__dict__, "digging": False})
    grinder = ToolState(**{**touching.__dict__, "tool": "grinder"})
    for state in (not_digging, grinder):
        assert np.array_equal(model.wrench(state).force, table.wrench(state).force)
    assert model.worker_pid is None and model.digs == []


# ------------------------------------------------------------------ with YADE
@pytest.fixture(scope="module")
def first_run(cache_dir: Path) -> tuple[LiveDemModel, np.ndarray]:
    model = live_model(cache_dir)
    try:
        wrenches = dig(model, EXCHANGES)
        model.finish_dig()
    finally:
        model.close()
    return model, wrenches


@pytest.mark.yade
@needs_yade
def test_a_live_dig_resists_the_cut_in_lockstep(first_run):
    model, wrenches = first_run
    (record,) = model.digs
    count, dem_dt = steps_per_exchange(STEP_S, model.config, MATERIALS[1])
    assert (record.steps_per_exchange, record.dem_dt) == (count, dem_dt)
    assert 100 < record.particles < 1000
    assert record.times == [cut_state(k).time for k in range(EXCHANGES)]
    assert record.error is None and record.truncated_m == 0.0
    assert record.dem_elapsed_s == pytest.approx(EXCHANGES * STEP_S, abs=1e-9)
    # The sand pushes back against the cutting edge (link -x) once the scoop moves in it.
    assert wrenches[10:, 0].mean() < -0.1
    assert np.all(np.isfinite(wrenches))
    assert record.sample is not None and record.sample["sample_particles"] >= 0
    # The settled template's packing (a poured random packing of spheres) turns the spheres'
    # volume into the regolith's bulk volume.
    assert 0.5 < record.solid_fraction < 0.68
    assert record.sample["sample_bulk_volume_m3"] == pytest.approx(
        record.sample["sample_volume_m3"] / record.solid_fraction, rel=1e-12
    )
    # The simulation takes each finished dig once, for /sim/dem_digs.
    (finished,) = model.take_finished()
    assert finished["sample"] == record.sample and finished["error"] is None
    assert finished["exchanges"] == EXCHANGES and finished["particles"] == record.particles
    assert model.take_finished() == []


@pytest.mark.yade
@needs_yade
def test_two_runs_give_the_same_forces_bit_for_bit(first_run, cache_dir):
    _, wrenches = first_run
    model = live_model(cache_dir)
    try:
        again = dig(model, EXCHANGES)
    finally:
        model.close()
    assert np.array_equal(again, wrenches)


@pytest.mark.yade
@needs_yade
def test_steps_without_an_exchange_still_pass_in_the_dem(cache_dir):
    # The simulation skips the model when the carving ahead of the tip zeroes its depth for a
    # step or two: the DEM runs through those steps, the scoop gliding on, and its clock stays
    # on the simulation's.
    model = live_model(cache_dir)
    try:
        for k in (*range(5), 8, 9, 13):
            wrench = model.wrench(cut_state(k))
            (record,) = model.digs
            assert record.dem_elapsed_s == pytest.approx((k + 1) * STEP_S, abs=1e-9)
            assert np.all(np.isfinite(wrench.force))
        assert record.times == [cut_state(k).time for k in (*range(5), 8, 9, 13)]
    finally:
        model.close()


@pytest.mark.yade
@needs_yade
def test_a_killed_dem_process_fails_the_dig_with_a_clear_error_and_the_next_dig_runs(cache_dir):
    model = live_model(cache_dir)
    table = make_model("table")
    try:
        dig(model, 3)
        pid = model.worker_pid
        assert pid is not None
        os.kill(pid, signal.SIGKILL)
        with pytest.raises(DemRunError) as failure:
            model.wrench(cut_state(3))
        message = str(failure.value)
        assert "t=0.030 s of the dig that started at t=0.000 s (exchange 4)" in message
        assert f"the YADE process (pid {pid})" in message and "killed by signal 9" in message
        assert model.digs[0].error is not None and model.worker_pid is None
        (failed,) = model.take_finished()  # reported at once, without a sample
        assert failed["sample"] is None and "killed by signal 9" in failed["error"]
        # The rest of that dig gets the fallback (the table); nothing raises again.
        state = cut_state(4)
        assert np.array_equal(model.wrench(state).force, table.wrench(state).force)
        # A new dig (progress from zero, 2 s later) starts a new process and digs live.
        wrench = model.wrench(cut_state(0, start=2.0))
        assert model.worker_pid not in (None, pid) and len(model.digs) == 2
        assert model.digs[1].times == [2.0] and np.all(np.isfinite(wrench.force))
    finally:
        model.close()


@pytest.mark.yade
@needs_yade
def test_a_diverging_dem_fails_the_dig(cache_dir):
    model = live_model(cache_dir, max_speed=1e-9)
    try:
        with pytest.raises(DemRunError, match=r"the DEM diverged: a sphere moves at .* m/s"):
            model.wrench(cut_state(0))
        assert model.digs[0].error is not None
    finally:
        model.close()


class Trench:
    """``GROUND`` with a 5 cm deep trench (|y| < 8 cm, x > 1.6 m) in the height map; the
    grinder's cuttings lie in it up to 1 cm below ``GROUND`` (the loose layer's top)."""

    def height_at(self, x: float, y: float) -> float:
        return GROUND - 0.05 if abs(y) < 0.08 and x > 1.6 else GROUND

    @staticmethod
    def loose_top(x: float, y: float) -> float:
        return GROUND - 0.01 if abs(y) < 0.08 and x > 1.6 else -math.inf


@pytest.mark.yade
@needs_yade
def test_the_cuttings_in_a_trench_are_loose_spheres_the_scoop_pushes_at_the_trench_floor(
    cache_dir,
):
    """The scoop's tip on the trench floor (depth 0 below the height map): with the loose layer
    the bed has spheres above the floor and they resist the cut; without it, the trench is
    empty and the scoop meets almost nothing."""
    results = {}
    for loose in (True, False):
        model = live_model(cache_dir)
        model.attach(Trench(), STEP_S, Trench.loose_top if loose else None)
        try:
            # Tip on the trench floor; a live model's depth is below its material's top.
            assert model.material_top(1.75, 0.0) == (GROUND - 0.01 if loose else GROUND - 0.05)
            rows = [model.wrench(cut_state(k, depth=0.05)).force.tolist() for k in range(EXCHANGES)]
        finally:
            model.close()
        (record,) = model.digs
        results[loose] = (record, np.array(rows))
    with_loose, empty = results[True], results[False]
    assert with_loose[0].loose_particles > 20 and empty[0].loose_particles == 0
    assert with_loose[0].particles > empty[0].particles + with_loose[0].loose_particles // 2
    assert with_loose[1][10:, 0].mean() < -0.1  # the cuttings push back on the cutting edge
    assert with_loose[1][10:, 0].mean() < 2 * empty[1][10:, 0].mean()
