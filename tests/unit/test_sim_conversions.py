"""tf transforms built from URDF joints agree with pinocchio's forward kinematics."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from ow_lander.description import URDF_PATH
from ow_sim_bullet.conversions import joint_frames, quaternion_from_matrix, stamp


def quaternion_matrix(q: tuple[float, float, float, float]) -> np.ndarray:
    return pin.Quaternion(q[3], q[0], q[1], q[2]).toRotationMatrix()


def test_joint_transforms_compose_to_pinocchio_link_poses():
    text = URDF_PATH.read_text()
    model = pin.buildModelFromUrdf(str(URDF_PATH))
    data = model.createData()
    rng = np.random.default_rng(3)
    q = rng.uniform(-1.0, 1.0, model.nq)
    pin.framesForwardKinematics(model, data, q)
    angle = {model.names[i]: q[model.joints[i].idx_q] for i in range(1, model.njoints)}
    poses = {"base_link": np.eye(4)}
    frames = joint_frames(text)
    assert {f.child for f in frames} >= {"l_scoop_tip", "l_grinder_tip", "lander_sample_dock0"}
    for _ in frames:  # resolve in tree order
        for frame in frames:
            if frame.parent in poses and frame.child not in poses:
                local = np.eye(4)
                local[:3, :3] = quaternion_matrix(frame.rotation_at(angle.get(frame.joint, 0.0)))
                local[:3, 3] = frame.translation
                poses[frame.child] = poses[frame.parent] @ local
    for link, pose in poses.items():
        expected = data.oMf[model.getFrameId(link)].homogeneous
        assert np.allclose(pose, expected, atol=1e-9), link


def test_quaternion_from_matrix_round_trips():
    rng = np.random.default_rng(0)
    for _ in range(20):
        rotation = pin.exp3(rng.normal(size=3) * 2.0)
        assert np.allclose(quaternion_matrix(quaternion_from_matrix(rotation)), rotation)


def test_stamp_is_exact_to_the_nanosecond():
    assert stamp(12.34).secs == 12 and stamp(12.34).nsecs == 340_000_000
    assert stamp(0.01 * 3).nsecs == 30_000_000
