"""Kinematics, dynamics and collision checking of the lander (pinocchio; collision checks by
:mod:`ow_description.collision`), no ROS.

Conventions (used across the project):
* ``q`` is the full configuration, shape (9,) rad, in *pinocchio's* joint order; never index it
  by position. Use :meth:`LanderModel.q_from` / :meth:`LanderModel.joint_values` to go between
  ``{joint name: angle}`` and ``q``, and :attr:`LanderModel.arm_idx` for the six arm joints.
* The continuous joints (:data:`~ow_description.description.CONTINUOUS_JOINTS`, marked in
  :attr:`LanderModel.continuous`) hold any angle; their URDF limits are only the travel of the
  simulated joint, and an angle and that angle plus whole turns are the same configuration.
* ``X_a_b`` is the pose of frame b expressed in frame a, a 4x4 homogeneous matrix; every pose here
  is ``X_base_<frame>`` with ``base_link`` as frame a (REP 103/105).
* Jacobians are "local world aligned": rows (v_x, v_y, v_z, w_x, w_y, w_z) of the frame's origin in
  base_link axes, columns one per joint of ``q``.
* Gravity is Europa's (:data:`~ow_description.description.EUROPA_GRAVITY`) along -z of base_link,
  unless given.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Mapping
from pathlib import Path

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ow_description.collision import ARM_LINKS, CollisionChecker, CollisionReport
from ow_description.description import (
    ARM_JOINTS,
    BASE_FRAME,
    CONTINUOUS_JOINTS,
    EUROPA_GRAVITY,
    URDF_PATH,
    nearest_turn,
    wrap_angle,
)
from ow_description.errors import IKError, ModelError
from ow_description.terrain import HeightMap

FloatArray = npt.NDArray[np.float64]

#: IK gives up on a start whose error (m + rad) fell by less than IK_STALL_GAIN (relative) over
#: the last IK_STALL_ITERATIONS iterations: converging starts gain far more (damped least
#: squares converges in 5-20 iterations from a start that leads to a solution).
IK_STALL_ITERATIONS = 5
IK_STALL_GAIN = 0.01

_EYE = {3: np.eye(3), 6: np.eye(6)}


class LanderModel:
    """The lander arm: forward and inverse kinematics, dynamics, and collision checks.

    Not thread-safe: each thread should own its instance (pinocchio data is shared state, also
    with its :attr:`collision` checker).

    Args:
        urdf_path: robot description to load (default: the project's lander URDF).
        gravity: m/s^2, magnitude of gravity along -z of base_link.

    Attributes:
        collision: the checker behind :meth:`collision_report` and :meth:`in_collision`.
        continuous: (9,) True for the continuous joints (no position limit; their URDF limits
            bound only where an angle may be written, see the module doc).
    """

    def __init__(self, urdf_path: Path = URDF_PATH, gravity: float = EUROPA_GRAVITY) -> None:
        path = Path(urdf_path)
        if not path.is_file():
            msg = f"robot description {path} does not exist"
            raise ModelError(msg)
        self.model = pin.buildModelFromUrdf(str(path))
        self.model.gravity.linear = np.array([0.0, 0.0, -gravity])
        self.data = self.model.createData()
        self.joint_names: tuple[str, ...] = tuple(self.model.names)[1:]
        self._q_index = {
            name: self.model.joints[self.model.getJointId(name)].idx_q for name in self.joint_names
        }
        self.arm_idx = np.array([self._q_index[name] for name in ARM_JOINTS], dtype=np.intp)
        self.lower = np.array(self.model.lowerPositionLimit, dtype=np.float64)
        self.upper = np.array(self.model.upperPositionLimit, dtype=np.float64)
        self.velocity_limit = np.array(self.model.velocityLimit, dtype=np.float64)
        self.effort_limit = np.array(self.model.effortLimit, dtype=np.float64)
        self.continuous = np.zeros(self.nq, dtype=bool)
        self.continuous[[self._q_index[name] for name in CONTINUOUS_JOINTS]] = True
        self.collision = CollisionChecker(self.model, self.data, path)
        self._frame_ids: dict[str, int] = {}
        self._joint_columns: dict[tuple[str, ...], npt.NDArray[np.intp]] = {}

    # ----------------------------------------------------------------- configuration helpers
    @property
    def nq(self) -> int:
        """Number of joints (9)."""
        return int(self.model.nq)

    def index(self, joint: str) -> int:
        """Position of ``joint`` in ``q``.

        Raises:
            ModelError: no joint of that name.
        """
        try:
            return int(self._q_index[joint])
        except KeyError:
            msg = f"unknown joint {joint!r}; the lander's joints are {', '.join(self.joint_names)}"
            raise ModelError(msg) from None

    def q_from(self, values: Mapping[str, float], base: FloatArray | None = None) -> FloatArray:
        """Configuration (9,) rad from ``{joint: angle}``; joints not named keep ``base`` (or 0)."""
        q = np.zeros(self.nq) if base is None else np.array(base, dtype=np.float64)
        for name, value in values.items():
            q[self.index(name)] = value
        return q

    def joint_values(self, q: FloatArray, joints: Iterable[str] | None = None) -> dict[str, float]:
        """``{joint: angle}`` (rad) of ``q`` for ``joints`` (default all)."""
        return {name: float(q[self.index(name)]) for name in (joints or self.joint_names)}

    def within_limits(self, q: FloatArray, tolerance: float = 1e-9) -> bool:
        """True when every joint of ``q`` lies within its URDF limits."""
        return bool(np.all(q >= self.lower - tolerance) and np.all(q <= self.upper + tolerance))

    def limit_violations(self, q: FloatArray, joints: Iterable[str] = ARM_JOINTS) -> list[str]:
        """Human-readable descriptions of the joints of ``q`` outside their limits. A continuous
        joint has none: any finite angle of it is valid (as a goal, the same angle less whole
        turns)."""
        out = []
        for name in joints:
            i = self.index(name)
            if self.continuous[i]:
                if not np.isfinite(q[i]):
                    out.append(f"{name}={q[i]} rad is not a finite angle")
            elif not self.lower[i] - 1e-9 <= q[i] <= self.upper[i] + 1e-9:
                out.append(
                    f"{name}={q[i]:.3f} rad is outside [{self.lower[i]:.3f}, {self.upper[i]:.3f}]"
                )
        return out

    def frame_id(self, frame: str) -> int:
        """pinocchio id of ``frame``.

        Raises:
            ModelError: no frame of that name.
        """
        fid = self._frame_ids.get(frame)
        if fid is None:
            if not self.model.existFrame(frame):
                msg = f"unknown frame {frame!r}"
                raise ModelError(msg)
            fid = self._frame_ids[frame] = int(self.model.getFrameId(frame))
        return fid

    def _columns(self, joints: tuple[str, ...]) -> npt.NDArray[np.intp]:
        """Positions of ``joints`` in ``q`` (cached: IK asks for the arm's on every waypoint).

        Raises:
            ModelError: an unknown joint.
        """
        cols = self._joint_columns.get(joints)
        if cols is None:
            cols = np.array([self.index(j) for j in joints], dtype=np.intp)
            self._joint_columns[joints] = cols
        return cols

    def chain_columns(self, frame: str) -> npt.NDArray[np.intp]:
        """Positions in ``q`` of the joints that move ``frame`` (its kinematic chain from
        base_link), in chain order.

        Raises:
            ModelError: no frame of that name.
        """
        joint = self.model.frames[self.frame_id(frame)].parentJoint
        return np.array(
            [self.model.joints[j].idx_q for j in self.model.supports[joint] if j > 0],
            dtype=np.intp,
        )

    # ----------------------------------------------------------------------------- kinematics
    def fk(self, q: FloatArray, frame: str) -> FloatArray:
        """``X_base_frame``: pose (4, 4) of ``frame`` in base_link at configuration ``q``."""
        fid = self.frame_id(frame)
        pin.forwardKinematics(self.model, self.data, q)
        return np.asarray(pin.updateFramePlacement(self.model, self.data, fid).homogeneous)

    def position(self, q: FloatArray, frame: str) -> FloatArray:
        """(3,) m, origin of ``frame`` in base_link."""
        return self.fk(q, frame)[:3, 3].copy()

    def jacobian(self, q: FloatArray, frame: str) -> FloatArray:
        """(6, 9) frame Jacobian of ``frame``'s origin, local-world-aligned (see module doc)."""
        fid = self.frame_id(frame)
        return np.asarray(
            pin.computeFrameJacobian(self.model, self.data, q, fid, pin.LOCAL_WORLD_ALIGNED)
        )

    def ik(
        self,
        frame: str,
        position: FloatArray,
        q0: FloatArray,
        rotation: FloatArray | None = None,
        joints: Iterable[str] = ARM_JOINTS,
        position_tolerance: float = 1e-4,
        rotation_tolerance: float = 1e-3,
        max_iterations: int = 200,
        restarts: int = 40,
        seed: int = 0,
        try_q0: bool = True,
    ) -> FloatArray:
        """Damped-least-squares inverse kinematics for the origin of ``frame``.

        Starts at ``q0`` and, if that fails, from ``restarts`` seeded random configurations
        within the joint limits (a continuous joint within half a turn of 0: one turn holds all
        its orientations). Joints not in ``joints`` keep their value from ``q0``.

        Args:
            frame: frame to place, e.g. ``l_scoop_tip`` or ``l_grinder_tip``.
            position: (3,) m, target origin in base_link.
            q0: (9,) rad, initial guess (also the value of the joints not moved).
            rotation: (3, 3) target orientation in base_link, or None for position only.
            joints: joints IK may move.
            position_tolerance: m, accepted position error.
            rotation_tolerance: rad, accepted orientation error.
            max_iterations: iterations per start.
            restarts: random starts tried after ``q0``.
            seed: seed of those random starts (same inputs, same answer).
            try_q0: start at ``q0`` first; when false, only the random starts are tried (their
                outcome then does not depend on ``q0``'s values of ``joints``).

        Returns:
            (9,) rad configuration within the joint limits reaching the target (a continuous
            joint at whichever turn the search ended on: :func:`nearest_turn
            <ow_description.description.nearest_turn>` picks the one wanted).

        Raises:
            IKError: no start converged; the message gives the best residual reached.
        """
        target = np.asarray(position, dtype=np.float64)
        best = (np.inf, np.inf)
        for q, pos_err, rot_err in self._ik_attempts(
            frame,
            target,
            q0,
            rotation,
            joints,
            position_tolerance,
            rotation_tolerance,
            max_iterations,
            restarts,
            seed,
            try_q0,
        ):
            if pos_err <= position_tolerance and rot_err <= rotation_tolerance:
                return q
            best = min(best, (pos_err, rot_err))
        what = "pose" if rotation is not None else "position"
        msg = (
            f"{frame} cannot reach the {what} "
            f"({target[0]:.3f}, {target[1]:.3f}, {target[2]:.3f}) m in base_link within the "
            f"joint limits: best error {best[0] * 1000:.1f} mm"
            + (f", {best[1]:.3f} rad" if rotation is not None else "")
        )
        raise IKError(msg)

    def ik_solutions(
        self,
        frame: str,
        position: FloatArray,
        q0: FloatArray,
        rotation: FloatArray | None = None,
        joints: Iterable[str] = ARM_JOINTS,
        restarts: int = 40,
        seed: int = 0,
    ) -> list[FloatArray]:
        """Every distinct solution :meth:`ik` finds from its ``restarts`` seeded random starts
        (not from ``q0``), in the order found: the kinematic branches (elbow, wrist) that reach
        the target, for a caller that needs one of them to be collision-free. Solutions that
        differ by less than 1e-3 rad in every joint, up to whole turns of a continuous joint,
        count once. Default tolerances and iterations as :meth:`ik`.

        Raises:
            IKError: a non-finite target.
        """
        target = np.asarray(position, dtype=np.float64)
        cols = self._columns(tuple(joints))
        continuous = self.continuous[cols]
        found: list[FloatArray] = []
        for q, pos_err, rot_err in self._ik_attempts(
            frame, target, q0, rotation, joints, 1e-4, 1e-3, 200, restarts, seed, False
        ):
            if pos_err > 1e-4 or rot_err > 1e-3:
                continue
            if not any(
                np.all(
                    np.abs(np.where(continuous, wrap_angle(q[cols] - f[cols]), q[cols] - f[cols]))
                    < 1e-3
                )
                for f in found
            ):
                found.append(q)
        return found

    def _ik_attempts(
        self,
        frame: str,
        target: FloatArray,
        q0: FloatArray,
        rotation: FloatArray | None,
        joints: Iterable[str],
        position_tolerance: float,
        rotation_tolerance: float,
        max_iterations: int,
        restarts: int,
        seed: int,
        try_q0: bool,
    ) -> Iterator[tuple[FloatArray, float, float]]:
        """The outcome of each IK start (:meth:`ik`), in order: (9,) rad, m and rad errors.

        Raises:
            IKError: a non-finite target.
        """
        if target.shape != (3,) or not np.all(np.isfinite(target)):
            msg = f"IK target position {target.tolist()} must be 3 finite numbers"
            raise IKError(msg)
        cols = self._columns(tuple(joints))
        fid = self.frame_id(frame)
        # Random starts are drawn only when needed, in the same order: same seed, same answer.
        rng = np.random.default_rng(seed) if restarts > 0 else None
        continuous = self.continuous[cols]
        low = np.where(continuous, np.maximum(-np.pi, self.lower[cols]), self.lower[cols])
        high = np.where(continuous, np.minimum(np.pi, self.upper[cols]), self.upper[cols])
        for attempt in range(0 if try_q0 else 1, restarts + 1):
            q_start = np.array(q0, dtype=np.float64)
            if attempt > 0 and rng is not None:
                q_start[cols] = rng.uniform(low, high)
            yield _damped_least_squares(
                self.model,
                self.data,
                fid,
                target,
                rotation,
                q_start,
                cols,
                (self.lower[cols], self.upper[cols], continuous),
                (position_tolerance, rotation_tolerance),
                max_iterations,
            )

    # ------------------------------------------------------------------------------- dynamics
    def gravity_torques(self, q: FloatArray) -> FloatArray:
        """(9,) N m, joint torques that hold ``q`` against gravity."""
        return np.asarray(pin.computeGeneralizedGravity(self.model, self.data, q)).copy()

    def rnea(self, q: FloatArray, v: FloatArray, a: FloatArray) -> FloatArray:
        """(9,) N m, inverse dynamics: torques giving acceleration ``a`` (rad/s^2) at q, v."""
        return np.asarray(pin.rnea(self.model, self.data, q, v, a)).copy()

    def potential_energy(self, q: FloatArray) -> float:
        """J, gravitational potential energy of the moving links (base_link z = 0 reference)."""
        return float(pin.computePotentialEnergy(self.model, self.data, q))

    # ------------------------------------------------------------------------------ collision
    def collision_report(
        self,
        q: FloatArray,
        terrain: HeightMap | None = None,
        terrain_links: Iterable[str] = ARM_LINKS,
        terrain_margin: float = 0.0,
        stop_at_first: bool = False,
    ) -> CollisionReport:
        """The contacts of ``q`` (9,) rad: :meth:`CollisionChecker.report
        <ow_description.collision.CollisionChecker.report>` on this lander's model."""
        return self.collision.report(q, terrain, terrain_links, terrain_margin, stop_at_first)

    def in_collision(
        self,
        q: FloatArray,
        terrain: HeightMap | None = None,
        terrain_links: Iterable[str] = ARM_LINKS,
        terrain_margin: float = 0.0,
    ) -> bool:
        """True when ``q`` collides (see :meth:`collision_report`); stops at the first contact."""
        return self.collision.in_collision(q, terrain, terrain_links, terrain_margin)

    def link_names(self) -> list[str]:
        """Names of all links (bodies and frame-only links) in the description."""
        return [f.name for f in self.model.frames if f.type == pin.FrameType.BODY]

    def total_mass(self) -> float:
        """kg, mass of every link including the fixed lander body."""
        return float(sum(inertia.mass for inertia in self.model.inertias))

    def base_frame(self) -> str:
        """Name of the root frame (base_link)."""
        return BASE_FRAME


def _damped_least_squares(
    model: pin.Model,
    data: pin.Data,
    fid: int,
    target: FloatArray,
    rotation: FloatArray | None,
    q: FloatArray,
    cols: npt.NDArray[np.intp],
    limits: tuple[FloatArray, FloatArray, npt.NDArray[np.bool_]],
    tolerances: tuple[float, float],
    max_iterations: int,
) -> tuple[FloatArray, float, float]:
    """One IK start (:meth:`LanderModel.ik`): damped least squares from ``q`` (9,) rad moving the
    joints ``cols`` (their ``limits``: lower, upper (rad) and continuous), until frame ``fid`` is
    at ``target`` (3,) m (and ``rotation`` (3, 3)) within ``tolerances`` (m, rad), it stalls or
    the iterations run out.

    Returns:
        The configuration reached, its position error (m) and orientation error (rad).
    """
    position_tolerance, rotation_tolerance = tolerances
    rows = 6 if rotation is not None else 3
    eye = _EYE[rows]
    # Position and orientation errors weighted by their tolerances: a pose just out of reach (a
    # target's rounded quaternion, the arm near full stretch) is met within both, instead of
    # the orientation exactly and the position not at all.
    weight = position_tolerance / rotation_tolerance
    rows_weight = np.array([1.0, 1.0, 1.0, weight, weight, weight])[:rows, None]
    lower, upper, _ = limits
    pos_err = rot_err = np.inf
    checkpoint = np.inf
    for iteration in range(max_iterations):
        # The Jacobian call also runs the forward kinematics the frame placement needs.
        J = pin.computeFrameJacobian(model, data, q, fid, pin.LOCAL_WORLD_ALIGNED)
        X = pin.updateFramePlacement(model, data, fid)
        e = target - X.translation
        pos_err = float(np.sqrt(e @ e))
        rot_err = 0.0
        if rotation is not None:
            w = pin.log3(rotation @ X.rotation.T)
            rot_err = float(np.sqrt(w @ w))
            e = np.concatenate([e, weight * w])
        if pos_err <= position_tolerance and rot_err <= rotation_tolerance:
            break
        if iteration % IK_STALL_ITERATIONS == 0:
            # A start that stopped improving sits in a local minimum (a joint limit, a
            # singularity); it would spend all its iterations there.
            if pos_err + rot_err > (1.0 - IK_STALL_GAIN) * checkpoint:
                break
            checkpoint = pos_err + rot_err
        J = rows_weight * J[:rows, cols]
        # Levenberg-Marquardt damping: robust far away and near singularities (q = 0 is a wrist
        # singularity), vanishing close to the solution for fast final convergence.
        damping = 1e-6 + 1e-2 * float(e @ e)
        dq = J.T @ np.linalg.solve(J @ J.T + damping * eye, e)
        # Bounded steps keep the linearisation honest far from the target.
        step = float(np.abs(dq).max())
        if step > 0.5:
            dq *= 0.5 / step
        q = q.copy()
        moved = q[cols] + dq
        if np.any(moved < lower) or np.any(moved > upper):
            moved = _into_limits(moved, limits)
        q[cols] = moved
    return q, pos_err, rot_err


def _into_limits(
    values: FloatArray, limits: tuple[FloatArray, FloatArray, npt.NDArray[np.bool_]]
) -> FloatArray:
    """Joint ``values`` (rad) brought into their ``limits`` (lower, upper, continuous): a
    continuous joint beyond its travel turned by whole turns to the angle nearest 0 (the same
    orientation), the others clipped."""
    lower, upper, continuous = limits
    beyond = (values < lower) | (values > upper)
    turned = np.where(continuous & beyond, nearest_turn(values, 0.0), values)
    return np.clip(turned, lower, upper)
