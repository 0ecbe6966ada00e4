"""The tool tracker on its own (pinocchio kinematics, a flat terrain, no pybullet): dig progress,
the terrain-force model's wrench as joint torques, snapshots and the wrist sensor, each checked
against an independent pinocchio formulation (LOCAL Jacobians, explicit transforms)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from ow_dem_bridge.api import ToolState, Wrench
from ow_description.description import (
    DEFAULT_GROUND_Z,
    EUROPA_GRAVITY,
    SCOOP_ABOVE_GROUND,
    SCOOP_BELOW_GROUND,
    SCOOP_LINK,
    SCOOP_TIP_FRAME,
    URDF_PATH,
)
from ow_description.terrain import HeightMap
from ow_sim_bullet.carving import TerrainCarver
from ow_sim_bullet.config import SimConfig
from ow_sim_bullet.joints import JointSample
from ow_sim_bullet.tool_forces import ToolForces
from ow_sim_bullet.tool_tracking import DIG_END_GAP_S, WRIST_FT_LINK, ToolTracker

MATERIAL = 3
CONFIG = SimConfig(terrain_material=MATERIAL)
COM = np.array([0.01, -0.02, 0.03])


class FakeSurface:
    floor = -1.0

    def refresh(self, heights: np.ndarray, rows: tuple[int, int], cols: tuple[int, int]) -> int:
        return 0

    def remove(self) -> None:
        """Nothing to remove."""


class ConstantModel:
    """A terrain-force model that pushes every tool in the ground the same way."""

    def __init__(self) -> None:
        self.wrench_given = Wrench(np.array([1.0, -2.0, 10.0]), np.array([0.1, 0.0, -0.3]))
        self.states: list[ToolState] = []

    def wrench(self, state: ToolState) -> Wrench:
        self.states.append(state)
        return self.wrench_given


@pytest.fixture()
def model() -> pin.Model:
    model = pin.buildModelFromUrdf(str(URDF_PATH))
    model.gravity.linear = np.array([0.0, 0.0, -EUROPA_GRAVITY])
    return model


@pytest.fixture()
def tracker(model) -> ToolTracker:
    ground = HeightMap.flat(DEFAULT_GROUND_Z, half_extent=3.0, resolution=0.04)
    terrain = TerrainCarver(ground, CONFIG, {}, lambda _: FakeSurface())
    return ToolTracker(
        model,
        ToolForces({"scoop": 10, "grinder": 11}),
        {"scoop": COM, "grinder": np.zeros(3)},
        terrain,
        CONFIG,
        frames=[frame.name for frame in model.frames],
    )


def sample(model: pin.Model, pose: dict[str, float], time: float = 0.0) -> JointSample:
    q = np.zeros(model.nq)
    for name, value in pose.items():
        q[model.joints[model.getJointId(name)].idx_q] = value
    zeros = np.zeros(model.nq)
    return JointSample(time, tuple(model.names[1:]), q, zeros, zeros, zeros, q)


def test_dig_progress_survives_a_moment_out_of_the_ground(tracker):
    X = pin.SE3.Identity()
    zero = np.zeros(3)

    def at(t, x, depth):
        return tracker.track_dig("scoop", t, X, np.array([x, 0.0, -0.2]), zero, zero, depth)

    at(0.0, 1.60, 0.03)
    at(0.5, 1.65, 0.03)
    # The carving ahead of the tip zeroes its depth for a moment: no state, but the cut goes on.
    assert at(0.6, 1.66, 0.0) is None
    state = at(0.7, 1.67, 0.02)
    assert state.progress == pytest.approx(0.07)
    assert (state.tool, state.material, state.depth) == ("scoop", MATERIAL, 0.02)
    # Out for longer than DIG_END_GAP_S: the next dig starts from zero.
    at(0.8, 1.70, 0.0)
    at(0.8 + DIG_END_GAP_S + 0.2, 1.80, 0.0)
    assert at(2.1, 1.81, 0.02).progress == pytest.approx(0.0)
    assert at(2.2, 1.83, 0.02).progress == pytest.approx(0.02)


def test_a_snapshot_places_the_tool_where_pinocchio_does(model, tracker):
    data = model.createData()
    joints = sample(model, SCOOP_ABOVE_GROUND)
    pin.framesForwardKinematics(model, data, joints.position)
    snapshot = tracker.snapshot("scoop", joints, 0.0, track=True)
    assert np.allclose(snapshot.tip, data.oMf[model.getFrameId(SCOOP_TIP_FRAME)].translation)
    assert np.allclose(snapshot.X_base_link, data.oMf[model.getFrameId(SCOOP_LINK)].homogeneous)
    assert snapshot.terrain_z == pytest.approx(DEFAULT_GROUND_Z)
    assert snapshot.depth == 0.0 and snapshot.progress == 0.0  # 5 cm above the ground
    assert np.allclose(snapshot.force, 0.0) and snapshot.model_wrench is None
    poses = tracker.link_poses(joints.position)
    assert np.allclose(poses[SCOOP_LINK], snapshot.X_base_link)


def test_the_models_wrench_acts_as_the_links_jacobian_transposed(model, tracker):
    """Below the ground the model is asked with the tool's state; its wrench (link frame, about
    the COM) gives J^T w at the joints, and the snapshot reports it about the link origin."""
    joints = sample(model, SCOOP_BELOW_GROUND)
    force_model = ConstantModel()
    tracker.place(joints.position, joints.velocity)
    torque = tracker.apply_model(joints.position, 0.0, force_model)
    (state,) = force_model.states  # the grinder is above the ground
    assert state.tool == "scoop" and state.depth == pytest.approx(0.05, abs=0.01)
    f, tau = force_model.wrench_given.force, force_model.wrench_given.torque
    about_origin = np.concatenate((f, tau + np.cross(COM, f)))
    data = model.createData()
    jacobian = pin.computeFrameJacobian(
        model, data, joints.position, model.getFrameId(SCOOP_LINK), pin.LOCAL
    )
    assert np.allclose(torque, jacobian.T @ about_origin, atol=1e-12)

    tracker.forces.add_contacts([])  # the step
    snapshot = tracker.snapshot("scoop", joints, 0.01, track=False)
    assert np.allclose(snapshot.force, f) and np.allclose(snapshot.torque, about_origin[3:])
    assert snapshot.model_wrench is force_model.wrench_given
    assert snapshot.model_depth == state.depth
    assert snapshot.progress == 0.0  # the first step of the dig

    # The wrist sensor: the same wrench about j_dist_pitch, in l_dist.
    force, torque_wrist = tracker.wrist_wrench(joints)
    pin.framesForwardKinematics(model, data, joints.position)
    X_link = data.oMf[model.getFrameId(SCOOP_LINK)]
    X_dist = data.oMf[model.getFrameId(WRIST_FT_LINK)]
    X_dist_link = X_dist.actInv(X_link)
    expected = X_dist_link.act(pin.Force(f, about_origin[3:]))
    assert np.allclose(force, expected.linear) and np.allclose(torque_wrist, expected.angular)


def test_contacts_of_the_last_step_act_as_joint_torques(model, tracker):
    joints = sample(model, SCOOP_BELOW_GROUND)
    assert tracker.contact_torque(joints.position) is None
    point, force = np.array([1.7, 0.0, DEFAULT_GROUND_Z]), np.array([0.5, 0.0, 8.0])
    row = (0, 1, 2, 10, -1, tuple(point), (0, 0, 0), (0.0, 0.0, 1.0), 0.0, 8.0)
    tracker.forces.add_contacts([(*row, 0.5, (1.0, 0.0, 0.0), 0.0, (0.0, 1.0, 0.0))])
    torque = tracker.contact_torque(joints.position)
    data = model.createData()
    fid = model.getFrameId(SCOOP_LINK)
    pin.computeJointJacobians(model, data, joints.position)
    pin.updateFramePlacements(model, data)
    jacobian = pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED)
    arm = point - data.oMf[fid].translation
    assert np.allclose(torque, jacobian.T @ np.concatenate((force, np.cross(arm, force))))


def test_reset_forgets_the_digs_and_forces(model, tracker):
    joints = sample(model, SCOOP_BELOW_GROUND)
    tracker.place(joints.position, joints.velocity)
    tracker.apply_model(joints.position, 0.0, ConstantModel())
    tracker.reset()
    tracker.forces.add_contacts([])
    snapshot = tracker.snapshot("scoop", joints, 0.01, track=False)
    assert snapshot.model_wrench is None and np.allclose(snapshot.force, 0.0)


def test_a_tool_above_all_terrain_is_tracked_as_with_its_full_kinematics(model, tracker):
    """Above every part of the terrain the model's step skips the tool's velocities: through a
    dig that goes in, leaves the ground for good and goes in again, the torques, the model's
    states and the progress are bit for bit those of the full kinematics."""
    ground = HeightMap.flat(DEFAULT_GROUND_Z, half_extent=3.0, resolution=0.04)
    full = ToolTracker(
        model,
        ToolForces({"scoop": 10, "grinder": 11}),
        {"scoop": COM, "grinder": np.zeros(3)},
        TerrainCarver(ground, CONFIG, {}, lambda _: FakeSurface()),
        CONFIG,
        frames=[frame.name for frame in model.frames],
    )
    full._terrain.above = lambda point: False  # never skips
    above, below = sample(model, SCOOP_ABOVE_GROUND), sample(model, SCOOP_BELOW_GROUND)
    models = ConstantModel(), ConstantModel()
    skipped = 0
    for k, s in enumerate([*np.linspace(0, 1, 20), *np.linspace(1, 0, 30), *np.linspace(0, 1, 20)]):
        q = (1 - s) * above.position + s * below.position
        v = np.full(model.nv, 0.1 * (k % 3 - 1))
        now = 0.1 * k
        torques = []
        for tool_tracker, force_model in zip((tracker, full), models, strict=True):
            tool_tracker.place(q, v)
            torques.append(tool_tracker.apply_model(q, now, force_model))
        if torques[0] is None:
            assert torques[1] is None
        else:
            assert np.array_equal(torques[0], torques[1])
        for tool in ("scoop", "grinder"):
            assert tracker._tools[tool].progress == full._tools[tool].progress
        tip = tracker._data.oMf[model.getFrameId(SCOOP_TIP_FRAME)].translation
        skipped += bool(tracker._terrain.above(tip))
    assert len(models[0].states) == len(models[1].states) > 10
    for a, b in zip(*(m.states for m in models), strict=True):
        assert (a.tool, a.material, a.depth, a.progress) == (
            b.tool,
            b.material,
            b.depth,
            b.progress,
        )
        assert np.array_equal(a.velocity, b.velocity)
        assert np.array_equal(a.angular_velocity, b.angular_velocity)
    assert skipped > 10  # the scoop spent steps above the terrain: the short cut was taken
