"""The arm operations of the paper (section 3) as plans: request validation, defaults and geometry.

:class:`Operations` plans every service's operation from the current configuration
``q: (9,) rad`` (pinocchio order) and the terrain: it lifts a tool out of the terrain first when
needed, plans the free-space operations (unstow, stow, deliver sample) itself and the operations in
the ground with :mod:`ow_lander.operations.ground`, all from the motions of
:class:`~ow_lander.operations.motions.ArmMotions`. A plan is an :class:`OperationPlan`: labelled
joint-space segments of the six arm joints, each with its speed class (see
:mod:`ow_description.trajectory`). Points are in base_link, m. Bad requests raise
:class:`~ow_lander.errors.PlanningError` with a message naming the value and the limit. No ROS.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
import numpy.typing as npt

from ow_description.description import ARM_JOINTS, SCOOP_LINK, SCOOP_TIP_FRAME, STOWED, UNSTOWED
from ow_description.terrain import HeightMap
from ow_description.trajectory import PathSegment
from ow_lander.errors import PlanningError
from ow_lander.operations import ground as ground_operations
from ow_lander.operations.motions import ArmMotions, ry
from ow_lander.operations.operation_plan import OperationPlan, check_finite
from ow_lander.operations.registry import OPERATIONS
from ow_lander.operations.workspace import SHOULDER_XY, shoulder_yaw_for
from ow_lander.planning.planner import ArmPlanner
from ow_lander.planning.validity import CheckContext

__all__ = [
    "DOCK_CENTRE",
    "DOCK_POUR_HEIGHT",
    "POUR_TILT",
    "OperationPlan",
    "Operations",
    "shoulder_yaw_for",
]

FloatArray = npt.NDArray[np.float64]

#: m, sample dock (lander_sample_dock0) box centre in base_link.
DOCK_CENTRE = (0.555, -0.35, 0.65)
#: m, height of the scoop tip above the dock centre when a delivery to the dock ends.
DOCK_POUR_HEIGHT = 0.25
#: rad, how far the scoop is tipped (about its own y axis) to pour.
POUR_TILT = math.radians(110)
#: The delivery to the dock (:meth:`Operations.plan_deliver_sample`): the scoop level, its mouth
#: along the dock's length (+y of base_link; the box is 30 cm long along y, 9.5 cm wide across
#: x), its tip (m, base_link) over the dock's +y half, 0.3 m above the dock; the arm's pitch
#: joints then turn about axes across the dock, so that turning the distal pitch alone tips the
#: scoop forward and its lip pours along the dock's length, all of it into the dock.
DOCK_STAGING_TIP = (0.56, -0.25, 0.95)
#: rad, the heading of the scoop's mouth at the staging pose.
DOCK_STAGING_HEADING = math.pi / 2
#: rad, (shoulder yaw ... scoop yaw) near the staging pose, the seed of its IK: the arm reaching
#: the dock from the front with its hand yaw at 0, the family of poses the arm digs in, in
#: which the scoop stays level along any straight joint move (OceanWATERS' own delivery goes
#: through named joint poses too: arm_deliver_staging_1, _2 and arm_deliver_final).
DOCK_STAGING_REFERENCE = (-1.72, 1.62, -0.43, -1.19, 0.0, -1.42)


class Operations:
    """Plans the paper's operations with an :class:`ArmPlanner`.

    Args:
        planner: the planner (and through it the model) to use.
    """

    def __init__(self, planner: ArmPlanner) -> None:
        self.planner = planner
        self.model = planner.model
        self.motions = ArmMotions(planner)

    def plan(
        self,
        name: str,
        q: FloatArray,
        terrain: HeightMap | None,
        request: Mapping[str, Any] | None = None,
    ) -> OperationPlan:
        """Plan operation ``name`` (a service name) from configuration ``q``.

        When the scoop or grinder starts in or within ``CONTACT_CLEARANCE`` of the terrain
        (after a guarded move, a dig or a grind), the plan begins with a straight lift of that
        tool's tip to ``LIFT_OFF_CLEARANCE`` above the terrain.

        Raises:
            PlanningError: unknown operation, invalid request, or no valid plan.
        """
        values = request or {}
        if name not in OPERATIONS:
            msg = f"unknown operation {name!r}; known: {', '.join(OPERATIONS)}"
            raise PlanningError(msg)
        plan_operation = getattr(self, OPERATIONS[name].planner_method)
        escape = self.motions.escape(q, terrain)
        if escape is not None:
            q = self.planner.full(escape[-1], q)
        lift = self.motions.lift_off(q, terrain)
        start = q if lift is None else self.planner.full(lift[-1], q)
        plan = plan_operation(start, terrain, values)
        if lift is not None:
            plan.segments.insert(0, PathSegment("lift_off", lift))
            plan.notes.append("started with a tool in the terrain: lifted it out first")
        if escape is not None:
            plan.segments.insert(0, PathSegment("escape", escape))
            plan.notes.append("started touching the lander's collision model: moved out first")
        return plan

    def plan_unstow(
        self, q: FloatArray, terrain: HeightMap | None, request: Mapping[str, Any] | None = None
    ) -> OperationPlan:
        """Free-space motion to the unstowed ("safe") configuration."""
        return self._to_named("unstow", UNSTOWED, q, terrain)

    def plan_stow(
        self, q: FloatArray, terrain: HeightMap | None, request: Mapping[str, Any] | None = None
    ) -> OperationPlan:
        """Free-space motion to the stowed configuration."""
        return self._to_named("stow", STOWED, q, terrain)

    def _to_named(
        self, name: str, pose: Mapping[str, float], q: FloatArray, terrain: HeightMap | None
    ) -> OperationPlan:
        start = self.motions.start(q, terrain)
        # The hand and scoop yaw turn freely (continuous in the original): reach the named
        # angle by the shorter way round from where the joint is.
        goal = self.planner.unwrap(np.array([pose[j] for j in ARM_JOINTS]), start)
        path = self.planner.plan_free(start, goal, self.motions.context(q, terrain))
        return OperationPlan(name, [PathSegment(name, path)], {})

    def plan_guarded_move(
        self, q: FloatArray, terrain: HeightMap | None, request: Mapping[str, Any]
    ) -> OperationPlan:
        """See :func:`ow_lander.operations.ground.plan_guarded_move`."""
        return ground_operations.plan_guarded_move(self.motions, q, terrain, request)

    def plan_grind(
        self, q: FloatArray, terrain: HeightMap | None, request: Mapping[str, Any]
    ) -> OperationPlan:
        """See :func:`ow_lander.operations.ground.plan_grind`."""
        return ground_operations.plan_grind(self.motions, q, terrain, request)

    def plan_dig_linear(
        self, q: FloatArray, terrain: HeightMap | None, request: Mapping[str, Any]
    ) -> OperationPlan:
        """See :func:`ow_lander.operations.ground.plan_dig_linear`."""
        return ground_operations.plan_dig_linear(self.motions, q, terrain, request)

    def plan_dig_circular(
        self, q: FloatArray, terrain: HeightMap | None, request: Mapping[str, Any]
    ) -> OperationPlan:
        """See :func:`ow_lander.operations.ground.plan_dig_circular`."""
        return ground_operations.plan_dig_circular(self.motions, q, terrain, request)

    def plan_deliver_sample(
        self, q: FloatArray, terrain: HeightMap | None, request: Mapping[str, Any]
    ) -> OperationPlan:
        """Carry the scoop upright to the pour point, then tip it to pour: over the sample dock
        (use_defaults) or at (x, y, z) to discard. To discard, the scoop tip is held at the
        point, or, with ``held: l_scoop`` (OceanWATERS' TaskDiscardSample), the scoop link's
        origin, tipping about it. To the dock, the scoop is carried level to a staging pose over
        the dock and pours there, all it holds into the dock (:meth:`_dock_delivery`); it then
        ends at the pour point, tipped. Where that cannot be planned, it is carried to the pour
        point and tipped there as a discard is (noted: the scoop pours on the way)."""
        use_dock = bool(request.get("use_defaults"))
        if use_dock:
            p: dict[str, Any] = {
                "x": DOCK_CENTRE[0],
                "y": DOCK_CENTRE[1],
                "z": DOCK_CENTRE[2] + DOCK_POUR_HEIGHT,
                "target": "sample_dock",
            }
        else:
            p = {"x": request["x"], "y": request["y"], "z": request["z"], "target": "discard"}
        check_finite(p, "x", "y", "z")
        point = np.array([p["x"], p["y"], p["z"]], dtype=float)
        origin = None  # the held frame's origin in the tip frame (None: the tip itself)
        if not use_dock and request.get("held", SCOOP_TIP_FRAME) == SCOOP_LINK:
            p["held"] = SCOOP_LINK
            X_tip = self.model.fk(q, SCOOP_TIP_FRAME)
            origin = (np.linalg.inv(X_tip) @ self.model.fk(q, SCOOP_LINK))[:3, 3]
        start = self.motions.start(q, terrain)
        ctx = self.motions.context(q, terrain)
        if not use_dock:
            return self._pour_at(start, point, ctx, p, origin)
        try:
            return self._dock_delivery(start, point, ctx, p)
        except PlanningError as error:
            plan = self._pour_at(start, point, ctx, p, origin)
            plan.notes.append(
                f"the pour from the dock's staging pose cannot be planned ({error}): poured at "
                "the pour point instead, which tips the scoop on the way"
            )
            return plan

    def _pour_at(
        self,
        start: FloatArray,
        point: FloatArray,
        ctx: CheckContext,
        p: dict[str, Any],
        origin: FloatArray | None,
    ) -> OperationPlan:
        """Carry the scoop upright over ``point`` (3,) m and tip it there (the held frame's
        ``origin`` (3,) m in the tip frame at the point; None: the tip).

        Raises:
            PlanningError: no heading has a path (the message gives the first reason).
        """
        errors: list[str] = []
        goals: list[tuple[FloatArray, FloatArray]] = []
        # The scoop's heading over the pour point is free: the first heading (in order of
        # preference) that straight joint moves reach and tip is taken, the tip a short motion
        # (direct or staged); failing that, the first whose tip passes the safe pose; a sampled
        # path (RRT*) only when no heading has either. IK follows the arm from its own pose, then
        # from the unstowed one (an arm left tipped at a discard point has its wrist on a branch
        # whose carrying poses touch the hand).
        for seed in (start, self.planner.safe):
            for phi in _pour_headings(point):
                solved = self._carry_and_pour(point, phi, seed, ctx, errors, origin)
                if solved is None:
                    continue
                # The tip first: a heading whose pour needs a detour is usually refuted there.
                plan = self._straight_delivery(start, *solved, ctx, p, via_safe=False)
                if plan is not None:
                    return plan
                goals.append(solved)
        for carry, pour in goals:
            plan = self._straight_delivery(start, carry, pour, ctx, p, via_safe=True)
            if plan is not None:
                return plan
        for carry, pour in goals:
            try:
                approach = self.planner.plan_free(start, carry, ctx)
                # From where the approach ended (it may end a whole turn of a wrist yaw away).
                tip = self.planner.plan_free(approach[-1], pour, ctx)
            except PlanningError as error:
                errors.append(str(error))
                continue
            return self._delivery(approach, tip, p)
        msg = f"no way to pour at ({point[0]:.3f}, {point[1]:.3f}, {point[2]:.3f}) m: {errors[0]}"
        raise PlanningError(msg)

    def _dock_delivery(
        self, start: FloatArray, point: FloatArray, ctx: CheckContext, p: dict[str, Any]
    ) -> OperationPlan:
        """The delivery to the sample dock: carry the scoop level to the staging pose
        (:data:`DOCK_STAGING_TIP`), pour by turning the distal pitch alone by ``POUR_TILT``,
        then take the (empty) scoop to a pour pose at ``point`` (3,) m: tipped by ``POUR_TILT``,
        its mouth along the first heading straight moves reach (:data:`DOCK_STAGING_HEADING`,
        then a discard's), else by a sampled path.

        Raises:
            PlanningError: the staging pose, the carry, the pour or the last move cannot be
                planned (the message says which).
        """
        carry_R, _ = _carry_and_pour_rotations(DOCK_STAGING_HEADING)
        reference = np.array(DOCK_STAGING_REFERENCE)
        staging = self.planner.solve_ik(
            SCOOP_TIP_FRAME, np.array(DOCK_STAGING_TIP), carry_R, reference, ctx
        )
        # The hand and scoop yaws the whole turns nearest the start's: a straight move that
        # turned the hand yaw by a whole turn would tip the scoop over on the way. The pitches
        # stay as solved near the reference (their sum, zero, keeps the scoop level).
        pitches = [ARM_JOINTS.index(j) for j in ("j_shou_pitch", "j_prox_pitch", "j_dist_pitch")]
        unwrapped = self.planner.unwrap(staging, start)
        unwrapped[pitches] = staging[pitches]
        approach = self.motions.level_route(start, unwrapped, ctx)
        poured = unwrapped.copy()
        poured[ARM_JOINTS.index("j_dist_pitch")] += POUR_TILT
        pour = self.planner.plan_joint_sweep(unwrapped, poured, ctx)
        # Empty, the scoop goes on to the pour point, where every delivery ends, as a discard
        # would pour there (straight moves at the first heading they reach, else sampled), its
        # mouth still along the dock first.
        errors: list[str] = []
        goals: list[FloatArray] = []
        for seed in (poured, self.planner.safe):
            for phi in (DOCK_STAGING_HEADING, *_pour_headings(point)):
                solved = self._carry_and_pour(point, phi, seed, ctx, errors)
                if solved is None:
                    continue
                present = self.planner.plan_straight(poured, solved[1], ctx)
                if present is not None:
                    return self._delivery(approach, np.vstack([pour, present[1:]]), p)
                goals.append(solved[1])
        if not goals:
            msg = f"no pour pose at the point: {errors[0]}"
            raise PlanningError(msg)
        present = self.planner.plan_free(poured, goals[0], ctx)
        return self._delivery(approach, np.vstack([pour, present[1:]]), p)

    def plan_discard(
        self, q: FloatArray, terrain: HeightMap | None, request: Mapping[str, Any]
    ) -> OperationPlan:
        """Discard the sample: carry the scoop upright, its link's origin at (x, y, z), and tip
        it there (the action TaskDiscardSample, as OceanWATERS holds ``l_scoop``, not the tip;
        the point is already raised by its ``height``)."""
        request = {**request, "use_defaults": False, "held": SCOOP_LINK}
        plan = self.plan_deliver_sample(q, terrain, request)
        return OperationPlan("discard", plan.segments, plan.parameters)

    def plan_move_joints(
        self, q: FloatArray, terrain: HeightMap | None, request: Mapping[str, Any]
    ) -> OperationPlan:
        """Free-space motion to the arm joints ``angles`` (6,) rad, shoulder to scoop; with
        ``guarded`` (a guarded action) the scoop may go into the terrain, where the
        force/torque guard stops it.

        Raises:
            PlanningError: a target outside its joint limits, in collision, or no path.
        """
        start = self.motions.start(q, terrain)
        goal = np.asarray(request["angles"], dtype=np.float64)
        bad = self.model.limit_violations(self.planner.full(goal, q))
        if bad:
            msg = f"target out of the joint limits: {'; '.join(bad)}"
            raise PlanningError(msg)
        ctx = self.motions.context(q, terrain, SCOOP_LINK if request.get("guarded") else None)
        path = self.planner.plan_free(start, goal, ctx)
        return OperationPlan("move_joints", [PathSegment("move", path)], {})

    def plan_move_cartesian(
        self, q: FloatArray, terrain: HeightMap | None, request: Mapping[str, Any]
    ) -> OperationPlan:
        """Free-space motion putting the scoop tip at ``position`` (3,) m with ``rotation``
        (3, 3) in base_link (IK on the arm's present branch, as MoveIt's pose targets); with
        ``guarded`` the scoop may go into the terrain.

        Raises:
            PlanningError: out of reach, in collision, or no path.
        """
        start = self.motions.start(q, terrain)
        ctx = self.motions.context(q, terrain, SCOOP_LINK if request.get("guarded") else None)
        position = np.asarray(request["position"], dtype=np.float64)
        rotation = np.asarray(request["rotation"], dtype=np.float64)
        goal = self.planner.solve_ik(SCOOP_TIP_FRAME, position, rotation, start, ctx)
        path = self.planner.plan_free(start, goal, ctx)
        return OperationPlan("move_cartesian", [PathSegment("move", path)], {})

    def _straight_delivery(
        self,
        start: FloatArray,
        carry: FloatArray,
        pour: FloatArray,
        ctx: CheckContext,
        p: dict[str, Any],
        via_safe: bool,
    ) -> OperationPlan | None:
        """Approach ``carry`` and tip to ``pour`` ((6,) rad) by straight joint moves (the tip
        through the safe pose only ``via_safe``), or None."""
        tip = self.planner.plan_straight(carry, pour, ctx, via_safe)
        approach = None if tip is None else self.planner.plan_straight(start, carry, ctx)
        return None if approach is None or tip is None else self._delivery(approach, tip, p)

    def _carry_and_pour(
        self,
        point: FloatArray,
        heading: float,
        seed: FloatArray,
        ctx: CheckContext,
        errors: list[str],
        origin: FloatArray | None = None,
    ) -> tuple[FloatArray, FloatArray] | None:
        """(carry, pour) (6,) rad: the scoop upright with its mouth along ``heading`` rad, then
        tipped, its tip at ``point`` (3,) m (or the point ``origin`` (3,) m in the tip frame),
        IK from ``seed``; None (the reason added to ``errors``) when either is unreachable or
        collides."""
        carry_R, pour_R = _carry_and_pour_rotations(heading)
        carry_at, pour_at = point, point
        if origin is not None:
            carry_at, pour_at = point - carry_R @ origin, point - pour_R @ origin
        solve = self.planner.solve_ik
        try:
            carry = solve(SCOOP_TIP_FRAME, carry_at, carry_R, seed, ctx)
            return carry, solve(SCOOP_TIP_FRAME, pour_at, pour_R, carry, ctx)
        except PlanningError as error:
            errors.append(str(error))
            return None

    def prepare(self, q: FloatArray) -> None:
        """Work out ahead the IK that deliveries to the sample dock may fall back to: the
        scoop's carrying and pouring poses over the dock at every heading tried, from random
        restarts (~0.1-0.2 s). The arm services node calls it at start-up, so that no delivery
        pays for them; a plan is the same with or without it (each outcome is a function of the
        pose and the planner's seed, :meth:`CartesianPlanner.prepare
        <ow_lander.planning.cartesian.CartesianPlanner.prepare>`).

        Args:
            q: (9,) rad, a configuration of the joints IK does not move.
        """
        point = np.add(DOCK_CENTRE, (0.0, 0.0, DOCK_POUR_HEIGHT))
        for heading in _pour_headings(point):
            for rotation in _carry_and_pour_rotations(heading):
                self.planner.prepare_ik(SCOOP_TIP_FRAME, point, rotation, q)

    @staticmethod
    def _delivery(approach: FloatArray, tip: FloatArray, p: dict[str, Any]) -> OperationPlan:
        segments = [PathSegment("approach", approach), PathSegment("pour", tip)]
        return OperationPlan("deliver_sample", segments, p)


def _pour_headings(point: FloatArray) -> tuple[float, ...]:
    """rad, the headings of the scoop's mouth tried over the pour ``point`` (3,) m, in order of
    preference: along base_link's x, away from the shoulder, then four fixed ones."""
    away = math.atan2(point[1] - SHOULDER_XY[1], point[0] - SHOULDER_XY[0])
    return (0.0, away, math.pi - math.pi / 4, -math.pi / 4, math.pi / 2, -math.pi / 2)


def _carry_and_pour_rotations(heading: float) -> tuple[FloatArray, FloatArray]:
    """(3, 3) each, in base_link: the scoop upright with its mouth along ``heading`` rad, and
    the same tipped to pour."""
    x_axis = np.array([math.cos(heading), math.sin(heading), 0.0])
    z_axis = np.array([0.0, 0.0, -1.0])
    carry = np.column_stack([x_axis, np.cross(z_axis, x_axis), z_axis])
    return carry, carry @ ry(-POUR_TILT)
