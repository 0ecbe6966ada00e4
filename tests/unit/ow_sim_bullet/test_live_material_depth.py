"""The simulation asks a live terrain-force model (the DEM, ``terrain_forces: yade``) about the
scoop in a dig phase wherever its tip is below the top of the material the model holds (its
bed's loose layer: the grinder's cuttings on the floor of its trench), also at depth 0 below the
height map; the other models are asked only below the height map, as before."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from ow_dem_bridge.api import ToolState, Wrench
from ow_description.description import (
    DEFAULT_GROUND_Z,
    EUROPA_GRAVITY,
    SCOOP_ABOVE_GROUND,
    SCOOP_TIP_FRAME,
    URDF_PATH,
)
from ow_description.terrain import HeightMap
from ow_sim_bullet.carving import TerrainCarver
from ow_sim_bullet.config import SimConfig
from ow_sim_bullet.tool_forces import ToolForces
from ow_sim_bullet.tool_tracking import DigPhase, ToolTracker

CONFIG = SimConfig(terrain_material=1)


class FakeSurface:
    floor = -1.0

    def refresh(self, heights: np.ndarray, rows: tuple[int, int], cols: tuple[int, int]) -> int:
        return 0

    def remove(self) -> None:
        """Nothing to remove."""


class RecordingModel:
    """Answers every state with the same wrench and keeps the states."""

    def __init__(self) -> None:
        self.states: list[ToolState] = []

    def wrench(self, state: ToolState) -> Wrench:
        self.states.append(state)
        return Wrench(np.array([1.0, 0.0, 0.0]), np.zeros(3))


@pytest.fixture(scope="module")
def model() -> pin.Model:
    model = pin.buildModelFromUrdf(str(URDF_PATH))
    model.gravity.linear = np.array([0.0, 0.0, -EUROPA_GRAVITY])
    return model


def scoop_above_ground(model: pin.Model) -> tuple[np.ndarray, float]:
    """Joint positions with the scoop tip above the flat ground, and the tip's z (m)."""
    q = np.zeros(model.nq)
    for name, value in SCOOP_ABOVE_GROUND.items():
        q[model.joints[model.getJointId(name)].idx_q] = value
    data = model.createData()
    pin.framesForwardKinematics(model, data, q)
    return q, float(data.oMf[model.getFrameId(SCOOP_TIP_FRAME)].translation[2])


def ask(
    model: pin.Model, phase: DigPhase, material_top: float | None
) -> tuple[RecordingModel, float]:
    """Apply a recording model once with the scoop above the height map in ``phase``, the live
    material's top at ``material_top`` m (None: no live model); (the model, the tip's z)."""
    ground = HeightMap.flat(DEFAULT_GROUND_Z, half_extent=3.0, resolution=0.04)
    terrain = TerrainCarver(ground, CONFIG, {}, lambda _: FakeSurface())
    tracker = ToolTracker(
        model,
        ToolForces({"scoop": 10, "grinder": 11}),
        {"scoop": np.zeros(3), "grinder": np.zeros(3)},
        terrain,
        CONFIG,
        frames=[frame.name for frame in model.frames],
        material_top=None if material_top is None else (lambda x, y: material_top),
    )
    tracker.dig.phase = phase
    q, tip_z = scoop_above_ground(model)
    tracker.place(q, np.zeros(model.nv))
    recorder = RecordingModel()
    tracker.apply_model(q, 1.0, recorder)
    return recorder, tip_z


def test_the_scoop_in_the_live_models_loose_layer_is_asked_at_depth_0_in_a_dig(model):
    _, tip_z = scoop_above_ground(model)
    assert tip_z > DEFAULT_GROUND_Z + 0.01  # above the height map: its depth there is 0
    recorder, _ = ask(model, DigPhase.PLOWING, tip_z + 0.03)
    (state,) = recorder.states
    assert state.tool == "scoop" and state.digging is True
    assert state.depth == pytest.approx(0.03, abs=1e-9)  # below the material's top


@pytest.mark.parametrize(
    ("case", "phase", "above_tip"),
    [
        ("live model, not in a dig phase", DigPhase.NOT_DIGGING, 0.03),
        ("live model, tip above its material", DigPhase.PLOWING, -0.01),
        ("table or Balovnev (no material top), in a dig", DigPhase.PLOWING, None),
    ],
)
def test_otherwise_a_tool_above_the_height_map_is_not_asked(model, case, phase, above_tip):
    _, tip_z = scoop_above_ground(model)
    top = None if above_tip is None else tip_z + above_tip
    recorder, _ = ask(model, phase, top)
    assert recorder.states == [], case
