"""The joints' controllers: the paper's PID position controllers, trajectories, gravity feed-forward
and the implicit damped step. No pybullet here: the caller measures the joints and applies the
torques.

Per joint and physics step (``dt``), the paper's effort PID position controller::

    e = q_set - q;  integral = clip(integral + i e dt, +-i_clamp)   (not while saturated outward)
    effort = clip(p e + integral + d (v_set - v_next), +-effort_limit)
    damping = -c v_next                    (c: the URDF joint damping, a passive torque)

For a continuous joint (:data:`~ow_description.description.CONTINUOUS_JOINTS`) ``e`` is wrapped
into [-pi, pi), as ros_control's position controllers do for continuous joints: a set-point a
whole turn away is where the joint is.

``v_next`` is the joint velocity at the end of the step, predicted from the full joint-space
inertia and bias (gravity + Coriolis) of pinocchio with the effort and damping treated implicitly
(``(M + dt C) v_next = M v + dt (p e + integral + d v_set - bias)``, ``C = diag(d + c)``, solved
by pinocchio's articulated-body algorithm with ``dt C`` as joint armature). This is backward Euler
for the dampers, stable at any step even on the light wrist and scoop links, where the explicit
form needs 1 kHz and the URDF damping applied explicitly by Bullet diverges. At rest ``v_next`` is
0, so the holding effort is exactly the gravity torque. The caller applies effort + damping as
joint torques, with the simulator's own joint damping off, so the energy the damping dissipates in
a step is exactly ``-damping * v dt``.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ow_description.description import ALL_JOINTS, CONTINUOUS_JOINTS, nearest_turn, wrap_angle
from ow_sim_bullet.config import PidGains
from ow_sim_bullet.errors import CommandError, ConfigError
from ow_sim_bullet.joints import ClippedSetpoint
from ow_sim_bullet.trajectory import ActiveTrajectory, JointTrajectory
from ow_sim_bullet.urdf import UrdfJoint

FloatArray = npt.NDArray[np.float64]
IndexArray = npt.NDArray[np.intp]


class JointController:
    """One PID position controller per joint, with trajectories and the implicit damped step.

    Every joint array (positions, velocities, torques) is in the order of :attr:`names`, which is
    pinocchio's coordinate order, so no permutation is needed.

    Set-points never leave the joints' URDF position limits: a commanded set-point or trajectory
    point beyond a limit is clipped onto it (the commands return what they clipped), so a hostile
    or mistaken command can drive a joint onto its limit but never hold it pressed beyond it.
    A continuous joint has no limit and is never clipped: a set-point for it, or a trajectory
    (all its points alike), is moved by whole turns to start nearest the joint's set-point, so
    the joint turns the shorter way round and its set-point stays comparable with its position
    (as joint_trajectory_controller's wrap-around).

    Args:
        model: pinocchio model of the lander, gravity set (not modified).
        joints: the URDF's joints by name (effort limits and damping of the movable ones).
        gains: PID gains by joint name, for every joint of :data:`ALL_JOINTS`.
        dt: s, the physics step.
        gravity_feedforward: add the gravity torque of the measured pose to the PID output.

    Raises:
        ConfigError: the model's coordinates are not the nine one-dof joints.
    """

    def __init__(
        self,
        model: pin.Model,
        joints: Mapping[str, UrdfJoint],
        gains: Mapping[str, PidGains],
        dt: float,
        gravity_feedforward: bool,
    ) -> None:
        self.model = model
        self.dt = dt
        self.gravity_feedforward = gravity_feedforward
        self._data = model.createData()
        # The implicit step's linear solve (M + dt C) x = r is pinocchio's articulated-body
        # algorithm on a copy of the model without gravity, at rest, with dt C as the joints'
        # armature: then ABA returns exactly (M + dt C)^-1 r, in O(n) and for less than numpy's
        # dense solve (plus the mass matrix) costs.
        self._solve_model = pin.Model(model)
        self._solve_model.gravity.linear = np.zeros(3)
        self._solve_data = self._solve_model.createData()
        order = sorted(ALL_JOINTS, key=lambda j: model.joints[model.getJointId(j)].idx_q)
        if model.nq != len(ALL_JOINTS) or model.nv != len(ALL_JOINTS):
            msg = f"expected {len(ALL_JOINTS)} one-dof joints, pinocchio has nq {model.nq}"
            raise ConfigError(msg)
        #: joint names in the order of every joint array of this class.
        self.names: tuple[str, ...] = tuple(order)
        n = len(self.names)
        self._zeros = np.zeros(n)
        self._effort_limit = np.array([joints[j].effort_limit for j in self.names])
        #: rad, the joints' URDF position limits (pinocchio's, in :attr:`names` order).
        self.lower = np.array(model.lowerPositionLimit, dtype=np.float64)
        self.upper = np.array(model.upperPositionLimit, dtype=np.float64)
        #: True for the continuous joints, in :attr:`names` order.
        self.continuous = np.array([j in CONTINUOUS_JOINTS for j in self.names])
        self._continuous_index = np.flatnonzero(self.continuous)
        # The bounds set-points are clipped to: the limits, none for a continuous joint.
        self._setpoint_lower = np.where(self.continuous, -np.inf, self.lower)
        self._setpoint_upper = np.where(self.continuous, np.inf, self.upper)
        self._negative_effort_limit = -self._effort_limit
        self._damping = np.array([joints[j].damping for j in self.names])
        self._negative_damping = -self._damping
        self._kp = np.zeros(n)
        self._ki = np.zeros(n)
        self._kd = np.zeros(n)
        self._i_clamp = np.zeros(n)
        #: N m s/rad, the implicit step's damper of each locked joint (0: not locked).
        self._lock = np.zeros(n)
        for joint in self.names:
            self._set_gains_array(joint, gains[joint])
        #: joint -> the trajectory it follows.
        self._trajectories: dict[str, ActiveTrajectory] = {}
        #: each followed trajectory with the indices of its joints that still follow it, in the
        #: trajectory's and in our joint order (derived from ``_trajectories``).
        self._followed: list[tuple[ActiveTrajectory, IndexArray, IndexArray]] = []
        #: the position limits of those joints, in the same order (clip the sampled set-points).
        self._followed_limits: list[tuple[FloatArray, FloatArray]] = []
        self._setpoint = np.zeros(n)
        self._integral = np.zeros(n)

    # ------------------------------------------------------------------ commands
    def reset(self, positions: FloatArray) -> None:
        """Hold ``positions`` (rad): set-points there, trajectories cleared.

        Without gravity feed-forward the integral terms start at the gravity torque of
        ``positions`` (for joints with an integral gain), as if the controllers had been holding
        it: the arm does not sag at start. With it they start at zero.
        """
        self._setpoint = positions.copy()
        self._trajectories.clear()
        self._update_followed()
        gravity = self.gravity_torque(positions)
        preload = (self._ki > 0) & (not self.gravity_feedforward)
        self._integral = np.where(preload, np.clip(gravity, -self._i_clamp, self._i_clamp), 0.0)

    @property
    def setpoint(self) -> FloatArray:
        """(9,) rad, a copy of the set-points now."""
        return self._setpoint.copy()

    def set_setpoint(self, joint: str, position: float) -> ClippedSetpoint | None:
        """Command one joint's position set-point (rad); cancels its trajectory.

        A set-point beyond the joint's URDF limits is clipped onto the nearer limit; one for a
        continuous joint is moved by whole turns to the angle nearest its set-point now.

        Returns:
            What was clipped, or None when the set-point was within the limits.

        Raises:
            CommandError: unknown joint or non-finite position (the command is ignored).
        """
        k = self._joint(joint)
        if not math.isfinite(position):
            msg = f"set-point {position} for {joint} is not finite; command ignored"
            raise CommandError(msg)
        if self._trajectories.pop(joint, None) is not None:
            self._update_followed()
        if self.continuous[k]:
            self._setpoint[k] = float(nearest_turn(position, self._setpoint[k]))
            return None
        lower, upper = float(self.lower[k]), float(self.upper[k])
        applied = min(max(position, lower), upper)
        self._setpoint[k] = applied
        if applied == position:
            return None
        return ClippedSetpoint(joint, position, applied, lower, upper)

    def release(self, joint: str, position: float) -> None:
        """Hold ``joint`` at ``position`` (rad) from now, its trajectory cancelled and its
        integral back to where :meth:`reset` starts it: after a lock is released, the integral
        wound up against the lock must not throw the joint.

        Raises:
            CommandError: unknown joint or non-finite position.
        """
        self.set_setpoint(joint, position)
        k = self._joint(joint)
        held = np.array(self._setpoint)
        gravity = float(self.gravity_torque(held)[k])
        preload = self._ki[k] > 0 and not self.gravity_feedforward
        self._integral[k] = (
            min(max(gravity, -self._i_clamp[k]), self._i_clamp[k]) if preload else 0.0
        )

    def set_trajectory(self, trajectory: JointTrajectory, now: float) -> list[ClippedSetpoint]:
        """Follow ``trajectory`` on its joints from sim time ``now`` (s), replacing any
        trajectory they were following; it starts from their set-points.

        Points beyond a joint's URDF limits are followed as if on the limit: the set-points
        sampled from the trajectory are clipped into the limits at every step. A continuous
        joint's points are all moved by the whole turns that bring the first nearest its
        set-point now, and never clipped.

        Returns:
            One entry per joint with points beyond its limits (its most extreme point), in the
            trajectory's joint order; empty when every point is within the limits.

        Raises:
            CommandError: the trajectory names an unknown joint.
        """
        columns = [self._joint(j) for j in trajectory.joints]
        trajectory = self._turned(trajectory, columns)
        clipped = []
        for i, (joint, k) in enumerate(zip(trajectory.joints, columns, strict=True)):
            if self.continuous[k]:
                continue
            values = trajectory.positions[:, i]
            lower, upper = float(self.lower[k]), float(self.upper[k])
            low, high = float(values.min()), float(values.max())
            if low < lower or high > upper:
                worst = low if lower - low >= high - upper else high
                applied = min(max(worst, lower), upper)
                clipped.append(ClippedSetpoint(joint, worst, applied, lower, upper))
        start = np.array([self._setpoint[k] for k in columns])
        active = ActiveTrajectory(trajectory, start, now)
        for joint in trajectory.joints:
            self._trajectories[joint] = active
        self._update_followed()
        return clipped

    def _turned(self, trajectory: JointTrajectory, columns: list[int]) -> JointTrajectory:
        """``trajectory`` with each continuous joint's points moved by the whole turns that put
        its first point nearest the joint's set-point (``columns``: its joints' indices)."""
        turning = [i for i, k in enumerate(columns) if self.continuous[k]]
        if not turning:
            return trajectory
        first = trajectory.positions[0, turning]
        shift = nearest_turn(first, self._setpoint[[columns[i] for i in turning]]) - first
        if not shift.any():
            return trajectory
        positions = trajectory.positions.copy()
        positions[:, turning] += shift
        return dataclasses.replace(trajectory, positions=positions)

    def _update_followed(self) -> None:
        """Derive ``_followed`` from ``_trajectories`` (after any change to it)."""
        followed = []
        for active in dict.fromkeys(self._trajectories.values()):
            pairs = [
                (i, self.names.index(joint))
                for i, joint in enumerate(active.trajectory.joints)
                if self._trajectories.get(joint) is active
            ]
            src, dst = np.array(pairs, dtype=np.intp).T
            followed.append((active, src, dst))
        self._followed = followed
        self._followed_limits = [
            (self._setpoint_lower[dst], self._setpoint_upper[dst]) for _, _, dst in followed
        ]

    def set_gains(self, joint: str, gains: PidGains) -> None:
        """Change one joint's PID gains now; the integral is kept, within the new clamp.

        Raises:
            CommandError: unknown joint.
        """
        self._joint(joint)
        self._set_gains_array(joint, gains)
        self._integral = np.clip(self._integral, -self._i_clamp, self._i_clamp)

    def gains(self, joint: str) -> PidGains:
        """The gains one joint uses now (i_clamp resolved to N m).

        Raises:
            CommandError: unknown joint.
        """
        k = self._joint(joint)
        return PidGains(
            float(self._kp[k]), float(self._ki[k]), float(self._kd[k]), float(self._i_clamp[k])
        )

    def _set_gains_array(self, joint: str, gains: PidGains) -> None:
        """Store one joint's gains and update the dampers of the implicit step."""
        k = self.names.index(joint)
        self._kp[k], self._ki[k], self._kd[k] = gains.p, gains.i, gains.d
        self._i_clamp[k] = self._effort_limit[k] if gains.i_clamp is None else gains.i_clamp
        self._negative_i_clamp = -self._i_clamp
        self._update_dampers()

    def _update_dampers(self) -> None:
        #: N m s/rad, d + c (+ a locked joint's lock): the dampers treated implicitly (diagonal
        #: of C).
        self._dampers = self._kd + self._damping + self._lock
        self._dampers.flags.writeable = False
        self._solve_model.armature = self.dt * self._dampers

    def set_locked(self, joints: frozenset[str], lock_damper: float) -> None:
        """Tell the implicit step which joints a lock holds (the simulation's locks act on
        them; the controllers still command them as before): each gets ``lock_damper``
        (N m s/rad) among the dampers, so the step predicts them at rest and the joints around
        them without the motion they do not make.

        Raises:
            CommandError: unknown joint.
        """
        lock = np.zeros(len(self.names))
        for joint in joints:
            lock[self._joint(joint)] = lock_damper
        self._lock = lock
        self._update_dampers()

    def _joint(self, joint: str) -> int:
        """The index of ``joint`` in :attr:`names`; CommandError for an unknown one."""
        try:
            return self.names.index(joint)
        except ValueError:
            msg = f"unknown joint {joint!r}; joints: {list(self.names)}"
            raise CommandError(msg) from None

    # ------------------------------------------------------------------ dynamics
    @property
    def dampers(self) -> FloatArray:
        """(9,) N m s/rad, d + c: the derivative gains plus the URDF damping, plus the lock of a
        locked joint (read-only)."""
        return self._dampers

    @property
    def damping(self) -> FloatArray:
        """(9,) N m s/rad, the URDF joint damping c (a copy)."""
        return self._damping.copy()

    def gravity_torque(self, q: FloatArray) -> FloatArray:
        """N m, the joint torques that hold positions ``q`` (rad) against gravity (RNEA at rest)."""
        return self._bias(q, np.zeros_like(q))

    def _gravity(self, q: FloatArray) -> FloatArray:
        """N m, the feed-forward's gravity torque at ``q``."""
        return np.array(pin.computeGeneralizedGravity(self.model, self._data, q))

    def _bias(self, q: FloatArray, v: FloatArray) -> FloatArray:
        """N m, gravity + Coriolis joint torques."""
        return np.array(pin.rnea(self.model, self._data, q, v, self._zeros))

    def implicit_solve(self, q: FloatArray, dampers: FloatArray, rhs: FloatArray) -> FloatArray:
        """x with (M(q) + dt diag(dampers)) x = rhs, by ABA with ``dt dampers`` as armature.

        Args:
            q: (9,) rad.
            dampers: (9,) N m s/rad; other than :attr:`dampers` (the same array) they are set
                for this solve only.
            rhs: (9,) N m.

        Returns:
            (9,) rad/s^2.
        """
        model = self._solve_model
        if dampers is not self._dampers:
            model.armature = self.dt * dampers
        x = np.array(pin.aba(model, self._solve_data, q, self._zeros, rhs))
        if dampers is not self._dampers:
            model.armature = self.dt * self._dampers
        return x

    # ------------------------------------------------------------------ stepping
    def follow(self, now: float) -> FloatArray:
        """Move the set-points of joints following trajectories to sim time ``now`` (s); drop
        the trajectories that ended.

        Returns:
            (9,) rad/s, the set-point velocities (0 for joints without a trajectory).
        """
        v_set = np.zeros(len(self.names))
        if self._followed:
            for (active, src, dst), (lower, upper) in zip(
                self._followed, self._followed_limits, strict=True
            ):
                positions, velocities = active.sample(now)
                wanted = positions[src]
                setpoint = np.minimum(np.maximum(wanted, lower), upper)
                velocity = velocities[src]
                if np.count_nonzero(setpoint != wanted):  # held on a limit: no velocity
                    velocity = np.where(setpoint != wanted, 0.0, velocity)
                self._setpoint[dst] = setpoint
                v_set[dst] = velocity
            if any(active.finished(now) for active, _, _ in self._followed):
                for joint in [j for j, a in self._trajectories.items() if a.finished(now)]:
                    del self._trajectories[joint]
                self._update_followed()
        return v_set

    def control(
        self, q: FloatArray, v: FloatArray, v_set: FloatArray, external: FloatArray | None = None
    ) -> tuple[FloatArray, FloatArray]:
        """Motor effort and damping torque for this step; updates the integrals.

        Args:
            q: (9,) rad, measured positions.
            v: (9,) rad/s, measured velocities.
            v_set: (9,) rad/s, set-point velocities (:meth:`follow`).
            external: (9,) N m, joint torques of the forces applied this step besides the motors
                and dampers (contacts, terrain-force model), or None: the implicit step must know
                them, or on a light link (the scoop) one step's acceleration would make the
                dampers' torque jump, and a joint the terrain blocks would be predicted moving.

        Returns:
            (9,) N m effort (motor) and (9,) N m damping torque.
        """
        # (M + dt C) v_next = M v + dt (tau - bias) written for the acceleration a, v_next =
        # v + dt a: (M + dt C) a = tau - bias - C v.
        dt = self.dt
        error = self._setpoint - q
        turn = error[self._continuous_index]
        if np.count_nonzero(np.abs(turn) > math.pi):
            # A continuous joint more than half a turn from its set-point: the set-point's angle
            # is nearer the other way round (errors within half a turn are left bit for bit).
            error[self._continuous_index] = wrap_angle(turn)
        tau_pi = self._kp * error + self._integral
        if self.gravity_feedforward:
            tau_pi = tau_pi + self._gravity(q)
        drive = tau_pi + self._kd * v_set
        bias = self._bias(q, v)
        if external is not None:
            bias = bias - external
        dampers = self._dampers
        v_next = v + dt * self.implicit_solve(q, dampers, drive - bias - dampers * v)
        effort = tau_pi + self._kd * (v_set - v_next)
        integral = self._integral + self._ki * error * dt
        limit, negative_limit = self._effort_limit, self._negative_effort_limit
        saturated = np.abs(effort) > limit
        if np.count_nonzero(saturated):  # (ndarray.any costs ten times more on 9 values)
            # A saturated joint's effort is its limit, no longer a damper.
            limited = np.minimum(np.maximum(effort, negative_limit), limit)
            dampers = np.where(saturated, 0.0, self._kd) + self._damping + self._lock
            tau = np.where(saturated, limited, drive)
            v_next = v + dt * self.implicit_solve(q, dampers, tau - bias - dampers * v)
            effort = np.where(saturated, limited, tau_pi + self._kd * (v_set - v_next))
            effort = np.minimum(np.maximum(effort, negative_limit), limit)
            # Anti-windup: no integration while the effort is saturated in the error's direction.
            winding = saturated & (np.sign(error) == np.sign(effort))
            integral = np.where(winding, self._integral, integral)
        self._integral = np.minimum(np.maximum(integral, self._negative_i_clamp), self._i_clamp)
        return effort, self._negative_damping * v_next
