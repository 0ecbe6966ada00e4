"""Parameter validation, terrain specs and trajectory interpolation of ow_sim_bullet (no ROS)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import yaml
from PIL import Image

from ow_description.description import DEFAULT_GROUND_Z, EUROPA_GRAVITY
from ow_sim_bullet.config import PID_YAML, SIM_YAML, SPEC_GAINS, PidGains, SimConfig
from ow_sim_bullet.errors import CommandError, ConfigError, TerrainSpecError
from ow_sim_bullet.terrains import WORKSPACE_CENTRE, europa, parse_terrain_spec
from ow_sim_bullet.trajectory import ActiveTrajectory, JointTrajectory


def test_defaults_are_the_spec_gains_at_europa_gravity():
    config = SimConfig.from_dict({})
    assert config.gravity == EUROPA_GRAVITY == 1.315
    for joint, (p, i, d) in SPEC_GAINS.items():
        gains = config.gains[joint]
        assert (gains.p, gains.i, gains.d, gains.i_clamp) == (p, i, d, None)


def test_yaml_style_parameters_are_accepted():
    config = SimConfig.from_dict(
        {
            "physics_rate_hz": 200,
            "real_time_factor": 0,
            "terrain": "flat:-0.2",
            "gains": {"j_shou_yaw": {"p": 900, "i": 1, "d": 200, "i_clamp": 20}},
            "initial_positions": {"j_ant_tilt": 0.3},
        }
    )
    assert config.dt == 0.005
    assert config.gains["j_shou_yaw"].i_clamp == 20.0
    assert config.gains["j_shou_pitch"].p == 2000.0
    assert config.initial_positions["j_ant_tilt"] == 0.3
    assert config.initial_positions["j_shou_yaw"] == -1.5


def test_the_shipped_yaml_files_load_as_the_launch_file_loads_them():
    """sim.launch loads sim.yaml, then pid.yaml, into the node's private namespace."""
    raw = {**yaml.safe_load(SIM_YAML.read_text()), **yaml.safe_load(PID_YAML.read_text())}
    assert set(raw) >= {"physics_rate_hz", "terrain", "initial_positions", "gains"}
    config = SimConfig.from_dict(raw)
    # The files ship the defaults.
    assert config == SimConfig()


@pytest.mark.parametrize(
    ("raw", "message"),
    [
        ({"physics_rate": 100}, "unknown key 'sim/physics_rate' (did you mean 'physics_rate_hz'?)"),
        ({"physics_rate_hz": 0}, "sim/physics_rate_hz = 0 Hz is outside (0, inf] Hz"),
        ({"real_time_factor": -1}, "sim/real_time_factor = -1 is outside [0, inf]"),
        ({"gravity": "europa"}, "sim/gravity must be a number, got 'europa'"),
        ({"gravity": math.nan}, "sim/gravity must be finite"),
        ({"start_paused": 1}, "sim/start_paused must be true or false, got 1"),
        ({"terrain": ""}, "sim/terrain must be a non-empty string"),
        ({"terrain_material": 300}, "sim/terrain_material = 300 is outside [0, 255]"),
        ({"terrain_material": 1.5}, "sim/terrain_material must be an integer, got 1.5"),
        ({"terrain_friction": -0.1}, "sim/terrain_friction = -0.1 is outside [0, inf]"),
        (
            {"terrain_file_center": [1.0]},
            "sim/terrain_file_center must be a list of two numbers (m), got [1.0]",
        ),
        (
            {"terrain_file_center": [1.0, "x"]},
            "sim/terrain_file_center[1] must be a number, got 'x'",
        ),
        (
            {"terrain_png_height_range": [1.0, -1.0]},
            "sim/terrain_png_height_range must be increasing, got [1.0, -1.0]",
        ),
        ({"terrain_force_params": 3}, "sim/terrain_force_params must be a mapping, got 3"),
        (
            {"carve_full_force": 5.0},
            "sim/carve_full_force = 5 N must exceed sim/terrain_yield_force = 10 N",
        ),
        (
            {"gains": {"j_elbow": {"p": 1, "i": 0, "d": 0}}},
            "sim/gains/j_elbow: unknown joint; joints: j_shou_yaw,",
        ),
        (
            {"gains": {"j_shou_yaww": {"p": 1, "i": 0, "d": 0}}},
            "sim/gains/j_shou_yaww: unknown joint (did you mean 'j_shou_yaw'?)",
        ),
        ({"dig_forward_angle": 0}, "sim/dig_forward_angle = 0 rad is outside (0, 3.14159] rad"),
        ({"dig_slope": 2.0}, "sim/dig_slope = 2 rad is outside (0, 1.5708] rad"),
        ({"dig_timeout": -1}, "sim/dig_timeout = -1 s is outside (0, inf] s"),
        ({"grind_down_angle": "x"}, "sim/grind_down_angle must be a number, got 'x'"),
        ({"gains": {"j_shou_yaw": {"p": 1, "i": 0}}}, "sim/gains/j_shou_yaw/d is missing"),
        (
            {"gains": {"j_shou_yaw": {"p": -1, "i": 0, "d": 0}}},
            "sim/gains/j_shou_yaw/p = -1 N m/rad is outside [0, inf] N m/rad",
        ),
        (
            {"gains": {"j_shou_yaw": {"p": 1, "i": 0, "d": 0, "iclamp": 3}}},
            "unknown key 'sim/gains/j_shou_yaw/iclamp' (did you mean 'i_clamp'?)",
        ),
        ({"gains": {"j_shou_yaw": 5}}, "sim/gains/j_shou_yaw must be a mapping, got 5"),
        (
            {"initial_positions": {"j_shou_yaw": "up"}},
            "sim/initial_positions/j_shou_yaw must be a number, got 'up'",
        ),
    ],
)
def test_bad_parameters_name_the_key(raw, message):
    with pytest.raises(ConfigError) as error:
        SimConfig.from_dict(raw)
    assert message in str(error.value)


def test_every_bad_parameter_is_reported_at_once():
    with pytest.raises(ConfigError) as error:
        SimConfig.from_dict({"gravity": -1.0, "tf_rate": 30, "gains": {"j_grinder": {"p": 1}}})
    text = str(error.value)
    assert text.startswith("4 problems in sim:")
    for part in (
        "sim/gravity = -1 m/s^2",
        "unknown key 'sim/tf_rate' (did you mean 'tf_rate_hz'?)",
        "sim/gains/j_grinder/i is missing",
        "sim/gains/j_grinder/d is missing",
    ):
        assert part in text


@pytest.mark.parametrize(
    ("raw", "message"),
    [
        ({"p": 1.0, "i": 0.0}, "gains of j_x/d is missing"),
        ({"p": 1.0, "i": 0.0, "d": 0.0, "i_clamp": -2.0}, "gains of j_x/i_clamp = -2 N m"),
        ({"p": 1.0, "i": 0.0, "d": 0.0, "q": 1.0}, "unknown key 'gains of j_x/q'"),
        ([1.0, 0.0, 0.0], "gains of j_x must be a mapping of names to values"),
    ],
)
def test_bad_gains_of_one_joint_name_the_gain(raw, message):
    with pytest.raises(ConfigError) as error:
        PidGains.from_dict(raw, "gains of j_x")
    assert message in str(error.value)


def test_gains_of_one_joint():
    assert PidGains.from_dict({"p": 2, "i": 0.5, "d": 1}, "g") == PidGains(2.0, 0.5, 1.0, None)
    assert PidGains.from_dict({"p": 2, "i": 0, "d": 1, "i_clamp": 3}, "g").i_clamp == 3.0


def test_flat_and_europa_specs():
    plane = parse_terrain_spec("flat:-0.2")
    assert np.all(plane.heights == -0.2)
    assert plane.origin_x < 0.0 and plane.x_max > 3.0
    first, again, other = europa(7), parse_terrain_spec("europa:7"), europa(8)
    assert np.array_equal(first.heights, again.heights)
    assert not np.array_equal(first.heights, other.heights)


def test_europa_has_a_smooth_workspace_and_spikes_away_from_the_lander():
    terrain = europa(0)
    xs = WORKSPACE_CENTRE[0] + np.linspace(-0.4, 0.4, 9)
    ys = WORKSPACE_CENTRE[1] + np.linspace(-0.5, 0.5, 11)
    gx, gy = np.meshgrid(xs, ys)
    workspace = terrain.height_at(gx, gy)
    assert abs(float(workspace.mean()) - DEFAULT_GROUND_Z) < 0.01
    assert float(np.ptp(workspace)) < 0.03
    far = terrain.heights[:, -10:]  # x > 3.1 m
    assert float(far.max()) > DEFAULT_GROUND_Z + 0.1


def test_file_specs(tmp_path):
    heights = np.linspace(-0.3, -0.1, 30 * 20).reshape(20, 30)
    np.save(tmp_path / "map.npy", heights)
    npy = parse_terrain_spec(f"file:{tmp_path / 'map.npy'}", 0.05, (1.0, 0.5))
    assert npy.resolution == 0.05
    assert (npy.origin_x + npy.x_max) / 2 == pytest.approx(1.0)
    assert (npy.origin_y + npy.y_max) / 2 == pytest.approx(0.5)
    np.savez(tmp_path / "map.npz", heights=heights, resolution=0.1, origin_x=-1.0, origin_y=-2.0)
    npz = parse_terrain_spec(f"file:{tmp_path / 'map.npz'}")
    assert (npz.resolution, npz.origin_x, npz.origin_y) == (0.1, -1.0, -2.0)
    pixels = np.zeros((20, 30), dtype=np.uint16)
    pixels[0, :] = 65535  # top image row = largest y
    Image.fromarray(pixels).save(tmp_path / "map.png")
    png = parse_terrain_spec(f"file:{tmp_path / 'map.png'}", 0.05, (1.0, 0.5), (-0.5, 0.5))
    assert png.heights[-1, 0] == pytest.approx(0.5)
    assert png.heights[0, 0] == pytest.approx(-0.5)


@pytest.mark.parametrize(
    ("spec", "message"),
    [
        ("moon:3", "unknown form 'moon'"),
        ("flat", "must be flat:<z>, europa:<seed> or file:<path>"),
        ("flat:low", "flat height 'low' is not a finite number"),
        ("flat:nan", "is not a finite number"),
        ("europa:-1", "europa seed '-1' must be an integer >= 0"),
        ("file:/nonexistent/map.npy", "terrain file /nonexistent/map.npy does not exist"),
    ],
)
def test_bad_terrain_specs(spec, message):
    with pytest.raises(TerrainSpecError) as error:
        parse_terrain_spec(spec)
    assert message in str(error.value)


def test_bad_terrain_files(tmp_path):
    (tmp_path / "map.txt").write_text("1 2 3")
    with pytest.raises(TerrainSpecError, match=r"unknown type '\.txt'"):
        parse_terrain_spec(f"file:{tmp_path / 'map.txt'}")
    np.save(tmp_path / "line.npy", np.zeros(5))
    with pytest.raises(TerrainSpecError, match="2-D numeric grid"):
        parse_terrain_spec(f"file:{tmp_path / 'line.npy'}")
    np.save(tmp_path / "nan.npy", np.full((4, 4), np.nan))
    with pytest.raises(TerrainSpecError, match="non-finite height"):
        parse_terrain_spec(f"file:{tmp_path / 'nan.npy'}")


JOINTS = ("a", "b")


def test_linear_trajectory_ramps_from_the_held_setpoint():
    trajectory = JointTrajectory.build(JOINTS, 10.0, [1.0, 3.0], [[1, 2], [3, 2]], None, JOINTS)
    active = ActiveTrajectory(trajectory, np.array([0.0, 0.0]), accept_time=10.0)
    position, velocity = active.sample(10.5)
    assert np.allclose(position, [0.5, 1.0]) and np.allclose(velocity, [1.0, 2.0])
    position, velocity = active.sample(12.0)
    assert np.allclose(position, [2.0, 2.0]) and np.allclose(velocity, [1.0, 0.0])
    assert np.allclose(active.sample(20.0)[0], [3.0, 2.0])
    assert active.finished(13.0) and not active.finished(12.9)


def test_cubic_trajectory_meets_positions_and_velocities():
    trajectory = JointTrajectory.build(
        JOINTS, 0.0, [0.0, 2.0], [[0, 0], [2, 1]], [[0, 0], [1, 0]], JOINTS
    )
    active = ActiveTrajectory(trajectory, np.array([0.0, 0.0]), accept_time=0.0)
    position, velocity = active.sample(2.0 - 1e-9)
    assert np.allclose(position, [2, 1], atol=1e-6) and np.allclose(velocity, [1, 0], atol=1e-6)
    assert np.allclose(active.sample(1.0)[0], [0.75, 0.5])


@pytest.mark.parametrize(
    ("joints", "times", "positions", "message"),
    [
        (("a", "z"), [1.0], [[0, 0]], "unknown joint(s) ['z']"),
        (("a", "a"), [1.0], [[0, 0]], "must be unique"),
        (JOINTS, [], [], "has no points"),
        (JOINTS, [1.0, 1.0], [[0, 0], [1, 1]], "increasing"),
        (JOINTS, [-1.0], [[0, 0]], ">= 0"),
        (JOINTS, [1.0], [[0, math.nan]], "positions of point 0 are not finite"),
        (JOINTS, [1.0], [[0]], "2 values each"),
    ],
)
def test_bad_trajectories(joints, times, positions, message):
    with pytest.raises(CommandError) as error:
        JointTrajectory.build(joints, 0.0, times, positions, None, JOINTS)
    assert message in str(error.value)
