"""Terrain checks of many configurations at once: forward kinematics of the revolute joints and
the links' terrain sample points in numpy, one bilinear height lookup for all of them. No ROS.

The planner checks paths state by state at a fine joint resolution; per state, Python's overhead
around pinocchio's forward kinematics and the per-link tests was most of a plan's time. Here a
whole path is one set of array operations, with the same answer as
:meth:`~ow_description.collision.CollisionChecker.in_collision`'s terrain part for each state: a
link is below the terrain when one of its sample points is below the height map (+ margin).

Configurations are ``Q: (n, 9) rad`` in pinocchio order (see :mod:`ow_description.model`).
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ow_description.collision import CollisionChecker
from ow_description.errors import ModelError
from ow_description.terrain import HeightMap

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]

#: Unit axes of pinocchio's axis-aligned revolute joints.
_ALIGNED_AXES = {
    "JointModelRX": (1.0, 0.0, 0.0),
    "JointModelRY": (0.0, 1.0, 0.0),
    "JointModelRZ": (0.0, 0.0, 1.0),
}


def _axis(joint: pin.JointModel) -> FloatArray:
    """(3,) unit axis of a revolute joint in its own frame.

    Raises:
        ModelError: not a revolute joint.
    """
    kind = joint.shortname()
    if kind in _ALIGNED_AXES:
        return np.array(_ALIGNED_AXES[kind])
    if kind == "JointModelRevoluteUnaligned":
        axis = np.array(joint.extract().axis, dtype=np.float64)
        return axis / np.linalg.norm(axis)
    msg = f"batch kinematics handles revolute joints only, not {kind}"
    raise ModelError(msg)


class BatchKinematics:
    """Placements of joint frames in base_link for many configurations (revolute joints only).

    Args:
        model: the pinocchio model (its joint tree, placements and axes are copied).

    Raises:
        ModelError: the model has a joint that is not revolute.
    """

    def __init__(self, model: pin.Model) -> None:
        self.nq = int(model.nq)
        self._parents = [int(p) for p in model.parents]
        self._idx_q = [int(j.idx_q) for j in model.joints]
        self._translations = [
            np.array(M.translation, dtype=np.float64) for M in model.jointPlacements
        ]
        # A joint's placement times its rotation by angle a (Rodrigues) is
        # along + cos(a) * across + sin(a) * turn, with these three fixed (3, 3) matrices.
        self._along, self._across, self._turn = [], [], []
        for joint, M in zip(model.joints, model.jointPlacements, strict=True):
            R = np.array(M.rotation, dtype=np.float64)
            a = _axis(joint) if joint.idx_q >= 0 else np.zeros(3)
            K = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
            along = R @ np.outer(a, a)
            self._along.append(along)
            self._across.append(R - along)
            self._turn.append(R @ K)

    def placements(
        self, Q: FloatArray, joints: Iterable[int]
    ) -> dict[int, tuple[FloatArray, FloatArray]]:
        """``{joint: (R (n, 3, 3), t (n, 3))}``: the frames of ``joints`` (and of their
        ancestors) in base_link at each configuration ``Q: (n, nq)`` rad, as pinocchio's
        ``oMi``."""
        n = len(Q)
        out: dict[int, tuple[FloatArray, FloatArray]] = {}

        def place(j: int) -> tuple[FloatArray, FloatArray]:
            if j in out:
                return out[j]
            angle = Q[:, self._idx_q[j], None, None]
            local = self._along[j] + np.cos(angle) * self._across[j] + np.sin(angle) * self._turn[j]
            parent = self._parents[j]
            if parent == 0:
                out[j] = (local, np.broadcast_to(self._translations[j], (n, 3)))
            else:
                R_parent, t_parent = place(parent)
                out[j] = (R_parent @ local, t_parent + R_parent @ self._translations[j])
            return out[j]

        for j in joints:
            if j:
                place(j)
            else:
                out[0] = (np.broadcast_to(np.eye(3), (n, 3, 3)), np.zeros((n, 3)))
        return out


class BatchTerrainCheck:
    """Which of many configurations put a link below the terrain.

    Args:
        model: the pinocchio model the checker's sample points belong to.
        checker: the collision checker whose terrain sample points and blocks are used.
    """

    def __init__(self, model: pin.Model, checker: CollisionChecker) -> None:
        self.kinematics = BatchKinematics(model)
        self.checker = checker

    def below(
        self,
        Q: FloatArray,
        terrain: HeightMap,
        links: Iterable[str],
        margin: float = 0.0,
    ) -> BoolArray:
        """(n,) True where a configuration of ``Q: (n, 9)`` rad has a sample point of one of
        ``links`` below ``terrain`` + ``margin`` m."""
        Q = np.asarray(Q, dtype=np.float64).reshape(-1, self.kinematics.nq)
        samples = self.checker.link_samples(links)
        hit = np.zeros(len(Q), dtype=bool)
        if not samples or not len(Q):
            return hit
        blocks = self.checker.blocks(terrain)
        frames = self.kinematics.placements(Q, {s.joint for s in samples})
        # No bilinear height exceeds the map's highest node, nor those of the blocks under a
        # link's bounding sphere: most links of most states are skipped on these bounds.
        centres = np.stack([frames[s.joint][0] @ s.centre + frames[s.joint][1] for s in samples])
        radii = np.array([s.radius for s in samples])[:, None]
        lowest = centres[:, :, 2] - radii
        link, rows = np.nonzero(lowest <= blocks.top + margin)
        local = np.full(lowest.shape, -np.inf)
        local[link, rows] = (
            blocks.highest_many(centres[link, rows, 0], centres[link, rows, 1], radii[link, 0])
            + margin
        )
        near_terrain = lowest <= local
        for k in np.flatnonzero(near_terrain.any(axis=1)):
            sample = samples[k]
            rows = np.flatnonzero(near_terrain[k] & ~hit)
            if not len(rows):
                continue
            R, t = frames[sample.joint]
            z = np.einsum("nj,pj->np", R[rows, 2, :], sample.points) + t[rows, 2, None]
            r_near, p_near = np.nonzero(z < local[k, rows, None])
            if not len(r_near):
                continue
            R_near = R[rows[r_near], :2, :]
            xy = np.einsum("nij,nj->ni", R_near, sample.points[p_near]) + t[rows[r_near], :2]
            depth = terrain.height_at(xy[:, 0], xy[:, 1]) + margin - z[r_near, p_near]
            hit[rows[r_near[depth > 0.0]]] = True
        return hit
