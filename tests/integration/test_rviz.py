"""A real RViz, under Xvfb with software rendering, draws the running stack where it should be.

The simulation, the arm services and the viz node run on a private master; RViz loads the shipped
``ow_viz.rviz`` with a fixed top-down orthographic camera (test-specific: no perspective, so a
point (x, y) of ``world`` lands on pixel ``(u0 + S x, v0 - S y)``; the TF axes are hidden so that
they do not paint over the arm). The screenshot (``import -window root``) must show the flat
terrain as a square of the terrain palette of the map's size, the lander's gold body at its
centre (base_link at the origin of world), and the arm's white links where forward kinematics of
the current joint states puts them, with terrain beside them.
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest
import rospy
import yaml
from PIL import Image
from sensor_msgs.msg import JointState

from ow_description.model import LanderModel
from ow_msgs.msg import HeightMap as HeightMapMsg
from ow_msgs.srv import Unstow
from ow_viz.config import CONFIG_FILE as VIZ_YAML

SCALE_PX_PER_M = 70.0  # pixels per metre of the orthographic view
SHIPPED_RVIZ = Path(VIZ_YAML).parent / "ow_viz.rviz"
TOOLS = ("rviz", "Xvfb", "import")
SETTLE_TIMEOUT_S = 180.0  # wall: RViz under software rendering on a loaded machine
# Settled: at most this fraction of the pixels changed between two screenshots 1 s apart (the
# held arm's sub-millimetre motion can still flip a few edge pixels).
SETTLED_FRACTION = 0.001


def _test_config(path: Path) -> Path:
    config = yaml.safe_load(SHIPPED_RVIZ.read_text())
    manager = config["Visualization Manager"]
    for display in manager["Displays"]:
        if display["Class"] == "rviz/TF":
            display["Enabled"] = display["Value"] = False
    manager["Views"]["Current"] = {
        "Class": "rviz/TopDownOrtho",
        "Angle": 0.0,
        "Invert Z Axis": False,
        "Name": "Current View",
        "Near Clip Distance": 0.01,
        "Scale": SCALE_PX_PER_M,
        "Target Frame": "<Fixed Frame>",
        "X": 0.0,
        "Y": 0.0,
    }
    # No panels: the render panel fills the window below the tool bar.
    config["Panels"] = []
    config["Window Geometry"] = {"Height": 768, "Width": 1024, "X": 0, "Y": 0}
    path.write_text(yaml.safe_dump(config))
    return path


def _rgb(path: Path) -> np.ndarray:
    with Image.open(path) as image:
        return np.asarray(image.convert("RGB"), dtype=np.float64) / 255.0


def _terrain_mask(rgb: np.ndarray) -> np.ndarray:
    """Pixels of the terrain palette: blue clearly above red (lit or not)."""
    r, g, b = rgb[..., 0], rgb[..., 1], rgb[..., 2]
    return (b > r + 0.15) & (b > 0.3) & (g > r)


def _arm_mask(rgb: np.ndarray) -> np.ndarray:
    """Pixels of the arm's light grey/white materials (arm, joints, scoop): bright, unsaturated."""
    return (rgb.min(axis=-1) > 0.45) & (np.ptp(rgb, axis=-1) < 0.12)


def _gold_mask(rgb: np.ndarray) -> np.ndarray:
    """Pixels of the lander body's foil: red and green well above blue."""
    r, g, b = rgb[..., 0], rgb[..., 1], rgb[..., 2]
    return (r > 0.4) & (r > b + 0.25) & (g > b + 0.15)


@pytest.fixture(scope="module")
def display(tmp_path_factory):
    missing = [tool for tool in TOOLS if shutil.which(tool) is None]
    if missing:
        pytest.skip(
            f"{', '.join(missing)} not installed (make setup installs rviz, xvfb, imagemagick)"
        )
    log = tmp_path_factory.mktemp("xvfb") / "xvfb.log"
    read_fd, write_fd = os.pipe()
    with log.open("wb") as out:
        xvfb = subprocess.Popen(
            [
                "Xvfb",
                "-displayfd",
                str(write_fd),
                "-screen",
                "0",
                "1024x768x24",
                "-nolisten",
                "tcp",
            ],
            pass_fds=(write_fd,),
            stdout=out,
            stderr=subprocess.STDOUT,
            start_new_session=True,
        )
    os.close(write_fd)
    with os.fdopen(read_fd) as pipe:
        number = pipe.readline().strip()
    if not number:
        xvfb.kill()
        pytest.skip(f"Xvfb did not start: {log.read_text()[-500:]}")
    try:
        yield f":{number}"
    finally:
        os.killpg(xvfb.pid, signal.SIGTERM)
        xvfb.wait(timeout=10)


@pytest.fixture(scope="module")
def stack(start_lander):
    stack = start_lander()
    stack.start_node("ow_viz", "viz", wait_for_topics=["/viz/terrain", "/robot_description"])
    response = stack.service("/arm/unstow", Unstow)(delete_prev_traj=False)
    assert response.success, response.message
    return stack


#: RViz starts at most this often: with software OpenGL under Xvfb it was seen to crash (SIGSEGV)
#: right after "Forcing OpenGl version 0" about once in ten loaded runs, before drawing anything.
RVIZ_STARTS = 2


@pytest.fixture(scope="module")
def screenshot(stack, display, tmp_path_factory):
    """The screen once RViz has drawn the lander and the terrain and the picture has settled."""
    directory = tmp_path_factory.mktemp("rviz")
    config = _test_config(directory / "test.rviz")
    env = {**stack.master.env, "DISPLAY": display, "LIBGL_ALWAYS_SOFTWARE": "1"}
    shot = directory / "shot.png"
    for start in range(1, RVIZ_STARTS + 1):
        log_path = directory / f"rviz_{start}.log"
        with log_path.open("wb") as log:
            rviz = subprocess.Popen(
                ["rosrun", "rviz", "rviz", "-d", str(config), "__name:=rviz_test"],
                env=env,
                stdout=log,
                stderr=subprocess.STDOUT,
                start_new_session=True,
            )
        try:
            rgb = _settled(rviz, display, shot)
        except RvizCrashError as crash:
            tail = log_path.read_text()[-2000:]
            if start == RVIZ_STARTS or crash.returncode >= 0:
                pytest.fail(f"rviz exited ({crash.returncode}) at start {start}: {tail}")
            print(f"rviz crashed ({crash.returncode}) at start {start}, started again: {tail}")
            continue
        except BaseException:
            _stop(rviz)
            raise
        break
    try:
        joints = rospy.wait_for_message("/joint_states", JointState, timeout=10)
        terrain = rospy.wait_for_message("/sim/terrain", HeightMapMsg, timeout=10)
        keep = os.environ.get("OW_VIZ_SCREENSHOT")  # a path to keep the picture at
        if keep:
            shutil.copy(shot, keep)
        yield rgb, joints, terrain
    finally:
        _stop(rviz)


class RvizCrashError(Exception):
    """RViz exited before drawing a settled picture."""

    def __init__(self, returncode: int) -> None:
        super().__init__(f"rviz exited ({returncode})")
        self.returncode = returncode


def _settled(rviz: subprocess.Popen, display: str, shot) -> np.ndarray:
    """The screenshot once RViz shows the terrain and the lander and the picture has settled.

    Raises:
        RvizCrashError: RViz exited meanwhile.
    """
    deadline = time.monotonic() + SETTLE_TIMEOUT_S
    previous = None
    seen = "no screenshot"
    while True:
        time.sleep(1.0)
        if rviz.poll() is not None:
            raise RvizCrashError(rviz.returncode)
        subprocess.run(
            ["import", "-display", display, "-window", "root", str(shot)],
            check=True,
            capture_output=True,
            timeout=30,
        )
        rgb = _rgb(shot)
        terrain_px, gold_px = int(_terrain_mask(rgb).sum()), int(_gold_mask(rgb).sum())
        changed = 1.0 if previous is None else float(np.any(rgb != previous, axis=-1).mean())
        seen = f"{terrain_px} terrain px, {gold_px} gold px, {changed:.2%} changed"
        if terrain_px > 1000 and gold_px > 100 and changed <= SETTLED_FRACTION:
            return rgb
        previous = rgb
        if time.monotonic() > deadline:
            pytest.fail(
                f"RViz drew no settled lander and terrain within {SETTLE_TIMEOUT_S} s "
                f"(last: {seen}): {shot}"
            )


def _stop(rviz: subprocess.Popen) -> None:
    """Stop RViz (SIGINT, then SIGKILL after 10 s) unless it has exited."""
    if rviz.poll() is not None:
        return
    try:
        os.killpg(rviz.pid, signal.SIGINT)
        rviz.wait(timeout=10)
    except ProcessLookupError:
        return
    except subprocess.TimeoutExpired:
        os.killpg(rviz.pid, signal.SIGKILL)
        rviz.wait()


def _terrain_square(rgb: np.ndarray) -> tuple[float, float, float, float]:
    """Bounding box (u_min, u_max, v_min, v_max) px of the terrain: the columns and rows that are
    at least 30 % terrain-coloured (the lander covers the rest of them)."""
    mask = _terrain_mask(rgb)
    cols = np.flatnonzero(mask.sum(axis=0) > 0.3 * mask.sum(axis=0).max())
    rows = np.flatnonzero(mask.sum(axis=1) > 0.3 * mask.sum(axis=1).max())
    return float(cols[0]), float(cols[-1]), float(rows[0]), float(rows[-1])


def _projection(rgb: np.ndarray, terrain) -> tuple[float, float, float]:
    """(u0, v0, S): the pixel of the world origin and the pixels per metre, found from the
    terrain's square on the screen and its extent in the /sim/terrain message."""
    u_min, u_max, v_min, v_max = _terrain_square(rgb)
    x_min, y_min = terrain.origin_x, terrain.origin_y
    x_max = x_min + (terrain.cols - 1) * terrain.resolution
    y_max = y_min + (terrain.rows - 1) * terrain.resolution
    scale_u = (u_max - u_min) / (x_max - x_min)
    scale_v = (v_max - v_min) / (y_max - y_min)
    # The camera's scale, the same along both axes: a terrain drawn at its size.
    assert scale_u == pytest.approx(SCALE_PX_PER_M, rel=0.03)
    assert scale_v == pytest.approx(SCALE_PX_PER_M, rel=0.03)
    return u_min - SCALE_PX_PER_M * x_min, v_min + SCALE_PX_PER_M * y_max, SCALE_PX_PER_M


def test_the_terrain_is_drawn_at_its_size_and_place_around_the_lander(screenshot):
    rgb, _, terrain = screenshot
    u0, v0, scale = _projection(rgb, terrain)
    # The camera looks at the origin of world: the centre of the render panel (the window
    # below the menu and tool bars), where the lander's gold body must be (base_link at the
    # origin of world).
    height, width = rgb.shape[:2]
    assert u0 == pytest.approx(width / 2, abs=15)
    assert v0 == pytest.approx(height / 2 + 30, abs=25)
    gold = _gold_mask(rgb)
    half = int(0.25 * scale)
    centre = gold[int(v0) - half : int(v0) + half, int(u0) - half : int(u0) + half]
    assert centre.mean() > 0.5, f"only {centre.mean():.0%} of the body's area is gold"


def test_the_arm_is_drawn_where_its_joint_states_put_it(screenshot):
    rgb, joints, terrain = screenshot
    u0, v0, scale = _projection(rgb, terrain)

    def window(mask, xy, half_m=0.04):
        """``mask`` within ``half_m`` of ``xy`` (m)."""
        u, v, h = round(u0 + scale * xy[0]), round(v0 - scale * xy[1]), round(half_m * scale)
        return mask[v - h : v + h + 1, u - h : u + h + 1]

    model = LanderModel()
    q = model.q_from(dict(zip(joints.name, joints.position, strict=True)))
    X_dist = model.fk(q, "l_dist")
    arm, ground = _arm_mask(rgb), _terrain_mask(rgb)
    # Along the axis of the distal link's tube (white, 6.5 cm across; l_dist's x from 0.09 m to
    # 0.5 m, 4 mm below its origin), seen from above.
    for x in (0.15, 0.295, 0.45):
        on_arm = (X_dist @ np.array([x, 0.0, -0.004, 1.0]))[:2]
        assert window(arm, on_arm).mean() > 0.3, f"no arm colour around {on_arm} m"
        beside = on_arm + np.array([0.0, 0.6])  # 0.6 m to the left of the arm: bare ground
        assert window(ground, beside).mean() > 0.9, f"no terrain at {beside} m"
        assert not window(arm, beside).any(), f"arm colour at {beside} m, off the arm"
