"""Sampling-based free-space planning with OMPL: seeded RRT* with the work objective of
:mod:`ow_lander.planning.work` (or path length), a seeded RRTConnect fallback, and a greedy shortcut
of their paths. No ROS.

States are arm vectors ``arm: (6,) rad`` (see :mod:`ow_lander.planning.validity`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable

import numpy as np
import numpy.typing as npt
from ompl import base as ob
from ompl import geometric as og
from ompl import util as ou

from ow_lander.config import PlannerConfig
from ow_lander.errors import PlanningError
from ow_lander.planning.stats import PlanStats
from ow_lander.planning.validity import CheckContext, StateChecker
from ow_lander.planning.work import OBJECTIVE_STEP_RAD, GravityWork

FloatArray = npt.NDArray[np.float64]

# OMPL reports through its own logger; our errors carry the reasons. RNG.setSeed also logs an
# error when called after the first plan, although it does reseed (see SampledPlanner._solve).
ou.setLogLevel(ou.LogLevel.LOG_NONE)


class SampledPlanner:
    """RRT* and RRTConnect over the arm's joint space (not thread-safe, like the model).

    Args:
        checker: state and path validity.
        work: the work objective.
        config: planner settings (the ``rrt_*`` and ``connect_*`` ones, the seed).
        stats: counts of the owning planner, to which the solved segments and the iterations
            run are added.
    """

    def __init__(
        self, checker: StateChecker, work: GravityWork, config: PlannerConfig, stats: PlanStats
    ) -> None:
        self.checker = checker
        self.work = work
        self.config = config
        self.stats = stats

    def plan(
        self,
        start: FloatArray,
        goal: FloatArray,
        ctx: CheckContext,
        objective: str = "work",
    ) -> FloatArray:
        """A valid path from ``start`` to ``goal`` ((6,) rad, both valid): RRT* (``rrt_attempts``
        seeds), then RRTConnect, shortcut and re-checked at the joint resolution.

        The continuous joints turn the shorter way round to ``goal``. When RRT* finds no path
        that way, a straight segment with one such joint reaching its goal angle the other way
        round is taken if it is valid (a delivery's end, where the scoop would sweep the lander
        the short way round, is one); then RRTConnect the shorter way, and a last RRTConnect
        letting them reach their goal angles either way round (as MoveIt's circular space for a
        continuous joint does). Those paths may end at ``goal`` with one such joint a whole turn
        away (see :meth:`goal_turns`), so callers continue from its last row. Every search ends
        on its iteration cap (``rrt_max_iterations``, ``connect_max_iterations``): the same
        request and state give the same plan at any machine load.

        Args:
            start: (6,) rad.
            goal: (6,) rad.
            ctx: what states are checked against.
            objective: ``work`` (ours) or ``length`` (OMPL path length, for comparisons).

        Returns:
            (n, 6) rad waypoints from start to goal (up to whole turns), n >= 2.

        Raises:
            PlanningError: no path found within the caps.
        """
        config = self.config
        direct = np.vstack([start, goal])
        for attempt in range(config.rrt_attempts):
            path = self._solve(
                start,
                [goal],
                ctx,
                config.seed + attempt,
                config.rrt_check_resolution_rad,
                objective,
            )
            if path is None:
                continue
            path = self._shortcut(path, ctx, objective)
            if self.checker.path_valid(path, ctx):
                self.stats.rrt_segments += 1
                return path
        turns = self.goal_turns(start, goal)
        for other in turns[1:]:
            turned = np.vstack([start, other])
            if self.checker.path_valid(turned, ctx):
                self.stats.direct_segments += 1
                return turned
        # The shorter way round first; either way round only when that finds nothing.
        searches = [[goal], turns] if len(turns) > 1 else [[goal]]
        for goals in searches if config.connect_time_limit_s > 0 else []:
            path = self._solve(
                start, goals, ctx, config.seed, config.joint_resolution_rad, objective, connect=True
            )
            if path is not None:
                path = self._shortcut(path, ctx, objective)
                if self.checker.path_valid(path, ctx):
                    self.stats.rrt_segments += 1
                    return path
        blocked = self.checker.first_invalid(direct, ctx)
        msg = (
            f"no collision-free path found by RRT* within {config.rrt_max_iterations} "
            f"iterations / {config.rrt_time_limit_s} s, nor by RRTConnect within "
            f"{config.connect_max_iterations} iterations / {config.connect_time_limit_s} s, "
            f"the continuous joints turning either way round "
            f"(the straight segment is blocked: "
            f"{self.checker.explain(start if blocked is None else blocked, ctx)})"
        )
        raise PlanningError(msg)

    def _solve(
        self,
        start: FloatArray,
        goals: list[FloatArray],
        ctx: CheckContext,
        seed: int,
        resolution: float,
        objective: str,
        connect: bool = False,
    ) -> FloatArray | None:
        """One seeded sample-based solve from ``start`` to any of ``goals`` ((6,) rad each, the
        first the one the cost threshold is measured to): RRT* with the objective, or RRTConnect
        (``connect``, feasibility only); None when it found no exact solution within its caps."""
        checker, config = self.checker, self.config
        dim = len(checker.idx)
        space = ob.RealVectorStateSpace(dim)
        bounds = ob.RealVectorBounds(dim)
        low, high = self.sampling_bounds(start, goals)
        for i in range(dim):
            bounds.setLow(i, float(low[i]))
            bounds.setHigh(i, float(high[i]))
        space.setBounds(bounds)
        # The seed generator is reset here, before any RNG of this solve is created, so the same
        # request and state give the same plan whatever was planned before.
        ou.RNG.setSeed(int(seed))
        si = ob.SpaceInformation(space)

        def to_arm(state: ob.State) -> FloatArray:
            return np.array([state[i] for i in range(dim)])

        def valid(state: ob.State) -> bool:
            return checker.is_valid(to_arm(state), ctx)

        si.setStateValidityChecker(valid)
        si.setStateValidityCheckingResolution(resolution / space.getMaximumExtent())
        si.setup()
        pdef = ob.ProblemDefinition(si)
        s = si.allocState()
        for i in range(dim):
            s[i] = float(start[i])
        pdef.addStartState(s)
        goal_states = ob.GoalStates(si)
        for arm in goals:
            g = si.allocState()
            for i in range(dim):
                g[i] = float(arm[i])
            goal_states.addState(g)
        pdef.setGoal(goal_states)
        goal = goals[0]
        straight = np.vstack([start, goal])
        if objective == "work":
            obj: ob.OptimizationObjective = _WorkObjective(si, self.work, ctx.base, to_arm)
            threshold = self.work.cost(straight, ctx.base, OBJECTIVE_STEP_RAD)
        else:
            obj = ob.PathLengthOptimizationObjective(si)
            threshold = float(np.linalg.norm(goal - start))
        obj.setCostThreshold(ob.Cost(threshold * config.rrt_cost_threshold_factor))
        pdef.setOptimizationObjective(obj)
        planner: og.RRTstar | og.RRTConnect
        if connect:
            planner = og.RRTConnect(si)
            planner.setRange(config.rrt_range_rad)
            cap, time_limit = config.connect_max_iterations, config.connect_time_limit_s
        else:
            planner = og.RRTstar(si)
            planner.setRange(config.rrt_range_rad)
            planner.setGoalBias(config.rrt_goal_bias)
            planner.setRewireFactor(config.rrt_rewire_factor)
            cap, time_limit = config.rrt_max_iterations, config.rrt_time_limit_s
        planner.setProblemDefinition(pdef)
        planner.setup()
        iterations = 0
        solved_at: int | None = None
        improve = config.rrt_improve_iterations
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

    def goal_turns(self, start: FloatArray, goal: FloatArray) -> list[FloatArray]:
        """``goal`` ((6,) rad) and the same state with one of its moving continuous joints
        reached the other way round from ``start``: that joint a whole turn away, on the far
        side of ``start`` (within its travel), one state per such joint."""
        checker = self.checker
        continuous = checker.model.continuous[checker.idx]
        goal = np.asarray(goal, dtype=np.float64)
        turns = [goal]
        for j in np.flatnonzero(continuous & (goal != start)):
            other = goal.copy()
            other[j] -= math.copysign(2 * math.pi, goal[j] - start[j])
            if checker.lower[j] <= other[j] <= checker.upper[j]:
                turns.append(other)
        return turns

    def sampling_bounds(
        self, start: FloatArray, goals: list[FloatArray]
    ) -> tuple[FloatArray, FloatArray]:
        """(6,) rad lower and upper bounds of the joint space searched from ``start`` to
        ``goals`` (:meth:`goal_turns`): the joint limits; for a continuous joint the angles
        between its start and its goal reached either way round, and half a turn beyond them
        for detours (within its travel). The whole turns of travel the URDF allows would only
        thin out the samples."""
        checker = self.checker
        continuous = checker.model.continuous[checker.idx]
        ends = np.vstack([start, *goals])
        low = np.maximum(ends.min(axis=0) - math.pi, checker.lower)
        high = np.minimum(ends.max(axis=0) + math.pi, checker.upper)
        return np.where(continuous, low, checker.lower), np.where(continuous, high, checker.upper)

    def _shortcut(self, path: FloatArray, ctx: CheckContext, objective: str) -> FloatArray:
        """Greedy shortcut: from each kept waypoint jump to the farthest later one reachable by a
        valid straight segment that does not cost more than the detour it replaces."""

        def cost(points: FloatArray) -> float:
            if objective == "work":
                return self.work.cost(points, ctx.base, OBJECTIVE_STEP_RAD)
            return float(np.linalg.norm(np.diff(points, axis=0), axis=1).sum())

        out = [path[0]]
        i = 0
        while i < len(path) - 1:
            for j in range(len(path) - 1, i, -1):
                segment = np.vstack([path[i], path[j]])
                if j == i + 1 or (
                    cost(segment) <= cost(path[i : j + 1]) + 1e-9
                    and self.checker.path_valid(segment, ctx, self.config.rrt_check_resolution_rad)
                ):
                    out.append(path[j])
                    i = j
                    break
        return np.array(out)


class _WorkObjective(ob.OptimizationObjective):
    """Mechanical work against gravity + a small path-length term, for RRT*."""

    def __init__(
        self,
        si: ob.SpaceInformation,
        work: GravityWork,
        base: FloatArray,
        to_arm: Callable[[ob.State], FloatArray],
    ) -> None:
        super().__init__(si)
        self._work = work
        self._base = np.array(base, dtype=np.float64)
        self._to_arm = to_arm
        self._weight = work.path_length_weight

    def stateCost(self, state: ob.State) -> ob.Cost:
        return ob.Cost(0.0)

    def motionCost(self, s1: ob.State, s2: ob.State) -> ob.Cost:
        a, b = self._to_arm(s1), self._to_arm(s2)
        work = self._work.work_between(a, b, self._base, OBJECTIVE_STEP_RAD)
        return ob.Cost(work + self._weight * float(np.linalg.norm(b - a)))

    def motionCostHeuristic(self, s1: ob.State, s2: ob.State) -> ob.Cost:
        a, b = self._to_arm(s1), self._to_arm(s2)
        return ob.Cost(self._weight * float(np.linalg.norm(b - a)))
