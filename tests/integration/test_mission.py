"""The sample-collection mission end to end (issue 8): ``rosrun ow_mission mission <file>`` as a
user runs it, checked against independent sources rather than against its own report.

* the ground found: the terrain as made (``ow_sim_bullet.terrains``, the same code the simulation
  builds it with) at the reported contact point;
* the trench: the last ``/sim/terrain`` in the bags, read with the ROS ``rosbag`` API;
* the delivery: forward kinematics of the recorded ``/joint_states`` at the end of the step;
* the energies: the ``ow_power`` analysis of the recorded ``/power`` over each step's window.

A second mission cannot find the ground and must stop there, keeping what it recorded. The
default mission runs twice at once (renders on, as ``make demo``), and the two must be the same
run (issue 16). The report's checks: every image it links exists, its energies are the power
plot's, its figures say what the run did. Each mission runs once per module; the checks only
read its run directory. The first default run is :func:`run_once`'s: a module of another
pytest-xdist worker that runs the same file (test_mission_sample) reads the same run instead of
making its own, and the second run is then made beside whatever else that worker runs. The
mission through OceanWATERS' actions (``interface: actions``) is test_campaign's: its missions run
through them.
"""

import fcntl
import hashlib
import json
import math
import os
import subprocess
import tempfile
import xml.etree.ElementTree as ET
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import rosbag
import rospy
import yaml
from PIL import Image

from ow_cameras.rig import LEFT_OPTICAL_FRAME, PANEL_LINK, X_panel
from ow_description.conversions import height_map_from_msg
from ow_description.model import URDF_PATH, LanderModel
from ow_lander.operations.planner import DOCK_CENTRE, POUR_TILT
from ow_mission.figures import wait_for_figures
from ow_mission.mission import MISSION_TELEMETRY_HZ
from ow_mission.mission_config import DEFAULT_MISSION_FILE
from ow_mission.report_files import image_links
from ow_mission.run_compare import differences, report_numbers
from ow_power.analysis import analyze, window_figures
from ow_sim_bullet.terrains import parse_terrain_spec

TERRAIN = "europa:7"
X, Y = 1.65, 0.0  # m, trench start in base_link
TRENCH_DEPTH = 0.10  # m
BOTTOM_GRIND_DEPTH = 0.05  # m
TRENCH_LENGTH = 0.3  # m
STEPS = [
    "unstow",
    "guarded_move",
    "grind",
    "dig_spoil",
    "discard_spoil",
    "grind_bottom",
    "dig_sample",
    "deliver_sample",
    "stow",
]
GROUND_TOLERANCE_M = 0.005
TRENCH_TOLERANCE_M = 0.01
#: m, terrain farther than this from the trench line must be exactly as made.
UNTOUCHED_DISTANCE_M = 0.3
TILT_TOLERANCE_RAD = math.radians(10.0)
ENERGY_RELATIVE = 0.02
#: s, how far two nodes' sim clocks may differ: each has the last /clock it received, and at
#: ~40x real time 50 ms of wall latency under load is 2 s of sim time.
CLOCK_SKEW_S = 2.0
ENERGY_ABSOLUTE_J = 0.5
MISSION_TIMEOUT_S = 900.0  # a hang fails the test instead of blocking the suite


@dataclass
class Run:
    """One finished mission: exit code, output, run directory and its report.json (with the
    figures drawn after the mission exited), and report.json as it was when it exited."""

    returncode: int
    output: str
    run_dir: Path
    report: dict[str, Any]
    at_exit: dict[str, Any]

    @property
    def bags(self) -> list[Path]:
        return sorted((self.run_dir / "bags").glob("*.bag"))

    def step(self, name: str) -> dict[str, Any]:
        return next(s for s in self.report["steps"] if s["step"] == name)


def _run_mission(directory: Path, **keys: Any) -> Run:
    # Renders off unless asked for: they only illustrate the report (and take time).
    mission = {"renders": False, **keys, "output_dir": str(directory / "runs")}
    path = directory / "mission.yaml"
    path.write_text(yaml.safe_dump(mission))
    proc = subprocess.run(
        ["rosrun", "ow_mission", "mission", str(path)],
        capture_output=True,
        text=True,
        timeout=MISSION_TIMEOUT_S,
        check=False,
    )
    output = proc.stdout + proc.stderr
    runs = sorted((directory / "runs").iterdir())
    assert len(runs) == 1, output
    report_file = runs[0] / "report.json"
    assert report_file.is_file(), output
    at_exit = json.loads(report_file.read_text())
    if mission.get("figures") == "none":  # the numbers only: nothing more is coming
        return Run(proc.returncode, output, runs[0], at_exit, at_exit)
    report = wait_for_figures(runs[0], timeout_s=MISSION_TIMEOUT_S)
    return Run(proc.returncode, output, runs[0], report, at_exit)


def _shared_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A directory every pytest-xdist worker of this session sees: the base temporary
    directory's parent under xdist (each worker's base is ``popen-gw<n>`` in it), else the
    base itself."""
    base = tmp_path_factory.getbasetemp()
    return base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base


def run_once(tmp_path_factory: pytest.TempPathFactory, **keys: Any) -> Run:
    """:func:`_run_mission` of ``keys``, made once per test session: every module asking for
    the same mission file (but its ``output_dir``) gets the same run, made by the first to ask;
    a worker asking while another makes it waits for it (a lock file). The checks only read a
    run directory, so they may share one. A run that raised (a timeout) is made again by the
    next to ask."""
    digest = hashlib.sha256(yaml.safe_dump(keys, sort_keys=True).encode()).hexdigest()[:16]
    root = _shared_dir(tmp_path_factory) / "mission_runs"
    root.mkdir(exist_ok=True)
    record = root / f"{digest}.json"
    with (root / f"{digest}.lock").open("w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # released when the file closes
        if record.is_file():
            saved = json.loads(record.read_text())
            run_dir = Path(saved["run_dir"])
            report = json.loads((run_dir / "report.json").read_text())
            return Run(saved["returncode"], saved["output"], run_dir, report, saved["at_exit"])
        directory = Path(tempfile.mkdtemp(prefix=f"{digest}-", dir=root))
        run = _run_mission(directory, **keys)
        saved = {
            "returncode": run.returncode,
            "output": run.output,
            "run_dir": str(run.run_dir),
            "at_exit": run.at_exit,
        }
        record.write_text(json.dumps(saved))
        return run


def _messages(
    bags: list[Path], topic: str, start_s: float | None = None, end_s: float | None = None
):
    """(message, bag time s) of ``topic`` over the run's bags, in recording order."""
    start = rospy.Time.from_sec(start_s) if start_s is not None else None
    end = rospy.Time.from_sec(end_s) if end_s is not None else None
    for path in bags:
        with rosbag.Bag(str(path)) as bag:
            for _, msg, t in bag.read_messages(topics=[topic], start_time=start, end_time=end):
                yield msg, t.to_sec()


def _default_mission() -> dict[str, Any]:
    """The default mission file (``make demo``'s): the procedure on europa:7 at (1.65, 0) m."""
    keys = yaml.safe_load(DEFAULT_MISSION_FILE.read_text())
    expected = {"x": X, "y": Y, "trench_depth": TRENCH_DEPTH, "trench_length": TRENCH_LENGTH}
    assert {k: keys[k] for k in expected} == expected
    assert (keys["terrain"], keys["seed"]) == ("europa", 7)
    assert (keys["bottom_grind_depth"], keys["parallel"], keys["dig"]) == (0.05, True, "linear")
    return keys


def demo_mission() -> dict[str, Any]:
    """The default mission as ``make demo`` runs it (renders on): the session's shared run."""
    return {**_default_mission(), "renders": True}


@pytest.fixture(scope="module")
def pair(tmp_path_factory):
    """The default mission run twice, renders on as ``make demo`` makes them: the session's run
    of it (:func:`run_once`) and one more, made at once unless another module made the first
    already (under make test the other worker's tests run beside both). The second draws no
    figures (``figures: none``): they are made from the bags after the mission exits, and the
    checks compare what the missions recorded and the report's numbers, which the figures
    change none of (test_the_mission_exits_with_every_number_the_figures_show)."""
    keys = demo_mission()
    again_dir = tmp_path_factory.mktemp("again")  # here: the factory is not thread-safe
    with ThreadPoolExecutor(max_workers=2) as pool:
        first = pool.submit(run_once, tmp_path_factory, **keys)
        again = pool.submit(_run_mission, again_dir, **{**keys, "figures": "none"})
        return first.result(), again.result()


@pytest.fixture(scope="module")
def mission(pair):
    """The default mission (renders on): the run the procedure's and the report's checks read."""
    return pair[0]


@pytest.fixture(scope="module")
def run(mission):
    """The report's mission: (exit code, output, run directory, report.json)."""
    return mission.returncode, mission.output, mission.run_dir, mission.report


@pytest.fixture(scope="module")
def no_ground(tmp_path_factory):
    """A mission whose guarded move searches 0.2 m above a ground 0.9 m down (its report's
    numbers and text are checked, not its figures: none drawn)."""
    return _run_mission(
        tmp_path_factory.mktemp("no_ground"),
        name="no ground",
        terrain="flat:-0.9",
        search_distance=0.2,
        figures="none",
    )


def test_every_step_succeeds(mission):
    assert mission.returncode == 0, mission.output
    report = mission.report
    assert report["success"], report["error"]
    assert report["error"] == ""
    assert report["failed_step"] is None
    assert [s["step"] for s in report["steps"]] == STEPS
    failed = [(s["step"], s["message"]) for s in report["steps"] if not s["success"]]
    assert failed == []
    assert all(s["sim_end_s"] > s["sim_start_s"] for s in report["steps"])
    # The simulation runs only during the steps (paused while the mission starts the nodes and
    # between steps): its time is the operations' own.
    in_steps = sum(s["sim_end_s"] - s["sim_start_s"] for s in report["steps"])
    assert in_steps <= report["sim_time_s"] <= in_steps + 5.0, (in_steps, report["sim_time_s"])
    assert "Result: **success**" in (mission.run_dir / "report.md").read_text()
    assert (mission.run_dir / "power.png").stat().st_size > 0
    assert len(list((mission.run_dir / "trajectories").glob("*.csv"))) == len(STEPS)


def test_ground_found_is_the_terrain(mission):
    step = mission.step("guarded_move")
    assert step["success"], step["message"]
    x, y, z = step["ground_position"]
    assert z == step["ground_z"] == mission.report["ground_z"]
    # The scoop comes down where it was sent.
    assert math.hypot(x - X, y - Y) < 0.02
    true_z = float(parse_terrain_spec(TERRAIN).height_at(x, y))
    assert z == pytest.approx(true_z, abs=GROUND_TOLERANCE_M)


@pytest.fixture(scope="module")
def carved(mission):
    """The last terrain the simulation published in the run (the bags, read once)."""
    last = None
    for msg, _ in _messages(mission.bags, "/sim/terrain"):
        last = msg
    assert last is not None, "no /sim/terrain in the bags"
    return height_map_from_msg(last)


def _trench_errors(mission: Run, carved) -> np.ndarray:
    """m, carved height less the requested bottom, along the requested trench line."""
    bottom = mission.report["ground_z"] - TRENCH_DEPTH - BOTTOM_GRIND_DEPTH
    xs = np.linspace(X, X + TRENCH_LENGTH, 13)
    return np.array([carved.height_at(x, Y) for x in xs]) - bottom


def test_trench_is_where_requested(mission, carved):
    made = parse_terrain_spec(TERRAIN)
    assert carved.shape == made.shape
    errors = _trench_errors(mission, carved)
    # Both grinds reached the requested bottom all along the line (not shallower than 1 cm)...
    assert errors.max() <= TRENCH_TOLERANCE_M, errors.round(4)
    # ...and not grossly deeper: a bound that catches a grind at the wrong depth; the 1 cm
    # acceptance on this side is test_trench_bottom_within_1cm.
    assert errors.min() >= -2 * TRENCH_TOLERANCE_M, errors.round(4)

    # Away from the trench no tool cut: the terrain is as made, but for the regolith the scoop
    # spilled there (docs/regolith.md), which only raises it, by less than what was dug out.
    cx, cy = carved.cell_centres()
    gx, gy = np.meshgrid(cx, cy)
    along = np.clip(gx, X, X + TRENCH_LENGTH)
    far = np.hypot(gx - along, gy - Y) > UNTOUCHED_DISTANCE_M
    assert far.sum() > 0.9 * far.size
    change = carved.heights - made.heights
    assert change[far].min() > -1e-6
    cell = carved.resolution**2
    assert change[far].sum() * cell < -change[~far][change[~far] < 0].sum() * cell


def test_trench_bottom_within_1cm(mission, carved, record_property):
    errors = _trench_errors(mission, carved)
    record_property("trench_bottom_errors_m", errors.round(4).tolist())
    print(f"\ntrench bottom - requested (m): {errors.round(4)}")
    assert np.abs(errors).max() <= TRENCH_TOLERANCE_M, errors.round(4)


def _dock_box() -> tuple[np.ndarray, np.ndarray]:
    """(low, high): m, axis-aligned bounds in base_link of the dock's collision box (URDF)."""
    link = ET.parse(URDF_PATH).getroot().find("link[@name='lander_sample_dock0']")
    assert link is not None
    collision = link.find("collision")
    centre = np.array([float(v) for v in collision.find("origin").get("xyz").split()])
    size = np.array([float(v) for v in collision.find("geometry/box").get("size").split()])
    model = LanderModel()
    X_base_dock = model.fk(np.zeros(model.nq), "lander_sample_dock0")
    signs = np.array(np.meshgrid([-1, 1], [-1, 1], [-1, 1])).reshape(3, -1).T
    corners = (X_base_dock[:3, :3] @ (centre + signs * size / 2).T).T + X_base_dock[:3, 3]
    return corners.min(axis=0), corners.max(axis=0)


def _ry(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _rotation_angle(R: np.ndarray) -> float:
    return math.acos(float(np.clip((np.trace(R) - 1.0) / 2.0, -1.0, 1.0)))


def test_scoop_ends_delivery_over_the_dock_tipped(mission):
    step = mission.step("deliver_sample")
    end = step["sim_end_s"]
    # Bag times are when the recorder received a message (it may lag the stamps): select by
    # stamp.
    states = [
        msg
        for msg, _ in _messages(mission.bags, "/joint_states", end - 1.0, end + 10.0)
        if msg.header.stamp.to_sec() <= end
    ]
    assert states, f"no /joint_states in the second before {end} s"
    state = states[-1]
    assert end - state.header.stamp.to_sec() < 0.5
    model = LanderModel()
    q = model.q_from(dict(zip(state.name, state.position, strict=True)))
    X_base_tip = model.fk(q, "l_scoop_tip")
    tip, R = X_base_tip[:3, 3], X_base_tip[:3, :3]

    low, high = _dock_box()
    assert np.allclose((low + high) / 2, DOCK_CENTRE, atol=1e-3)
    assert low[0] <= tip[0] <= high[0], (tip, low, high)
    assert low[1] <= tip[1] <= high[1], (tip, low, high)
    assert tip[2] > high[2], (tip, low, high)

    # Carried upright (tip z axis straight down, heading phi), then tipped about the tip's y
    # axis, which tipping leaves horizontal: y = (sin phi, -cos phi, 0).
    phi = math.atan2(R[0, 1], -R[1, 1])
    x_axis = np.array([math.cos(phi), math.sin(phi), 0.0])
    z_axis = np.array([0.0, 0.0, -1.0])
    carry_R = np.column_stack([x_axis, np.cross(z_axis, x_axis), z_axis])
    assert _rotation_angle(carry_R.T @ R) == pytest.approx(POUR_TILT, abs=TILT_TOLERANCE_RAD)
    assert _rotation_angle(_ry(-POUR_TILT).T @ carry_R.T @ R) < TILT_TOLERANCE_RAD


def test_step_energies_agree_with_the_bags(mission):
    analysis = analyze(mission.bags)
    assert analysis.source == "/power"
    for step in mission.report["steps"]:
        figures = window_figures(analysis.power, step["sim_start_s"], step["sim_end_s"])
        bag_j = figures["mechanical_energy_j"]
        tolerance = max(ENERGY_RELATIVE * abs(bag_j), ENERGY_ABSOLUTE_J)
        assert step["mechanical_energy_j"] == pytest.approx(bag_j, abs=tolerance), step["step"]
        # With P0 too: the window's end must not be cut by the live trace running behind.
        assert step["energy_wh"] == pytest.approx(figures["energy_wh"], rel=ENERGY_RELATIVE)

    # Each step's operation (START/END markers on /arm/operation) lies in the step's window. The
    # markers carry the arm services' clock, the window the mission's: each node has the sim time
    # of the last /clock it received, so under load they differ by up to a few /clock periods.
    ops = analysis.summary
    assert list(ops["name"]) == [s["service"].rsplit("/", 1)[1] for s in mission.report["steps"]]
    assert ops["success"].all() and ops["complete"].all()
    for step, op in zip(mission.report["steps"], ops.itertuples(index=False), strict=True):
        assert step["sim_start_s"] - CLOCK_SKEW_S <= op.start_s, step
        assert op.end_s <= step["sim_end_s"] + CLOCK_SKEW_S, step


def test_no_ground_stops_the_mission_with_a_clear_report(no_ground):
    assert no_ground.returncode == 1, no_ground.output
    report = no_ground.report
    assert not report["success"]
    assert report["failed_step"] == "guarded_move"
    assert [(s["step"], s["success"]) for s in report["steps"]] == [
        ("unstow", True),
        ("guarded_move", False),
    ]
    reason = no_ground.step("guarded_move")["message"]
    assert "no ground" in reason
    assert "guarded_move" in report["error"] and reason in report["error"]
    assert report["ground_z"] is None
    md = (no_ground.run_dir / "report.md").read_text()
    assert "Result: **FAILED**" in md
    assert "step guarded_move (/arm/guarded_move) failed" in md and reason in md


def test_no_ground_keeps_what_was_recorded(no_ground):
    bag_dir = no_ground.run_dir / "bags"
    assert list(bag_dir.glob("*.active")) == []
    assert no_ground.bags
    for path in no_ground.bags:
        info = subprocess.run(["rosbag", "info", str(path)], capture_output=True, text=True)
        assert info.returncode == 0, info.stderr
    unstow, failed = no_ground.step("unstow"), no_ground.step("guarded_move")
    # Everything up to where the simulation stopped: the stack stopped only once the recorder
    # had the last state's /power (a loaded machine once lost its last 0.35 s).
    assert no_ground.report["recording_note"] == ""
    last = {}
    for topic in ("/power", "/joint_states"):
        stamps = [msg.header.stamp.to_sec() for msg, _ in _messages(no_ground.bags, topic)]
        assert stamps, topic
        assert min(stamps) <= unstow["sim_start_s"], topic
        last[topic] = max(stamps)
    # The failed step ends at the last state before the hold.
    assert last["/power"] == last["/joint_states"] == pytest.approx(failed["sim_end_s"])
    # The failed operation is in the bags, with its reason.
    ops = analyze(no_ground.bags).summary
    assert list(ops["name"]) == ["unstow", "guarded_move"]
    assert list(ops["success"]) == [True, False]
    assert "no ground" in ops["message"].iloc[1]


VIEWER_LATCHED = ("/tf_static", "/robot_description", "/viz/terrain")


def test_every_bag_replays_in_a_viewer(mission):
    """Each split file on its own has the frames, the robot and the terrain a viewer needs, the
    latched ones flagged as latched (read with the ROS rosbag API)."""
    assert len(mission.bags) > 1, "the mission's bags were not split: the check needs several"
    for path in mission.bags:
        with rosbag.Bag(str(path)) as bag:
            topics = bag.get_type_and_topic_info().topics
            assert topics["/tf"].message_count > 0, path.name
            assert topics["/robot_description"].msg_type == "std_msgs/String", path.name
            assert topics["/viz/terrain"].msg_type == "visualization_msgs/Marker", path.name
            for topic in VIEWER_LATCHED:
                flags = [
                    c.header.get("latching") for c in bag._connections.values() if c.topic == topic
                ]
                assert flags and all(f == b"1" for f in flags), f"{path.name}: {topic} {flags}"


def test_the_bags_carry_oceanwaters_telemetry(mission):
    """/arm_joint_positions at 10 Hz of sim time (the mission's telemetry rate), each in
    OceanWATERS' order (sorted joint names without the antenna) and equal to the /joint_states
    message of the same stamp; /arm_pose and the wrist F/T recorded too."""
    states = {
        round(msg.header.stamp.to_sec(), 6): dict(zip(msg.name, msg.position, strict=True))
        for msg, _ in _messages(mission.bags, "/joint_states")
    }
    positions = [msg for msg, _ in _messages(mission.bags, "/arm_joint_positions")]
    stamps = np.array([m.header.stamp.to_sec() for m in positions])
    assert np.all(np.diff(stamps) > 0)
    rate = (len(stamps) - 1) / (stamps[-1] - stamps[0])
    assert rate == pytest.approx(MISSION_TELEMETRY_HZ, rel=0.02)
    order = sorted(n for n in next(iter(states.values())) if not n.startswith("j_ant"))
    for msg in positions[:: max(1, len(positions) // 50)]:
        state = states[round(msg.header.stamp.to_sec(), 6)]
        assert list(msg.value) == [state[n] for n in order]
    for topic in ("/arm_pose", "/arm_end_effector_force_torque", "/arm_joint_torques"):
        assert next(_messages(mission.bags, topic), None) is not None, topic


def test_a_run_is_a_function_of_its_mission_file(pair, no_ground):
    """Issue 16: the default mission twice, at once (each beside the other), gives the same
    report numbers and the same /joint_states and /power, bit for bit."""
    mission, again = pair
    assert again.returncode == 0, again.output
    assert again.report["figures_pending"]  # no figure drawn from its bags
    first, second = report_numbers(mission.report), report_numbers(again.report)
    assert len(first) > 100  # every step's times, energies, positions, the trench, ...
    assert {k: (v, second.get(k)) for k, v in first.items() if second.get(k) != v} == {}
    assert first.keys() == second.keys()
    # Read with the ROS bag API here; run_compare (rosbags) adds the wrenches, battery, faults.
    topics = ("/joint_states", "/power", "/arm_end_effector_force_torque")
    raw_mission, raw_again = _raw(mission.bags, topics), _raw(again.bags, topics)
    for topic in topics:
        a, b = raw_mission[topic], raw_again[topic]
        assert len(a) > 10000, topic  # 100 Hz over the mission's ~330 s (50 Hz F/T)
        differ = next((i for i, (x, y) in enumerate(zip(a, b, strict=False)) if x != y), None)
        assert (len(a), differ) == (len(b), None), f"{topic}: first difference at message {differ}"
    assert differences(mission.run_dir, again.run_dir) == []
    # A mission that found no ground and stopped differs (the comparison can fail).
    assert differences(mission.run_dir, no_ground.run_dir, ["/joint_states"]) != []


def _ply_points(path: Path) -> np.ndarray:
    """(n, 3) m of a binary PLY of x y z float and red green blue uchar vertices."""
    head, body = path.read_bytes().split(b"end_header\n", 1)
    assert b"format binary_little_endian 1.0" in head
    layout = [(n, "<f4") for n in "xyz"] + [(n, "u1") for n in ("red", "green", "blue")]
    vertices = np.frombuffer(body, dtype=layout)
    return np.column_stack([vertices[n].astype(np.float64) for n in "xyz"])


def test_the_workspace_is_captured_before_the_first_arm_step(mission):
    """The stereo capture (OceanWATERS' CameraCapture) of the simulation at t = 0, the mast
    aimed at the trench: its files are in the run directory, the report shows the picture, and
    its point cloud, put in base_link with the URDF's kinematics at the recorded mast angles,
    lies on the terrain as made (not on the report's own numbers)."""
    capture = mission.report["capture"]
    assert capture["success"], capture["message"]
    assert capture["stamp_s"] == 0.0 == mission.step("unstow")["sim_start_s"]
    with Image.open(mission.run_dir / capture["image"]) as image:
        assert (image.size, image.mode) == ((800, 600), "RGB")
    points = _ply_points(mission.run_dir / capture["cloud"])
    assert len(points) == capture["cloud_points"] > 0.4 * 800 * 600

    state = next(msg for msg, _ in _messages(mission.bags, "/joint_states"))
    assert state.header.stamp.to_sec() == 0.0
    model = LanderModel()
    q = model.q_from(dict(zip(state.name, state.position, strict=True)))
    X_base_left = model.fk(q, PANEL_LINK) @ X_panel(LEFT_OPTICAL_FRAME)
    base = points @ X_base_left[:3, :3].T + X_base_left[:3, 3]
    terrain = parse_terrain_spec(TERRAIN)
    on_terrain = [abs(z - float(terrain.height_at(x, y))) for x, y, z in base[::97]]
    assert np.median(on_terrain) < GROUND_TOLERANCE_M

    site = capture["site"]
    assert site["valid_fraction"] > 0.9  # the trench site in view, matched
    assert site["ground_z"] == pytest.approx(mission.report["ground_z"], abs=GROUND_TOLERANCE_M)
    md = (mission.run_dir / "report.md").read_text()
    assert image_links(md)[0] == capture["site_image"] == mission.report["figures"]["workspace"]
    assert f"`{capture['cloud']}`" in md


def test_the_capture_is_a_function_of_the_mission_file(pair):
    """The two runs of the same file made the same picture and cloud, byte for byte."""
    mission, again = pair
    for key in ("image", "site_image", "cloud"):
        name = mission.report["capture"][key]
        assert (mission.run_dir / name).read_bytes() == (again.run_dir / name).read_bytes(), name


def _raw(bags: list[Path], topics: tuple[str, ...]) -> dict[str, list[bytes]]:
    """Every message of each of ``topics`` as recorded, serialised (header and all), in order:
    one pass over the bags (each topic's messages keep their order within it)."""
    data: dict[str, list[bytes]] = {topic: [] for topic in topics}
    for path in bags:
        with rosbag.Bag(str(path)) as bag:
            for topic, raw, _ in bag.read_messages(topics=list(topics), raw=True):
                data[topic].append(raw[1])
    return data


# -------------------------------------------------------------------------- the report
def test_the_mission_succeeds_and_every_linked_image_exists(run):
    returncode, output, run_dir, report = run
    assert returncode == 0, output
    links = image_links((run_dir / "report.md").read_text())
    for link in links:
        assert (run_dir / link).is_file(), link
    for role in ("power", "trench_profile", "guarded_move", "replay"):
        assert role in report["figures"], report.get("figure_notes")
        assert report["figures"][role] in links
    stills = [f for role, f in report["figures"].items() if role.startswith("still_")]
    assert len(stills) == 4
    for still in stills:
        with Image.open(run_dir / still) as image:
            assert image.size == (1024, 768)
    assert report["figure_notes"] == {}


def test_the_mission_exits_with_every_number_the_figures_show(mission):
    """figures: after_exit (the default): report.json at the exit has the steps' energies,
    the trench and the detector; the figures' process, drawing from the same bags, changes
    none of them. The table printed at the exit shows the same energies."""
    assert mission.at_exit["figures_pending"] is True
    assert "figures_pending" not in mission.report
    timed = {"figures", "figure_notes", "figures_seconds", "replay"}
    final = {k: v for k, v in mission.report.items() if k not in timed}
    assert {k: v for k, v in mission.at_exit.items() if k not in timed | {"figures_pending"}} == (
        final
    )
    assert "figures: being drawn by process" in mission.output
    for step in mission.report["steps"]:
        row = next(
            line for line in mission.output.splitlines() if line.startswith(step["step"] + " ")
        )
        assert f"{step['mechanical_energy_j']:.1f}" in row.split()


def test_the_tables_energies_are_the_plots_labels(run):
    _, _, run_dir, report = run
    markdown = (run_dir / "report.md").read_text()
    for step in report["steps"]:
        _, signed, absolute = step["power_plot_label"].split("\n")
        row = next(line for line in markdown.splitlines() if line.startswith(f"| {step['step']} "))
        cells = [c.strip() for c in row.strip("|").split("|")]
        assert f"{cells[4]} J signed" == signed
        assert f"{cells[5]} J |.|" == absolute
        assert step["mechanical_energy_abs_j"] >= abs(step["mechanical_energy_j"]) - 1e-9
        assert step["peak_power_w"] > step["peak_mechanical_power_w"]  # with P0 and without


def test_the_dig_reached_the_requested_depth(run):
    _, _, run_dir, report = run
    assert report["trench"]["worked"], report["trench"]["verdict"]
    assert "The dig worked" in (run_dir / "report.md").read_text()


def test_the_detector_figure_finds_the_contact_the_arm_reported(run):
    _, _, _, report = run
    detector = report["guarded_move_detector"]
    assert detector["contact_s"] is not None
    assert detector["contact_s"] == pytest.approx(detector["result_s"], abs=0.1), detector


def test_the_replay_runs_at_ten_frames_per_second_or_more(run):
    _, _, run_dir, report = run
    replay = report["replay"]
    with Image.open(run_dir / replay["file"]) as gif:
        assert gif.n_frames == replay["frames"] >= 100
        assert gif.info["duration"] <= 100  # ms per frame
