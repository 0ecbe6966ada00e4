"""Motion planning for the six arm joints: free-space (direct segment or OMPL RRT*) and Cartesian
lines (IK every ``cartesian_step_m``), collision-checked against self, lander body, dock and the
terrain. No ROS.

States are arm vectors ``arm: (6,) rad`` in :data:`~ow_lander.description.ARM_JOINTS` order; the
other joints (grinder, antenna) keep the values of a base configuration ``base: (9,)`` in
pinocchio order (see :mod:`ow_lander.model`).

The optimisation objective is mechanical work against gravity (Europa's), the energy the joint
motors spend on a quasi-static motion: the sum over joints of |tau_g(q) * dq| along the path, plus
``path_length_weight`` times the joint-space path length. OMPL's MechanicalWorkOptimizationObjective
is not used: it ignores the robot's dynamics and reduces to path length.
"""

from __future__ import annotations

import itertools
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt
import pinocchio as pin
from ompl import base as ob
from ompl import geometric as og
from ompl import util as ou

from ow_lander.config import PlannerConfig
from ow_lander.description import ARM_JOINTS
from ow_lander.errors import IKError, PlanningError
from ow_lander.model import ARM_LINKS, LanderModel
from ow_lander.terrain import HeightMap

FloatArray = npt.NDArray[np.float64]

#: rad, joint step of the work integral reported for plans (gravity torque at step midpoints).
WORK_STEP_RAD = 0.02
#: rad, coarser step of the same integral inside RRT*'s objective (called ~20 times an iteration).
OBJECTIVE_STEP_RAD = 0.25

# OMPL reports through its own logger; our errors carry the reasons. RNG.setSeed also logs an
# error when called after the first plan, although it does reseed (see ArmPlanner._rrt_star).
ou.setLogLevel(ou.LogLevel.LOG_NONE)


@dataclass(frozen=True)
class CheckContext:
    """What a state is checked against.

    Attributes:
        base: (9,) rad, configuration giving the non-arm joints (grinder, antenna).
        terrain: height map, or None for no terrain check.
        terrain_links: links that must stay above the terrain (leave out a digging tool).
        terrain_margin: m, clearance required above the terrain.
    """

    base: FloatArray
    terrain: HeightMap | None
    terrain_links: tuple[str, ...] = ARM_LINKS
    terrain_margin: float = 0.0


@dataclass
class PlanStats:
    """What the planner did, for messages and benchmarks.

    Attributes:
        direct_segments: free-space segments solved by the direct joint-space segment.
        rrt_segments: free-space segments solved by RRT*.
        rrt_iterations: RRT* iterations run in total.
        cartesian_waypoints: IK solutions computed along Cartesian lines.
    """

    direct_segments: int = 0
    rrt_segments: int = 0
    rrt_iterations: int = 0
    cartesian_waypoints: int = 0
    notes: list[str] = field(default_factory=list)


def densify(waypoints: FloatArray, resolution: float) -> FloatArray:
    """(m, k) states along the polyline ``waypoints`` (n, k) with no joint step above
    ``resolution`` rad; every waypoint is kept."""
    points = np.asarray(waypoints, dtype=np.float64)
    out = [points[:1]]
    for a, b, n in zip(points[:-1], points[1:], _steps(points, resolution), strict=True):
        w = np.arange(1, n + 1)[:, None] / n
        out.append(a + w * (b - a))
    return np.concatenate(out)


def _steps(waypoints: FloatArray, resolution: float) -> list[int]:
    """How many states :func:`densify` puts on each segment of ``waypoints`` (n, k)."""
    largest = np.abs(np.diff(waypoints, axis=0)).max(axis=1, initial=0.0)
    return [max(1, math.ceil(float(d) / resolution - 1e-9)) for d in largest]


def _coarse_to_fine(n: int) -> npt.NDArray[np.intp]:
    """The indices 0..n-1 in bisection order: 0, then the multiples of the largest power of two
    below n, then the odd multiples of each smaller power of two in turn."""
    index = np.arange(n)
    # The largest power of two dividing each index (index 0 first of all).
    lowest_bit = np.where(index == 0, n + 1, index & -index)
    return np.argsort(-lowest_bit, kind="stable")


class ArmPlanner:
    """Plans arm motions for one :class:`LanderModel` (not thread-safe, like the model).

    Args:
        model: kinematics, dynamics and collision model (this planner's own instance).
        config: planner settings.
    """

    def __init__(self, model: LanderModel, config: PlannerConfig) -> None:
        self.model = model
        self.config = config
        self.idx = model.arm_idx
        self.lower = model.lower[self.idx].copy()
        self.upper = model.upper[self.idx].copy()
        self.velocity_limits = model.velocity_limit[self.idx].copy()
        self.stats = PlanStats()
        self._lower_tol = self.lower - 1e-9
        self._upper_tol = self.upper + 1e-9
        #: (index, lower, upper) of the joints whose range spans a full turn.
        self._full_turn = [
            (j, float(self.lower[j]), float(self.upper[j]))
            for j in np.flatnonzero(self.upper - self.lower >= 2 * np.pi - 1e-6)
        ]

    # ------------------------------------------------------------------------------ helpers
    def full(self, arm: FloatArray, base: FloatArray) -> FloatArray:
        """(9,) rad configuration: ``base`` with the arm joints set to ``arm`` (6,)."""
        q = np.array(base, dtype=np.float64)
        q[self.idx] = arm
        return q

    def arm(self, q: FloatArray) -> FloatArray:
        """(6,) rad arm joints of a (9,) configuration."""
        return np.asarray(q, dtype=np.float64)[self.idx].copy()

    def within_limits(self, arm: FloatArray) -> bool:
        """True when every arm joint is within its URDF limits."""
        return bool(((arm >= self._lower_tol) & (arm <= self._upper_tol)).all())

    def is_valid(self, arm: FloatArray, ctx: CheckContext) -> bool:
        """True when ``arm`` is within the joint limits and collision-free in ``ctx``."""
        if not self.within_limits(arm):
            return False
        return not self.model.in_collision(
            self.full(arm, ctx.base), ctx.terrain, ctx.terrain_links, ctx.terrain_margin
        )

    def explain(self, arm: FloatArray, ctx: CheckContext) -> str:
        """Why ``arm`` is invalid, in words (joint limits or contacts)."""
        q = self.full(arm, ctx.base)
        problems = self.model.limit_violations(q, ARM_JOINTS)
        report = self.model.collision_report(q, ctx.terrain, ctx.terrain_links, ctx.terrain_margin)
        if report.in_collision:
            problems.append(report.describe())
        return "; ".join(problems) or "valid"

    def first_invalid(
        self, waypoints: FloatArray, ctx: CheckContext, resolution: float | None = None
    ) -> FloatArray | None:
        """The first invalid state along the polyline at ``resolution`` rad (default: the
        configured joint resolution), or None when the whole path is valid."""
        states = densify(waypoints, resolution or self.config.joint_resolution_rad)
        return self._first_invalid_state(states, ctx)

    def path_valid(
        self, waypoints: FloatArray, ctx: CheckContext, resolution: float | None = None
    ) -> bool:
        """True when every state along the polyline at ``resolution`` rad (default: the
        configured joint resolution) is valid: the states of :meth:`first_invalid`, checked
        coarse to fine, so that a blocked motion is usually rejected after a few checks."""
        states = densify(waypoints, resolution or self.config.joint_resolution_rad)
        return self._first_invalid_state(states[_coarse_to_fine(len(states))], ctx) is None

    def _first_invalid_state(self, states: FloatArray, ctx: CheckContext) -> FloatArray | None:
        """The first invalid row of ``states`` (m, 6), or None."""
        index = self._first_invalid_index(states, ctx)
        return None if index is None else states[index]

    def _first_invalid_index(self, states: FloatArray, ctx: CheckContext) -> int | None:
        """The index of the first invalid row of ``states`` (m, 6), or None."""
        inside = np.all((states >= self._lower_tol) & (states <= self._upper_tol), axis=1)
        q = np.array(ctx.base, dtype=np.float64)
        in_collision = self.model.in_collision
        for i, (arm, ok) in enumerate(zip(states, inside.tolist(), strict=True)):
            if not ok:
                return i
            q[self.idx] = arm
            if in_collision(q, ctx.terrain, ctx.terrain_links, ctx.terrain_margin):
                return i
        return None

    def unwrap(self, arm: FloatArray, reference: FloatArray) -> FloatArray:
        """``arm`` with each full-turn joint moved by whole turns to the value closest to
        ``reference`` that stays within its limits."""
        out = np.array(arm, dtype=np.float64)
        for j, lower, upper in self._full_turn:
            value = float(out[j])
            turns = round((float(reference[j]) - value) / (2 * math.pi))
            for k in (turns, turns - 1, turns + 1):
                candidate = value + 2 * math.pi * k
                if lower <= candidate <= upper:
                    out[j] = candidate
                    break
        return out

    # -------------------------------------------------------------------------------- work
    def work(self, waypoints: FloatArray, base: FloatArray, step: float = WORK_STEP_RAD) -> float:
        """J, mechanical work against gravity along the polyline (n, 6): the sum over joints and
        steps of |tau_g(q_mid) * dq|, steps of at most ``step`` rad."""
        total = 0.0
        points = np.asarray(waypoints, dtype=np.float64)
        for a, b in itertools.pairwise(points):
            total += self.work_between(a, b, base, step)
        return total

    def work_between(
        self, a: FloatArray, b: FloatArray, base: FloatArray, step: float = WORK_STEP_RAD
    ) -> float:
        """J, :meth:`work` of the straight joint motion ``a`` -> ``b`` ((6,) rad each)."""
        delta = b - a
        n = max(1, math.ceil(float(np.abs(delta).max()) / step))
        qs = np.empty((n, len(base)))
        qs[:] = base
        qs[:, self.idx] = a + (np.arange(n)[:, None] + 0.5) * (delta / n)
        model, data = self.model.model, self.model.data
        torque = np.empty_like(qs)
        for i, q in enumerate(qs):
            torque[i] = pin.computeGeneralizedGravity(model, data, q)
        # sum over steps and joints of |tau * delta / n| = sum over joints of
        # |delta / n| * (sum over steps of |tau|).
        return float(np.abs(torque[:, self.idx]).sum(axis=0) @ np.abs(delta / n))

    def cost(self, waypoints: FloatArray, base: FloatArray, step: float = WORK_STEP_RAD) -> float:
        """The objective of a polyline (n, 6): work (J) + weight * joint path length (rad)."""
        points = np.asarray(waypoints, dtype=np.float64)
        length = float(np.linalg.norm(np.diff(points, axis=0), axis=1).sum())
        return self.work(points, base, step) + self.config.path_length_weight * length

    # ---------------------------------------------------------------------------- free space
    def plan_free(
        self,
        start: FloatArray,
        goal: FloatArray,
        ctx: CheckContext,
        objective: str = "work",
    ) -> FloatArray:
        """A collision-free joint-space path from ``start`` to ``goal`` (both (6,) rad).

        The direct segment is kept when it is valid at the joint resolution; then two staged
        straight moves (wrist first or shoulder first); otherwise RRT*
        (seeded, capped by iterations, time and a cost threshold) and a greedy shortcut; when
        RRT* finds nothing within its caps, a seeded RRTConnect search for any valid path
        (``connect_time_limit_s``), shortened the same way.

        Args:
            start: (6,) rad.
            goal: (6,) rad.
            ctx: what states are checked against.
            objective: ``work`` (ours) or ``length`` (OMPL path length, for comparisons).

        Returns:
            (n, 6) rad waypoints from start to goal, n >= 2.

        Raises:
            PlanningError: invalid start or goal (with the reason), or no path found.
        """
        start = np.asarray(start, dtype=np.float64)
        goal = np.asarray(goal, dtype=np.float64)
        for name, arm in (("start", start), ("goal", goal)):
            if not self.is_valid(arm, ctx):
                msg = f"the {name} configuration is invalid: {self.explain(arm, ctx)}"
                raise PlanningError(msg)
        straight = self.plan_straight(start, goal, ctx)
        if straight is not None:
            return straight
        return self.plan_sampled(start, goal, ctx, objective)

    def plan_sampled(
        self,
        start: FloatArray,
        goal: FloatArray,
        ctx: CheckContext,
        objective: str = "work",
    ) -> FloatArray:
        """The sampling steps of :meth:`plan_free` alone (RRT*, then RRTConnect), shortcut and
        re-checked at the joint resolution; ``start`` and ``goal`` (6,) rad must be valid.

        Raises:
            PlanningError: no path found within the caps.
        """
        direct = np.vstack([start, goal])
        for attempt in range(self.config.rrt_attempts):
            path = self._rrt_star(
                start, goal, ctx, self.config.seed + attempt, self.config.rrt_check_resolution_rad,
                objective,
            )  # fmt: skip
            if path is None:
                continue
            path = self._shortcut(path, ctx, objective)
            if self.path_valid(path, ctx):
                self.stats.rrt_segments += 1
                return path
        if self.config.connect_time_limit_s > 0:
            path = self._rrt_star(
                start, goal, ctx, self.config.seed, self.config.joint_resolution_rad, objective,
                connect=True,
            )  # fmt: skip
            if path is not None:
                path = self._shortcut(path, ctx, objective)
                if self.path_valid(path, ctx):
                    self.stats.rrt_segments += 1
                    return path
        msg = (
            f"no collision-free path found by RRT* within {self.config.rrt_max_iterations} "
            f"iterations / {self.config.rrt_time_limit_s} s, nor by RRTConnect within "
            f"{self.config.connect_time_limit_s} s "
            f"(the straight segment is blocked: {self.explain(self._blocked(direct, ctx), ctx)})"
        )
        raise PlanningError(msg)

    def plan_straight(
        self, start: FloatArray, goal: FloatArray, ctx: CheckContext
    ) -> FloatArray | None:
        """The first two steps of :meth:`plan_free` alone: the direct segment ``start`` ->
        ``goal`` ((6,) rad, both valid) when it is valid, else the cheaper valid pair of staged
        straight moves; None when neither is, for a caller that prefers another goal to a
        sampled path."""
        direct = np.vstack([start, goal])
        if self.path_valid(direct, ctx):
            self.stats.direct_segments += 1
            return direct
        staged = self._staged(start, goal, ctx)
        if staged is not None:
            self.stats.direct_segments += 2
        return staged

    def _staged(self, start: FloatArray, goal: FloatArray, ctx: CheckContext) -> FloatArray | None:
        """Two straight joint moves, as an operator would: the wrist (distal pitch, hand and
        scoop yaw) first and then the shoulder and proximal joints, or the other way round;
        failing those, the same with the two yaws alone as the wrist. The cheaper valid one,
        or None."""
        # Split after the proximal pitch (wrist = distal pitch, hand and scoop yaw), or after
        # the distal pitch (the two yaws alone: turning the hand where the elbow is open).
        for split in (3, 4):
            candidates = [
                np.vstack([start, first, goal])
                for first in (
                    np.r_[start[:split], goal[split:]],
                    np.r_[goal[:split], start[split:]],
                )
            ]
            # Cheaper first: the first valid one is the cheaper valid one, and a costly
            # candidate is not checked when a cheap one is valid.
            candidates.sort(key=lambda path: self.cost(path, ctx.base, OBJECTIVE_STEP_RAD))
            for path in candidates:
                if self.is_valid(path[1], ctx) and self.path_valid(path, ctx):
                    return path
        return None

    def _blocked(self, path: FloatArray, ctx: CheckContext) -> FloatArray:
        state = self.first_invalid(path, ctx)
        return path[0] if state is None else state

    def _rrt_star(
        self,
        start: FloatArray,
        goal: FloatArray,
        ctx: CheckContext,
        seed: int,
        resolution: float,
        objective: str,
        connect: bool = False,
    ) -> FloatArray | None:
        """One seeded sample-based solve: RRT* with the objective, or RRTConnect (``connect``,
        feasibility only); None when it found no exact solution within its caps."""
        space = ob.RealVectorStateSpace(len(self.idx))
        bounds = ob.RealVectorBounds(len(self.idx))
        for i in range(len(self.idx)):
            bounds.setLow(i, float(self.lower[i]))
            bounds.setHigh(i, float(self.upper[i]))
        space.setBounds(bounds)
        # The seed generator is reset here, before any RNG of this solve is created, so the same
        # request and state give the same plan whatever was planned before.
        ou.RNG.setSeed(int(seed))
        si = ob.SpaceInformation(space)
        dim = len(self.idx)

        def to_arm(state: ob.State) -> FloatArray:
            return np.array([state[i] for i in range(dim)])

        def valid(state: ob.State) -> bool:
            return self.is_valid(to_arm(state), ctx)

        si.setStateValidityChecker(valid)
        si.setStateValidityCheckingResolution(resolution / space.getMaximumExtent())
        si.setup()
        pdef = ob.ProblemDefinition(si)
        s, g = si.allocState(), si.allocState()
        for i in range(dim):
            s[i] = float(start[i])
            g[i] = float(goal[i])
        pdef.setStartAndGoalStates(s, g)
        straight = np.vstack([start, goal])
        if objective == "work":
            obj: ob.OptimizationObjective = _WorkObjective(si, self, ctx.base, to_arm)
            threshold = self.cost(straight, ctx.base, OBJECTIVE_STEP_RAD)
        else:
            obj = ob.PathLengthOptimizationObjective(si)
            threshold = float(np.linalg.norm(goal - start))
        obj.setCostThreshold(ob.Cost(threshold * self.config.rrt_cost_threshold_factor))
        pdef.setOptimizationObjective(obj)
        planner: og.RRTstar | og.RRTConnect
        if connect:
            planner = og.RRTConnect(si)
            planner.setRange(self.config.rrt_range_rad)
            cap, time_limit = 100 * self.config.rrt_max_iterations, self.config.connect_time_limit_s
        else:
            planner = og.RRTstar(si)
            planner.setRange(self.config.rrt_range_rad)
            planner.setGoalBias(self.config.rrt_goal_bias)
            planner.setRewireFactor(self.config.rrt_rewire_factor)
            cap, time_limit = self.config.rrt_max_iterations, self.config.rrt_time_limit_s
        planner.setProblemDefinition(pdef)
        planner.setup()
        iterations = 0
        solved_at: int | None = None
        improve = self.config.rrt_improve_iterations
        deadline = time.monotonic() + time_limit

        def stop() -> bool:
            # Ends on iteration counts (reproducible whatever the load): the cap, or
            # ``rrt_improve_iterations`` after the first exact solution; the clock only as a
            # safety net. (The cost threshold ends RRT* from inside.)
            nonlocal iterations, solved_at
            iterations += 1
            # RRT* keeps its best solution to itself until the end; a finite best cost means it
            # has one (checked every 10 iterations: the call is not free).
            if (
                solved_at is None
                and not connect
                and iterations % 10 == 0
                and math.isfinite(planner.bestCost().value())
            ):
                solved_at = iterations
            if solved_at is not None and iterations > solved_at + improve:
                return True
            return iterations > cap or time.monotonic() > deadline

        status = planner.solve(ob.PlannerTerminationCondition(stop))
        self.stats.rrt_iterations += iterations
        if not pdef.hasExactSolution() or "Exact" not in status.asString():
            return None
        path = pdef.getSolutionPath()
        return np.array([to_arm(path.getState(i)) for i in range(path.getStateCount())])

    def _shortcut(self, path: FloatArray, ctx: CheckContext, objective: str) -> FloatArray:
        """Greedy shortcut: from each kept waypoint jump to the farthest later one reachable by a
        valid straight segment that does not cost more than the detour it replaces."""

        def cost(points: FloatArray) -> float:
            if objective == "work":
                return self.cost(points, ctx.base, OBJECTIVE_STEP_RAD)
            return float(np.linalg.norm(np.diff(points, axis=0), axis=1).sum())

        out = [path[0]]
        i = 0
        while i < len(path) - 1:
            for j in range(len(path) - 1, i, -1):
                segment = np.vstack([path[i], path[j]])
                if j == i + 1 or (
                    cost(segment) <= cost(path[i : j + 1]) + 1e-9
                    and self.path_valid(segment, ctx, self.config.rrt_check_resolution_rad)
                ):
                    out.append(path[j])
                    i = j
                    break
        return np.array(out)

    # ------------------------------------------------------------------------------- goals
    def solve_ik(
        self,
        frame: str,
        position: FloatArray,
        rotation: FloatArray | None,
        seed_arm: FloatArray,
        ctx: CheckContext,
    ) -> FloatArray:
        """A valid arm configuration placing ``frame`` at ``position`` (3,) m (and ``rotation``
        (3, 3) if given) in base_link, on the same kinematic branch as ``seed_arm`` (6,) rad.

        The target is approached from the seed's own pose in 5 cm steps (each IK seeded by the
        previous one), so the solution keeps the seed's elbow and wrist branch; seeded random
        restarts are the fallback.

        Raises:
            PlanningError: unreachable, or the solution collides (with the reason).
        """
        target = np.asarray(position, dtype=np.float64)
        arm = self._ik_continuation(frame, target, rotation, seed_arm, ctx)
        if arm is None:
            try:
                q = self.model.ik(
                    frame,
                    target,
                    self.full(seed_arm, ctx.base),
                    rotation=rotation,
                    joints=ARM_JOINTS,
                    restarts=self.config.ik_restarts,
                    seed=self.config.seed,
                )
            except IKError as error:
                raise PlanningError(str(error)) from error
            arm = self.unwrap(self.arm(q), seed_arm)
        if not self.is_valid(arm, ctx):
            msg = (
                f"placing {frame} at ({target[0]:.3f}, {target[1]:.3f}, {target[2]:.3f}) m is not "
                f"possible without a collision: {self.explain(arm, ctx)}"
            )
            raise PlanningError(msg)
        return arm

    def _ik_continuation(
        self,
        frame: str,
        target: FloatArray,
        rotation: FloatArray | None,
        seed_arm: FloatArray,
        ctx: CheckContext,
    ) -> FloatArray | None:
        here = self.model.fk(self.full(seed_arm, ctx.base), frame)
        n = max(1, int(np.ceil(np.linalg.norm(target - here[:3, 3]) / 0.05)))
        arm = np.asarray(seed_arm, dtype=np.float64)
        for i in range(1, n + 1):
            point = here[:3, 3] + (target - here[:3, 3]) * (i / n)
            try:
                q = self.model.ik(
                    frame,
                    point,
                    self.full(arm, ctx.base),
                    rotation=rotation,
                    joints=ARM_JOINTS,
                    restarts=0,
                    max_iterations=100,
                )
            except IKError:
                return None
            arm = self.unwrap(self.arm(q), arm)
        return arm

    # ---------------------------------------------------------------------------- cartesian
    def plan_cartesian(
        self,
        start: FloatArray,
        frame: str,
        positions: Sequence[FloatArray],
        rotations: Sequence[FloatArray | None],
        ctx: CheckContext,
        partial: bool = False,
    ) -> FloatArray:
        """Follow Cartesian waypoints with ``frame``, IK seeded by the previous solution.

        Args:
            start: (6,) rad, current arm configuration (its ``frame`` pose need not be the
                first waypoint exactly; the first step moves there).
            frame: controlled frame, e.g. ``l_grinder_tip``.
            positions: (3,) m each, in base_link, at most ``cartesian_step_m`` apart.
            rotations: (3, 3) orientation of ``frame`` at each waypoint, or None for position
                only.
            ctx: what states are checked against (every joint step of the joint resolution).
            partial: stop at the last reachable, valid waypoint instead of raising (a search
                motion such as the guarded descent goes as far as the arm can).

        Returns:
            (n + 1, 6) rad: ``start`` then one configuration per waypoint (fewer if partial).

        Raises:
            PlanningError: IK fails, a joint jumps more than ``max_joint_jump_rad`` between
                waypoints, or a state collides (the message names the waypoint).
        """
        out = [np.asarray(start, dtype=np.float64)]
        # IK along the whole line first (each solution seeds the next), then one check of the
        # joint path; a failure is reported at the first waypoint where either fails.
        failure: tuple[int, str, Exception] | None = None
        for k, (position, rotation) in enumerate(zip(positions, rotations, strict=True)):
            previous = out[-1]
            # Waypoints are evenly spaced: the joint path extrapolated from the last solutions
            # (quadratic, then linear) is a close first guess; IK then needs 0-1 iterations
            # instead of 1-2.
            guess = previous
            if len(out) > 3:
                guess = np.clip(3 * previous - 3 * out[-2] + out[-3], self.lower, self.upper)
            elif len(out) > 2:
                guess = np.clip(2 * previous - out[-2], self.lower, self.upper)
            try:
                q = self.model.ik(
                    frame,
                    np.asarray(position, dtype=np.float64),
                    self.full(guess, ctx.base),
                    rotation=rotation,
                    joints=ARM_JOINTS,
                    restarts=0,
                    max_iterations=100,
                )
            except IKError as error:
                failure = (k, "breaks", error)
                break
            arm = self.unwrap(self.arm(q), previous)
            jump = np.abs(arm - previous)
            j = int(np.argmax(jump))
            if jump[j] > self.config.max_joint_jump_rad:
                reason = (
                    f"{ARM_JOINTS[j]} would jump {jump[j]:.3f} rad "
                    f"(limit {self.config.max_joint_jump_rad} rad)"
                )
                failure = (k, "breaks", PlanningError(reason))
                break
            out.append(arm)
        path = np.array(out)
        states = densify(path, self.config.joint_resolution_rad)
        bad = self._first_invalid_index(states, ctx)
        if bad is not None:
            # The waypoint whose step holds the invalid state (state 0 is the start).
            ends = np.cumsum(_steps(path, self.config.joint_resolution_rad))
            k = int(np.searchsorted(ends, bad))
            failure = (k, "is blocked", PlanningError(self.explain(states[bad], ctx)))
        if failure is not None:
            k, what, cause = failure
            if partial and k > 0:
                path = path[: k + 1]
            else:
                p = np.asarray(positions[k], dtype=np.float64)
                msg = (
                    f"Cartesian path of {frame} {what} at waypoint {k} "
                    f"({p[0]:.3f}, {p[1]:.3f}, {p[2]:.3f}) m: {cause}"
                )
                raise PlanningError(msg) from cause
        self.stats.cartesian_waypoints += len(path) - 1
        return path

    def plan_joint_sweep(
        self, start: FloatArray, goal: FloatArray, ctx: CheckContext
    ) -> FloatArray:
        """The straight joint-space motion ``start`` -> ``goal`` (e.g. a digging sweep), which
        must itself be valid: (2, 6) rad.

        Raises:
            PlanningError: a state along it is invalid (with the reason).
        """
        path = np.vstack([start, goal])
        bad = self.first_invalid(path, ctx)
        if bad is not None:
            msg = f"the joint motion is blocked: {self.explain(bad, ctx)}"
            raise PlanningError(msg)
        return path


class _WorkObjective(ob.OptimizationObjective):
    """Mechanical work against gravity + a small path-length term, for RRT*."""

    def __init__(
        self,
        si: ob.SpaceInformation,
        planner: ArmPlanner,
        base: FloatArray,
        to_arm: object,
    ) -> None:
        super().__init__(si)
        self._planner = planner
        self._base = np.array(base, dtype=np.float64)
        self._to_arm = to_arm
        self._weight = planner.config.path_length_weight

    def stateCost(self, state: ob.State) -> ob.Cost:
        return ob.Cost(0.0)

    def motionCost(self, s1: ob.State, s2: ob.State) -> ob.Cost:
        a = self._to_arm(s1)  # type: ignore[operator]
        b = self._to_arm(s2)  # type: ignore[operator]
        work = self._planner.work_between(a, b, self._base, OBJECTIVE_STEP_RAD)
        return ob.Cost(work + self._weight * float(np.linalg.norm(b - a)))

    def motionCostHeuristic(self, s1: ob.State, s2: ob.State) -> ob.Cost:
        a = self._to_arm(s1)  # type: ignore[operator]
        b = self._to_arm(s2)  # type: ignore[operator]
        return ob.Cost(self._weight * float(np.linalg.norm(b - a)))
