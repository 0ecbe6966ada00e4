"""Balovnev model against the reference values, and the model factory the simulation uses."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from ow_dem_bridge.api import ToolState
from ow_dem_bridge.balovnev import BalovnevParams, balovnev_forces, coefficient_a
from ow_dem_bridge.errors import ConfigError, QueryError
from ow_dem_bridge.models import DEFAULT_TABLE_PATH, GRINDER_COM, make_model

HEADER = "tool,material,depth_m,progress_m,Fx_N,Fy_N,Fz_N,Tx_Nm,Ty_Nm,Tz_Nm"


def state(
    tool: str = "scoop",
    depth: float = 0.02,
    progress: float = 0.1,
    material: int = 1,
    velocity: tuple[float, float, float] = (0.1, 0.0, 0.0),
) -> ToolState:
    return ToolState(tool, material, depth, progress, np.array(velocity), np.zeros(3))


@pytest.mark.parametrize(
    ("depth", "horizontal", "vertical"),
    [
        # Spec section 5.2 [derived] examples, to their printed precision; then the caps.
        (0.01, 0.48, 0.61),
        (0.02, 1.80, 2.30),
        (0.05, 10.9, 13.9),
        (0.2, 40.0, 30.0),
        (0.0, 0.0, 0.0),
    ],
)
def test_balovnev_reference_values(depth: float, horizontal: float, vertical: float) -> None:
    h, v = balovnev_forces(depth)
    assert h == pytest.approx(horizontal, abs=0.006 if depth < 0.05 else 0.05)
    assert v == pytest.approx(vertical, abs=0.006 if depth < 0.05 else 0.05)


@pytest.mark.parametrize(("x_deg", "expected"), [(10, 0.893), (30, 1.752), (90, 13.24)])
def test_balovnev_coefficients(x_deg: float, expected: float) -> None:
    assert coefficient_a(math.radians(x_deg), math.radians(44), math.radians(28)) == pytest.approx(
        expected, abs=0.001
    )


def test_balovnev_wrench_direction_and_grinder_delegation(tmp_path: Path) -> None:
    model = make_model("balovnev", {"grinder_table": ""})
    w = model.wrench(state(depth=0.02))
    assert np.allclose(w.force, [-1.7984, 0.0, 2.3019], atol=1e-3)
    assert np.allclose(w.torque, 0.0)
    assert np.allclose(model.wrench(state(tool="grinder")).force, 0.0)
    assert np.allclose(model.wrench(state(depth=0.0)).force, 0.0)


def test_balovnev_gravity_scales_forces() -> None:
    earth = make_model("balovnev", {"gravity": 9.81, "grinder_table": ""})
    europa = make_model("balovnev", {"grinder_table": ""})
    ratio = earth.wrench(state(depth=0.02)).force[0] / europa.wrench(state(depth=0.02)).force[0]
    assert ratio == pytest.approx(9.81 / 1.315, rel=1e-9)


@pytest.mark.parametrize(
    ("params", "pattern"),
    [
        ({"gravty": 9.81}, "unknown Balovnev parameter 'gravty'"),
        ({"gravity": "high"}, "'gravity' must be a finite number"),
        ({"external_friction": 1.0}, "external_friction"),
    ],
)
def test_balovnev_bad_params(params: dict[str, object], pattern: str) -> None:
    with pytest.raises(ConfigError, match=pattern):
        BalovnevParams.from_dict(params)


@pytest.fixture
def table_path(tmp_path: Path) -> Path:
    rows = [
        "scoop,1,0.01,0.0,-1,0,2,0,0.1,0",
        "scoop,1,0.01,0.2,-3,0,4,0,0.3,0",
        "scoop,1,0.03,0.0,-5,0,6,0,0.5,0",
        "scoop,1,0.03,0.2,-7,0,8,0,0.7,0",
        # The grinder is dragged along its link +y: resisting force -y, axial push-back -x.
        "grinder,1,0.05,0.0,-2,-1,0,0,0,0.5",
        "grinder,1,0.05,0.2,-2,-1,0,0,0,0.5",
    ]
    path = tmp_path / "t.csv"
    path.write_text("\n".join([HEADER, *rows]) + "\n")
    return path


def test_table_model_interpolates(table_path: Path) -> None:
    model = make_model("table", {"path": str(table_path)})
    w = model.wrench(state(depth=0.02, progress=0.1))
    assert np.allclose(w.force, [-4.0, 0.0, 5.0])
    assert np.allclose(w.torque, [0.0, 0.4, 0.0])
    assert np.allclose(model.wrench(state(depth=0.0)).force, 0.0)


def test_table_model_material_override(table_path: Path) -> None:
    with pytest.raises(QueryError, match="material 2"):
        make_model("table", {"path": str(table_path)}).wrench(state(material=2))
    forced = make_model("table", {"path": str(table_path), "material": 1})
    assert np.allclose(forced.wrench(state(material=2, depth=0.01, progress=0.0)).force, [-1, 0, 2])


@pytest.mark.parametrize(
    ("velocity", "lateral_direction"),
    [
        ((0.0, 0.1, 0.0), (0.0, 1.0, 0.0)),  # the table's own drag direction
        ((0.0, 0.0, 0.1), (0.0, 0.0, 1.0)),
        ((0.05, -0.1, 0.0), (0.0, -1.0, 0.0)),
    ],
)
def test_grinder_lateral_force_opposes_its_motion(
    table_path: Path, velocity: tuple[float, float, float], lateral_direction: tuple[float, ...]
) -> None:
    model = make_model("table", {"path": str(table_path)})
    w = model.wrench(state(tool="grinder", depth=0.05, velocity=velocity))
    assert w.force[0] == pytest.approx(-2.0)
    assert np.allclose(w.force[1:], -np.asarray(lateral_direction)[1:])
    # Torque about the COM stays consistent with a force turned about the axis through the origin.
    com = np.asarray(GRINDER_COM)
    assert np.allclose(w.torque + np.cross(com, w.force), _turned_axis_torque(velocity))


def _turned_axis_torque(velocity: tuple[float, float, float]) -> np.ndarray:
    com = np.asarray(GRINDER_COM)
    about_origin = np.array([0.0, 0.0, 0.5]) + np.cross(com, [-2.0, -1.0, 0.0])
    angle = math.atan2(velocity[2], velocity[1])
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]]) @ about_origin


def test_grinder_lateral_force_fades_when_not_moving_sideways(table_path: Path) -> None:
    model = make_model("table", {"path": str(table_path)})
    w = model.wrench(state(tool="grinder", depth=0.05, velocity=(0.02, 0.0, 0.0)))
    assert np.allclose(w.force, [-2.0, 0.0, 0.0])


def test_none_model_is_zero() -> None:
    w = make_model("none", {}).wrench(state())
    assert np.allclose(w.force, 0.0) and np.allclose(w.torque, 0.0)


@pytest.mark.parametrize(
    ("name", "params", "pattern"),
    [
        (
            "dem",
            {},
            "unknown terrain-force model 'dem'; choose one of none, table, balovnev, yade, bridge",
        ),
        ("bridge", {}, r"'bridge' listens on ROS topics: the simulation node creates it"),
        ("table", {"pth": "x.csv"}, "unknown 'table' model parameter"),
        ("table", {"material": "sand"}, "'material' must be an integer"),
        ("table", {"pass_number": 1.5}, "'pass_number' must be an integer"),
    ],
)
def test_factory_errors(name: str, params: dict[str, object], pattern: str) -> None:
    with pytest.raises(ConfigError, match=pattern):
        make_model(name, params)


@pytest.mark.skipif(not DEFAULT_TABLE_PATH.exists(), reason="no shipped table (make dem-tables)")
def test_shipped_table_covers_both_tools_and_resists_the_dig() -> None:
    model = make_model("table", {})
    scoop = model.wrench(state(depth=0.02, progress=0.2))
    assert scoop.force[0] < 0  # resists the dig along link +x
    grinder = model.wrench(state(tool="grinder", depth=0.04, progress=0.1, velocity=(0, 0.1, 0)))
    assert grinder.force[1] < 0  # resists the drag
