"""The camera node's pure parts that need no rendering: the rig's geometry against OceanWATERS'
figures (spec section 13), the configuration, the actions' decisions and texts, the messages."""

from __future__ import annotations

import math
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from ow_cameras import commands
from ow_cameras.config import CONFIG_FILE, CameraConfig
from ow_cameras.conversions import (
    camera_info_msg,
    cloud_msg,
    cloud_points,
    image_msg,
    image_pixels,
    transform_msg,
)
from ow_cameras.errors import CameraError, ConfigError, GoalError, RigError
from ow_cameras.rig import (
    BASELINE_M,
    FIXED_FRAMES,
    LEFT_OPTICAL_FRAME,
    PANEL_LINK,
    Mast,
    Pinhole,
    RigPose,
    X_panel,
)
from ow_description.description import URDF_PATH
from ow_description.model import LanderModel

DOCS = Path(__file__).resolve().parents[3] / "docs" / "cameras.md"


@pytest.fixture(scope="module")
def model():
    return LanderModel()


def rig_at(model: LanderModel, pan: float, tilt: float) -> RigPose:
    q = model.q_from({"j_ant_pan": pan, "j_ant_tilt": tilt})
    return RigPose.from_panel(model.fk(q, PANEL_LINK))


# ------------------------------------------------------------------------------- the rig
def test_at_pan_and_tilt_zero_the_head_and_lights_sit_where_oceanwaters_has_them(model):
    rig = rig_at(model, 0.0, 0.0)  # (1e-4: the URDF writes pi as 3.1416)
    head = (rig.X_base_left[:3, 3] + rig.X_base_right[:3, 3]) / 2
    assert np.allclose(head, [0.0, 0.65, 1.461], atol=1e-3)
    assert np.allclose(rig.X_base_left[:3, 2], [0.0, -1.0, 0.0], atol=1e-4)  # looks along -y
    assert rig.X_base_left[0, 3] == pytest.approx(0.1, abs=1e-4)  # the left camera at +x
    assert np.allclose(rig.X_base_left[:3, 0], [-1.0, 0.0, 0.0], atol=1e-4)  # image x: right
    assert np.allclose(rig.X_base_left[:3, 1], [0.0, 0.0, -1.0], atol=1e-4)  # image y: down
    left, right = rig.lights
    assert (left.name, right.name) == ("left", "right")
    assert np.allclose(left.position, [0.33, 0.66, 1.773], atol=1e-3)
    assert np.allclose(right.position, [-0.33, 0.66, 1.773], atol=1e-3)
    assert np.allclose(left.axis, [0.0, -1.0, 0.0], atol=1e-4)


@pytest.mark.parametrize(
    ("pan", "tilt", "view"),
    [(0.0, 0.5, (0.0, -0.878, -0.479)), (1.0, 0.0, (0.841, -0.540, 0.0))],
)
def test_the_cameras_turn_with_pan_and_tilt(model, pan, tilt, view):
    rig = rig_at(model, pan, tilt)
    for X in (rig.X_base_left, rig.X_base_right):
        assert np.allclose(X[:3, 2], view, atol=1e-3)
    for light in rig.lights:
        assert np.allclose(light.axis, view, atol=1e-3)
    baseline = rig.X_base_right[:3, 3] - rig.X_base_left[:3, 3]
    assert np.allclose(baseline, BASELINE_M * rig.X_base_left[:3, 0], atol=1e-9)


def test_every_frame_of_the_rig_hangs_from_the_panel():
    children = {child for _, child, _ in FIXED_FRAMES}
    assert {parent for parent, _, _ in FIXED_FRAMES} <= children | {PANEL_LINK}
    X = X_panel(LEFT_OPTICAL_FRAME)
    assert np.allclose(X[:3, :3] @ X[:3, :3].T, np.eye(3))
    with pytest.raises(KeyError, match="'nowhere' is not a frame of the camera rig"):
        X_panel("nowhere")


def test_oceanwaters_intrinsics():
    pinhole = Pinhole(1600, 1200, math.radians(21.0))
    assert pinhole.focal_px == pytest.approx(4316.4, abs=0.1)
    assert math.degrees(pinhole.vfov_rad) == pytest.approx(15.83, abs=0.01)
    assert pinhole.P(-pinhole.focal_px * BASELINE_M)[0, 3] == pytest.approx(-863.3, abs=0.1)
    assert (pinhole.cx, pinhole.cy) == (799.5, 599.5)


# ------------------------------------------------------------------------- configuration
def test_the_shipped_yaml_holds_the_defaults():
    assert CameraConfig.from_dict(yaml.safe_load(CONFIG_FILE.read_text())) == CameraConfig()


def _flatten(values: dict, prefix: str = "") -> dict:
    flat = {}
    for key, value in values.items():
        if isinstance(value, dict):
            flat.update(_flatten(value, f"{prefix}{key}/"))
        else:
            flat[f"{prefix}{key}"] = value
    return flat


def test_the_docs_table_lists_every_parameter_with_its_default():
    text = DOCS.read_text()
    table = text[text.index("| parameter | default |") :].splitlines()[2:]
    documented = {}
    for line in table:
        if not line.startswith("|"):
            break
        name, default = re.match(r"^\| `([a-z0-9_/]+)` \| `?([^|`]*)`? \|", line).groups()
        documented[name] = yaml.safe_load(default)
    assert documented == _flatten(yaml.safe_load(CONFIG_FILE.read_text()))


@pytest.mark.parametrize(
    ("params", "message"),
    [
        ({"width": 10}, "camera/width = 10 is outside"),
        ({"exposure_s": 0.0}, "camera/exposure_s = 0 s is outside"),
        ({"lights": {"left": 1.5}}, "camera/lights/left = 1.5 is outside"),
        ({"sun": {"elevation_deg": 95.0}}, "camera/sun/elevation_deg = 95 deg is outside"),
        ({"stereo": {"num_disparities": 100}}, "num_disparities = 100 must be a multiple of 16"),
        ({"stereo": {"block_size": 4}}, "camera/stereo/block_size = 4 must be odd"),
        ({"width": 320, "stereo": {"num_disparities": 336}}, "leaves no column"),
        ({"exposure": 0.01}, "unknown key 'camera/exposure' \\(did you mean 'exposure_s'\\?\\)"),
    ],
)
def test_bad_parameters_are_refused_naming_the_key(params, message):
    with pytest.raises(ConfigError, match=message):
        CameraConfig.from_dict(params)


def test_the_sun_direction_follows_azimuth_and_elevation():
    config = CameraConfig.from_dict({"sun": {"azimuth_deg": 90.0, "elevation_deg": 30.0}})
    assert np.allclose(config.sun.direction, [0.0, math.cos(math.pi / 6), 0.5])


# ----------------------------------------------------------------------------- the goals
@pytest.mark.parametrize(
    ("automatic", "exposure", "changed", "text"),
    [
        (False, 0.01, 0.01, "Exposure set to 0.01"),
        (False, 0.02, 0.02, "Exposure set to 0.02"),
        (False, 5e-05, 5e-05, "Exposure set to 5e-05"),
        (False, -1.0, None, "Exposure not changed"),
        (False, 0.0, None, "Exposure not changed"),
    ],
)
def test_exposure_goals_as_oceanwaters(automatic, exposure, changed, text):
    got = commands.exposure_change(automatic, exposure)
    assert got == changed
    assert commands.exposure_text(got) == text


@pytest.mark.parametrize(
    ("automatic", "exposure", "message"),
    [
        (True, 0.01, "^CameraSetExposure action does not support autoexposure.$"),
        (False, math.inf, "^exposure = inf s is not a finite number"),
        (False, math.nan, "^exposure = nan s is not a finite number"),
    ],
)
def test_exposure_goals_refused(automatic, exposure, message):
    with pytest.raises(GoalError, match=message):
        commands.exposure_change(automatic, exposure)


@pytest.mark.parametrize(
    ("name", "intensity", "light"),
    [("left", 0.2, "left"), ("RIGHT", 1.0, "right"), ("Left", 0.0, "left")],
)
def test_light_goals_as_oceanwaters(name, intensity, light):
    assert commands.light_change(name, intensity) == (light, intensity)
    assert commands.light_text(light) == f"{light} light intensity set successfully."


@pytest.mark.parametrize(
    ("name", "intensity", "message"),
    [
        ("left", 1.5, r"^Intensity = 1\.5 is out of range\. intensity must be within \[0, 1\]"),
        ("left", -0.0001, r"^Intensity = -0\.0001 is out of range\."),
        ("left", math.nan, r"^Intensity = nan is out of range\."),
        ("Top", 0.5, r"^'top' is not a light identifier\. name must be 'left' or 'right'"),
        ("top", 2.0, r"^Intensity = 2\.0 is out of range\."),  # the range first, as OceanWATERS
    ],
)
def test_light_goals_refused_naming_the_field(name, intensity, message):
    with pytest.raises(GoalError, match=message):
        commands.light_change(name, intensity)


@pytest.mark.parametrize(
    ("left", "right", "capturing", "watts"),
    [(1.0, 1.0, False, 9.6), (1.0, 1.0, True, 9.7), (0.5, 0.0, False, 2.4), (0.0, 0.0, True, 0.1)],
)
def test_the_power_drawn_is_oceanwaters(left, right, capturing, watts):
    drawn = commands.electrical_power_w(CameraConfig(), {"left": left, "right": right}, capturing)
    assert drawn == pytest.approx(watts)


# ------------------------------------------------------------------------------ messages
def test_messages_carry_the_arrays():
    pinhole = Pinhole(8, 6, math.radians(21.0))
    rgb = np.arange(8 * 6 * 3, dtype=np.uint8).reshape(6, 8, 3)
    image = image_msg(rgb, 0, "frame")
    assert (image.width, image.height, image.step, image.encoding) == (8, 6, 24, "rgb8")
    assert np.array_equal(np.frombuffer(image.data, np.uint8).reshape(6, 8, 3), rgb)
    assert np.array_equal(image_pixels(image), rgb)
    points = np.full((6, 8, 3), np.nan, dtype=np.float32)
    points[2, 3] = (0.1, -0.2, 2.5)
    cloud = cloud_msg(points, rgb, 0, "frame")
    assert (cloud.width, cloud.height, cloud.point_step, cloud.is_dense) == (8, 6, 16, False)
    assert [f.name for f in cloud.fields] == ["x", "y", "z", "rgb"]
    back = cloud_points(cloud)
    assert np.allclose(back[2, 3], (0.1, -0.2, 2.5))
    assert np.isnan(back[0, 0]).all()
    packed = np.frombuffer(cloud.data, "<u4").reshape(6, 8, 4)[2, 3, 3]
    assert packed == (int(rgb[2, 3, 0]) << 16) | (int(rgb[2, 3, 1]) << 8) | int(rgb[2, 3, 2])
    info = camera_info_msg(pinhole, 0, "frame", -pinhole.focal_px * BASELINE_M)
    assert info.P[3] == pytest.approx(-pinhole.focal_px * BASELINE_M)
    assert info.K[2] == pytest.approx(3.5) and info.D == [0.0] * 5


@pytest.mark.parametrize(
    ("encoding", "data", "message"),
    [
        ("mono8", bytes(48), "encoding 'mono8' with 48 bytes is not an rgb8 image"),
        ("rgb8", bytes(100), "with 100 bytes is not an rgb8 image of 6 rows of 24 bytes"),
    ],
)
def test_an_image_that_is_not_rgb8_is_refused_naming_it(encoding, data, message):
    image = image_msg(np.zeros((6, 8, 3), np.uint8), 0, "frame")
    image.encoding, image.data = encoding, data
    with pytest.raises(CameraError, match=message):
        image_pixels(image)


def test_the_readers_leave_pinocchio_out():
    """The mission reads captures with them and must not load the planners' libraries."""
    code = "import sys, ow_cameras.conversions, ow_cameras.rig; print('pinocchio' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_a_transform_message_holds_the_rotation():
    X = X_panel(LEFT_OPTICAL_FRAME)
    msg = transform_msg("a", "b", X, 0)
    q = msg.transform.rotation
    x, y, z, w = q.x, q.y, q.z, q.w
    R = np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )
    assert np.allclose(R, X[:3, :3], atol=1e-9)
    assert msg.transform.translation.x == pytest.approx(X[0, 3])


# ------------------------------------------------------------------------------ the mast
@pytest.fixture(scope="module")
def mast():
    return Mast.from_urdf()


@pytest.mark.parametrize(("pan", "tilt"), [(0.0, 0.0), (1.2, 0.7), (-2.5, -0.4), (3.1, 1.5)])
def test_the_mast_puts_the_panel_where_the_model_does(model, mast, pan, tilt):
    q = model.q_from({"j_ant_pan": pan, "j_ant_tilt": tilt})
    assert np.allclose(mast.X_base_panel(pan, tilt), model.fk(q, PANEL_LINK), atol=1e-12)


@pytest.mark.parametrize(
    "point",
    [(1.8, 0.0, -0.155), (1.65, -0.7, -0.3), (-1.0, 1.9, -0.155), (0.4, -1.5, 0.6)],
)
def test_looking_at_a_point_puts_it_on_the_heads_axis_as_the_mast_node_does(model, mast, point):
    from ow_lander.mast.pan_tilt import AntennaPointing

    pan, tilt = mast.look_at(np.array(point))
    X = mast.X_base_panel(pan, tilt) @ X_panel("StereoCamera_head_link")
    along = X[:3, 0]  # the head looks along its +x
    offset = np.asarray(point) - X[:3, 3]
    assert offset @ along > 1.0  # in front, metres away
    miss = np.linalg.norm(offset - (offset @ along) * along)
    assert miss < 1e-4 * np.linalg.norm(offset)  # the URDF's pi is 3.1416
    expected = AntennaPointing(model).look_at(np.array(point))
    assert np.allclose((pan, tilt), expected, atol=1e-4)


def test_no_tilt_looks_at_a_point_within_the_lever(mast):
    with pytest.raises(RigError, match=r"within the camera head's lever of 0\.538 m"):
        mast.look_at(np.array([0.0, 0.6, 1.2]))


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda u: u.replace('name="j_ant_tilt"', 'name="j_tilt"'), "has no joint 'j_ant_tilt'"),
        (
            lambda u: u.replace('<child link="l_ant_panel"/>', '<child link="l_x"/>'),
            "not base_link",
        ),
        (lambda u: u[: len(u) // 2], "cannot read the mast's joints"),
    ],
)
def test_a_urdf_without_the_mast_is_refused_naming_what_lacks(tmp_path, edit, message):
    urdf = tmp_path / "lander.urdf"
    urdf.write_text(edit(URDF_PATH.read_text()))
    with pytest.raises(RigError, match=message):
        Mast.from_urdf(urdf)
