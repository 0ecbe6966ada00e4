"""Motion planning for the six arm joints: free-space (direct segment, staged straight moves or
OMPL RRT*) and Cartesian lines (IK every ``cartesian_step_m``), collision-checked against self,
lander body, dock and the terrain. No ROS.

:class:`ArmPlanner` is the one entry point. It chooses among the free-space strategies itself and
hands the rest to its parts: state and path validity (:mod:`ow_lander.planning.validity`), the work
objective (:mod:`ow_lander.planning.work`), sampling-based planning
(:mod:`ow_lander.planning.sampling`) and IK goals and Cartesian lines
(:mod:`ow_lander.planning.cartesian`).

States are arm vectors ``arm: (6,) rad`` in :data:`~ow_description.description.ARM_JOINTS` order;
the other joints (grinder, antenna) keep the values of a base configuration ``base: (9,)`` in
pinocchio order (see :mod:`ow_description.model`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

from ow_description.description import ARM_JOINTS, UNSTOWED
from ow_description.model import LanderModel
from ow_lander.config import PlannerConfig
from ow_lander.errors import PlanningError
from ow_lander.planning.cartesian import CartesianPlanner
from ow_lander.planning.sampling import SampledPlanner
from ow_lander.planning.stats import PlanStats
from ow_lander.planning.validity import CheckContext, StateChecker
from ow_lander.planning.work import OBJECTIVE_STEP_RAD, WORK_STEP_RAD, GravityWork

FloatArray = npt.NDArray[np.float64]


class ArmPlanner:
    """Plans arm motions for one :class:`LanderModel` (not thread-safe, like the model).

    Args:
        model: kinematics, dynamics and collision model (this planner's own instance).
        config: planner settings.

    Attributes:
        checker: state and path validity at ``config.joint_resolution_rad``.
        gravity_work: work against gravity and the planning objective.
        stats: what the planner and its parts did.
    """

    def __init__(self, model: LanderModel, config: PlannerConfig) -> None:
        self.model = model
        self.config = config
        self.checker = StateChecker(model, config.joint_resolution_rad)
        self.gravity_work = GravityWork(model, config.path_length_weight)
        self.stats = PlanStats()
        self._sampled = SampledPlanner(self.checker, self.gravity_work, config, self.stats)
        self._cartesian = CartesianPlanner(self.checker, config, self.stats)
        self.idx = self.checker.idx
        self.lower = self.checker.lower
        self.upper = self.checker.upper
        self.velocity_limits = model.velocity_limit[self.idx].copy()
        #: (6,) rad, the unstowed ("safe") pose free-space motions may pass through.
        self.safe = np.array([UNSTOWED[j] for j in ARM_JOINTS])

    # ------------------------------------------------------------------------------ states
    def full(self, arm: FloatArray, base: FloatArray) -> FloatArray:
        """(9,) rad configuration: ``base`` with the arm joints set to ``arm`` (6,)."""
        return self.checker.full(arm, base)

    def arm(self, q: FloatArray) -> FloatArray:
        """(6,) rad arm joints of a (9,) configuration, a joint a hair beyond a limit (at most
        :data:`~ow_lander.planning.validity.START_LIMIT_TOLERANCE_RAD`) put on it: the state plans
        start from (see :meth:`StateChecker.arm`)."""
        return self.checker.arm(q)

    def within_limits(self, arm: FloatArray) -> bool:
        """True when every arm joint is within its URDF limits."""
        return self.checker.within_limits(arm)

    def is_valid(self, arm: FloatArray, ctx: CheckContext) -> bool:
        """True when ``arm`` is within the joint limits and collision-free in ``ctx``."""
        return self.checker.is_valid(arm, ctx)

    def explain(self, arm: FloatArray, ctx: CheckContext) -> str:
        """Why ``arm`` is invalid, in words (joint limits or contacts)."""
        return self.checker.explain(arm, ctx)

    def first_invalid(
        self, waypoints: FloatArray, ctx: CheckContext, resolution: float | None = None
    ) -> FloatArray | None:
        """The first invalid state along the polyline at ``resolution`` rad (default: the
        configured joint resolution), or None when the whole path is valid."""
        return self.checker.first_invalid(waypoints, ctx, resolution)

    def path_valid(
        self, waypoints: FloatArray, ctx: CheckContext, resolution: float | None = None
    ) -> bool:
        """True when every state along the polyline at ``resolution`` rad (default: the
        configured joint resolution) is valid (see :meth:`StateChecker.path_valid`)."""
        return self.checker.path_valid(waypoints, ctx, resolution)

    def unwrap(self, arm: FloatArray, reference: FloatArray, headroom: float = 0.0) -> FloatArray:
        """``arm`` with each continuous joint moved by whole turns to the value closest to
        ``reference`` that stays within its travel (the same configuration, reached from
        ``reference`` the shorter way round), ``headroom`` rad inside it when possible (see
        :meth:`StateChecker.unwrap`)."""
        return self.checker.unwrap(arm, reference, headroom)

    # -------------------------------------------------------------------------------- work
    def work(self, waypoints: FloatArray, base: FloatArray, step: float = WORK_STEP_RAD) -> float:
        """J, mechanical work against gravity along the polyline (n, 6) (see
        :meth:`GravityWork.work`)."""
        return self.gravity_work.work(waypoints, base, step)

    def work_between(
        self, a: FloatArray, b: FloatArray, base: FloatArray, step: float = WORK_STEP_RAD
    ) -> float:
        """J, :meth:`work` of the straight joint motion ``a`` -> ``b`` ((6,) rad each)."""
        return self.gravity_work.work_between(a, b, base, step)

    def cost(self, waypoints: FloatArray, base: FloatArray, step: float = WORK_STEP_RAD) -> float:
        """The objective of a polyline (n, 6): work (J) + weight * joint path length (rad)."""
        return self.gravity_work.cost(waypoints, base, step)

    # ---------------------------------------------------------------------------- free space
    def plan_free(
        self,
        start: FloatArray,
        goal: FloatArray,
        ctx: CheckContext,
        objective: str = "work",
    ) -> FloatArray:
        """A collision-free joint-space path, (n >= 2, 6) rad, from ``start`` to ``goal`` (both
        (6,) rad) checked against ``ctx``: the direct segment when it is valid at the joint
        resolution; then two staged straight moves (wrist first or shoulder first), also
        through the unstowed pose (:meth:`plan_straight`); otherwise the sampled search of
        :meth:`plan_sampled` (``objective`` ``work``, ours, or ``length``, OMPL's).

        A continuous joint's goal may be any angle: the path ends at the same angle less whole
        turns, the one nearest ``start`` (:meth:`unwrap`), so that it turns the shorter way
        round, as MoveIt plans continuous joints (a goal of 7.87 rad from 0 ends at 1.588 rad);
        only when no path is found that way, one such joint may end a whole turn further,
        having turned the other way round (:meth:`goal_turns`). Continue from the path's last
        row.

        Raises:
            PlanningError: invalid start or goal (with the reason), or no path found.
        """
        start = np.asarray(start, dtype=np.float64)
        goal = self.checker.unwrap(np.asarray(goal, dtype=np.float64), start)
        for name, arm in (("start", start), ("goal", goal)):
            if not self.checker.is_valid(arm, ctx):
                msg = f"the {name} configuration is invalid: {self.checker.explain(arm, ctx)}"
                raise PlanningError(msg)
        straight = self.plan_straight(start, goal, ctx)
        if straight is not None:
            return straight
        return self.plan_sampled(start, goal, ctx, objective)

    def goal_turns(self, start: FloatArray, goal: FloatArray) -> list[FloatArray]:
        """``goal`` and the same state with one of its moving continuous joints reached the
        other way round from ``start`` (a whole turn away), one per such joint: (6,) rad each,
        ``goal`` first."""
        return self._sampled.goal_turns(start, goal)

    def plan_sampled(
        self,
        start: FloatArray,
        goal: FloatArray,
        ctx: CheckContext,
        objective: str = "work",
    ) -> FloatArray:
        """The sampling steps of :meth:`plan_free` alone (RRT*, then RRTConnect, the continuous
        joints turning the shorter way; then RRTConnect, either way), shortcut and re-checked
        at the joint resolution; ``start`` and ``goal`` (6,) rad must be valid.

        Raises:
            PlanningError: no path found within the caps.
        """
        return self._sampled.plan(start, goal, ctx, objective)

    def plan_straight(
        self, start: FloatArray, goal: FloatArray, ctx: CheckContext, via_safe: bool = True
    ) -> FloatArray | None:
        """The straight-move steps of :meth:`plan_free` alone: the direct segment ``start`` ->
        ``goal`` ((6,) rad, both valid) when it is valid, else the cheaper valid pair of staged
        straight moves, else (``via_safe``) the same two steps to the unstowed pose and from
        there on (the paper's reason for having a "safe" configuration); None when none is, for
        a caller that prefers another goal to a sampled path."""
        path = self._direct_or_staged(start, goal, ctx)
        if path is None and via_safe:
            path = self._via_safe(start, goal, ctx)
        if path is not None:
            self.stats.direct_segments += len(path) - 1
        return path

    def _direct_or_staged(
        self, start: FloatArray, goal: FloatArray, ctx: CheckContext
    ) -> FloatArray | None:
        direct = np.vstack([start, goal])
        if self.checker.path_valid(direct, ctx):
            return direct
        return self._staged(start, goal, ctx)

    def _via_safe(
        self, start: FloatArray, goal: FloatArray, ctx: CheckContext
    ) -> FloatArray | None:
        """Direct or staged moves to the unstowed pose (its yaws turned nearest to ``goal``) and
        from there to ``goal``, or None."""
        safe = self.checker.unwrap(self.safe, goal)
        # Not when either end is the safe pose already (up to whole turns of the yaws).
        if np.allclose(self.checker.unwrap(start, safe), safe) or np.allclose(safe, goal):
            return None
        if not self.checker.is_valid(safe, ctx):
            return None
        first = self._direct_or_staged(start, safe, ctx)
        if first is None:
            return None
        second = self._direct_or_staged(safe, goal, ctx)
        return None if second is None else np.vstack([first, second[1:]])

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
            candidates.sort(
                key=lambda path: self.gravity_work.cost(path, ctx.base, OBJECTIVE_STEP_RAD)
            )
            for path in candidates:
                if self.checker.is_valid(path[1], ctx) and self.checker.path_valid(path, ctx):
                    return path
        return None

    def plan_joint_sweep(
        self, start: FloatArray, goal: FloatArray, ctx: CheckContext
    ) -> FloatArray:
        """The straight joint-space motion ``start`` -> ``goal`` (e.g. a digging sweep), which
        must itself be valid: (2, 6) rad.

        Raises:
            PlanningError: a state along it is invalid (with the reason).
        """
        path = np.vstack([start, goal])
        bad = self.checker.first_invalid(path, ctx)
        if bad is not None:
            msg = f"the joint motion is blocked: {self.checker.explain(bad, ctx)}"
            raise PlanningError(msg)
        return path

    # ---------------------------------------------------------------------- tool frame space
    def solve_ik(
        self,
        frame: str,
        position: FloatArray,
        rotation: FloatArray | None,
        seed_arm: FloatArray,
        ctx: CheckContext,
    ) -> FloatArray:
        """A valid arm configuration placing ``frame`` at ``position`` (3,) m (and ``rotation``
        (3, 3) if given) in base_link, on the same kinematic branch as ``seed_arm`` (6,) rad
        (see :meth:`CartesianPlanner.solve_ik`).

        Raises:
            PlanningError: unreachable, or the solution collides (with the reason).
        """
        return self._cartesian.solve_ik(frame, position, rotation, seed_arm, ctx)

    def prepare_ik(
        self, frame: str, position: FloatArray, rotation: FloatArray | None, base: FloatArray
    ) -> None:
        """Work out ahead the IK that :meth:`solve_ik` may fall back to for a target (see
        :meth:`CartesianPlanner.prepare`)."""
        self._cartesian.prepare(frame, position, rotation, base)

    def plan_cartesian(
        self,
        start: FloatArray,
        frame: str,
        positions: Sequence[FloatArray],
        rotations: Sequence[FloatArray | None],
        ctx: CheckContext,
        partial: bool = False,
    ) -> FloatArray:
        """Follow Cartesian waypoints ``positions`` (3,) m and ``rotations`` (3, 3) or None with
        ``frame`` from ``start`` (6,) rad: (n + 1, 6) rad, fewer rows with ``partial`` (see
        :meth:`CartesianPlanner.plan_cartesian`).

        Raises:
            PlanningError: IK fails, a joint jumps too far or a state collides (the message
                names the waypoint).
        """
        return self._cartesian.plan_cartesian(start, frame, positions, rotations, ctx, partial)
