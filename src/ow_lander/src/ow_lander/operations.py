"""The arm operations of the paper (section 3) as plans: request validation, defaults and geometry.

Each ``plan_*`` method takes the current configuration ``q: (9,) rad`` (pinocchio order), the
terrain and the request's values, and returns an :class:`OperationPlan`: labelled joint-space
segments of the six arm joints (see :mod:`ow_lander.planning`). Points are in base_link, m.
Bad requests raise :class:`~ow_lander.errors.PlanningError` with a message naming the value and
the limit. No ROS.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from ow_lander.description import (
    ARM_JOINTS,
    GRINDER_LINK,
    GRINDER_TIP_FRAME,
    SCOOP_LINK,
    SCOOP_TIP_FRAME,
    STOWED,
    UNSTOWED,
)
from ow_lander.errors import PlanningError
from ow_lander.model import ARM_LINKS
from ow_lander.planning import ArmPlanner, CheckContext
from ow_lander.terrain import HeightMap
from ow_lander.trajectory import PathSegment

FloatArray = npt.NDArray[np.float64]

#: m, shoulder yaw axis in base_link (OceanWATERS X_SHOU, Y_SHOU).
SHOULDER_XY = (0.79, 0.175)
#: m, lateral offset of the arm's working plane from the shoulder axis (Y_SHOU - HAND_Y_OFFSET).
ARM_PLANE_OFFSET = 0.15
#: m, default ground height in base_link (OceanWATERS DEFAULT_GROUND_HEIGHT at v6.0).
DEFAULT_GROUND = -0.155
#: m, height above the ground of the tool before it goes down and after it comes up.
APPROACH_HEIGHT = 0.2
#: m, lateral distance between the two grinding passes (OceanWATERS: 0.08 m / 0.08 rad).
GRIND_PASS_SHIFT = 0.08
#: m, deepest trench the grinder can make: its 0.16 m length less clearance for the hand.
MAX_GRIND_DEPTH = 0.14
#: m, deepest cut or sweep of the scoop (its mouth is ~0.08 m deep; deeper buries the hand).
MAX_SCOOP_DEPTH = 0.1
#: m, longest trench or cut accepted.
MAX_LENGTH = 1.0
#: rad, sweep of the circular dig (OceanWATERS: 2 pi / 3 of the distal pitch).
CIRCULAR_SWEEP = 2 * math.pi / 3
#: m, sample dock (lander_sample_dock0) box centre in base_link.
DOCK_CENTRE = (0.555, -0.35, 0.65)
#: m, height of the scoop tip above the dock centre when pouring.
DOCK_POUR_HEIGHT = 0.25
#: m, clearance above the terrain a tool is lifted to when an operation starts in contact.
LIFT_OFF_CLEARANCE = 0.10
#: m, a tool closer than this to the terrain at the start of an operation is lifted off first
#: (it may sit in a dent it made, whose walls the next motion would scrape).
CONTACT_CLEARANCE = 0.02
#: rad, how far the scoop is tipped (about its own y axis) to pour.
POUR_TILT = math.radians(110)
#: rad, (shoulder pitch, prox, dist, hand, scoop) of the reference configurations, aimed by the
#: shoulder yaw: OceanWATERS' joint-space pre-configurations, used as tool orientations, IK seeds
#: and via points.
#: Dig linear: scoop yaw pi/2 (OceanWATERS) and the mouth pitched down into the cut by the first
#: of these distal pitches that the arm can hold along the whole cut (OceanWATERS' 40 degree
#: "dig in" attitude cannot be held along a cut at ground level by this arm).
DIG_LINEAR_PITCHES = tuple(math.radians(d) for d in (-30, -45, -15, 0, -60))
GRIND_POSE = (math.pi / 2, -math.pi / 2, 0.0, 4 * math.pi / 3, 0.0)
GUARDED_POSE = (math.pi / 2, -math.pi / 2, 0.0, 0.0, 0.0)
#: Circular dig references: parallel sweeps the distal pitch, perpendicular the hand yaw.
CIRCULAR_PARALLEL_POSE = (math.pi / 2, -math.pi / 2, -19 * math.pi / 54, 0.0, math.pi / 2)
CIRCULAR_PERPENDICULAR_POSE = (math.pi / 2, -math.pi / 2, 0.0, 0.0, 0.0)

#: Defaults when use_defaults is true (OceanWATERS v6.0, spec section 2.4).
DEFAULTS: dict[str, dict[str, Any]] = {
    "guarded_move": {
        "x": 2.0,
        "y": 0.0,
        "z": 0.3,
        "direction_x": 0.0,
        "direction_y": 0.0,
        "direction_z": 1.0,
        "search_distance": 0.5,
    },
    "dig_circular": {
        "x": 1.65,
        "y": 0.0,
        "depth": 0.01,
        "parallel": True,
        "ground_position": -0.155,
    },
    "dig_linear": {"x": 1.46, "y": 0.0, "depth": 0.01, "length": 0.1, "ground_position": -0.155},
    "grind": {
        "x": 1.65,
        "y": 0.0,
        "depth": 0.05,
        "length": 0.6,
        "parallel": True,
        "ground_position": -0.155,
    },
}


@dataclass
class OperationPlan:
    """A planned operation.

    Attributes:
        operation: service name, e.g. ``grind``.
        segments: labelled joint paths of the arm joints (ARM_JOINTS order), in order.
        parameters: the effective request (after defaults), for /arm/operation and the docs.
        notes: remarks for the response message.
    """

    operation: str
    segments: list[PathSegment]
    parameters: dict[str, Any]
    notes: list[str] = field(default_factory=list)

    @property
    def end(self) -> FloatArray:
        """(6,) rad, the arm configuration at the end of the plan."""
        return np.asarray(self.segments[-1].waypoints[-1])


# --------------------------------------------------------------------------- validation
def effective_parameters(operation: str, request: Mapping[str, Any]) -> dict[str, Any]:
    """The request's values, replaced by :data:`DEFAULTS` when ``use_defaults`` is true."""
    values = {k: v for k, v in request.items() if k not in ("use_defaults", "delete_prev_traj")}
    if request.get("use_defaults") and operation in DEFAULTS:
        values.update(DEFAULTS[operation])
    return values


def _finite(values: Mapping[str, Any], *names: str) -> None:
    for name in names:
        value = float(values[name])
        if not math.isfinite(value):
            msg = f"{name}={value} is not a finite number"
            raise PlanningError(msg)


#: Request fields are float32: 0.1 arrives as 0.10000000149. Limits are compared with this slack.
FLOAT32_SLACK = 1e-6


def _depth(depth: float, limit: float, tool: str) -> None:
    if depth < 0:
        msg = f"depth={depth:.3f} m must not be negative (it is measured down from the ground)"
        raise PlanningError(msg)
    if depth > limit + FLOAT32_SLACK:
        msg = f"depth={depth:.3f} m is deeper than the {tool} can go (max {limit:.2f} m)"
        raise PlanningError(msg)


def _length(length: float) -> None:
    if not 0 < length <= MAX_LENGTH + FLOAT32_SLACK:
        msg = f"length={length:.3f} m must be in (0, {MAX_LENGTH}] m"
        raise PlanningError(msg)


def shoulder_yaw_for(x: float, y: float, lower: float, upper: float) -> float:
    """rad, shoulder yaw aiming the arm's working plane at (x, y) (OceanWATERS alpha + beta).

    Raises:
        PlanningError: the point is inside the shoulder's offset circle or the yaw is outside
            [lower, upper].
    """
    dx, dy = x - SHOULDER_XY[0], y - SHOULDER_XY[1]
    h = math.hypot(dx, dy)
    if h <= ARM_PLANE_OFFSET:
        msg = (
            f"(x, y)=({x:.3f}, {y:.3f}) m is {h:.3f} m from the shoulder axis, closer than the "
            f"arm plane offset {ARM_PLANE_OFFSET} m"
        )
        raise PlanningError(msg)
    yaw = math.atan2(dy, dx) + math.asin(ARM_PLANE_OFFSET / h)
    if not lower <= yaw <= upper:
        msg = (
            f"(x, y)=({x:.3f}, {y:.3f}) m needs shoulder yaw {yaw:.3f} rad, outside the joint "
            f"limits [{lower:.2f}, {upper:.2f}] rad"
        )
        raise PlanningError(msg)
    return yaw


def _rz(angle: float) -> FloatArray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _ry(angle: float) -> FloatArray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _align(R: FloatArray, axis: int, target: FloatArray) -> FloatArray:
    """``R`` rotated by the smallest rotation taking its column ``axis`` onto ``target``."""
    a = R[:, axis]
    b = target / np.linalg.norm(target)
    v = np.cross(a, b)
    c = float(a @ b)
    if np.linalg.norm(v) < 1e-9:
        if c > 0:
            return R.copy()
        perp = np.cross(a, [1.0, 0.0, 0.0] if abs(a[0]) < 0.9 else [0.0, 1.0, 0.0])
        perp /= np.linalg.norm(perp)
        K = np.array([[0, -perp[2], perp[1]], [perp[2], 0, -perp[0]], [-perp[1], perp[0], 0]])
        return (np.eye(3) + 2 * K @ K) @ R
    K = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    return (np.eye(3) + K + K @ K / (1 + c)) @ R


def line(start: FloatArray, end: FloatArray, step: float) -> list[FloatArray]:
    """Points from ``start`` (excluded) to ``end`` (included), at most ``step`` m apart."""
    start, end = np.asarray(start, dtype=np.float64), np.asarray(end, dtype=np.float64)
    n = max(1, math.ceil(float(np.linalg.norm(end - start)) / step - 1e-9))
    return [start + (end - start) * (i / n) for i in range(1, n + 1)]


class Operations:
    """Plans the paper's operations with an :class:`ArmPlanner`.

    Args:
        planner: the planner (and through it the model) to use.
    """

    def __init__(self, planner: ArmPlanner) -> None:
        self.planner = planner
        self.model = planner.model
        i = self.model.index("j_shou_yaw")
        self.yaw_limits = (float(self.model.lower[i]), float(self.model.upper[i]))

    # ------------------------------------------------------------------------- helpers
    def _ctx(
        self, q: FloatArray, terrain: HeightMap | None, tool: str | None = None
    ) -> CheckContext:
        """What states are checked against. In free space every arm link stays above the
        terrain; while a ``tool`` works in the ground, the tool end (hand, scoop, grinder) may
        go below the original surface into the trench, as in OceanWATERS, where only the scoop
        and the grinder touch the terrain and the hand never does."""
        tool_end = {tool, "l_hand", SCOOP_LINK, GRINDER_LINK} if tool else set()
        links = tuple(link for link in ARM_LINKS if link not in tool_end)
        return CheckContext(
            np.asarray(q, dtype=np.float64), terrain, links, self.planner.config.terrain_margin_m
        )

    def _reference(self, yaw: float, pose: tuple[float, ...]) -> FloatArray:
        return np.array([yaw, *pose])

    def _rotation(self, arm: FloatArray, q: FloatArray, frame: str) -> FloatArray:
        return self.model.fk(self.planner.full(arm, q), frame)[:3, :3]

    def _position(self, arm: FloatArray, q: FloatArray, frame: str) -> FloatArray:
        return self.model.fk(self.planner.full(arm, q), frame)[:3, 3]

    def _yaw(self, x: float, y: float) -> float:
        return shoulder_yaw_for(x, y, *self.yaw_limits)

    def _cartesian(
        self,
        start: FloatArray,
        frame: str,
        target: FloatArray,
        rotation_at: Any,
        ctx: CheckContext,
        partial: bool = False,
    ) -> FloatArray:
        """Straight line of ``frame`` from where it is to ``target``; orientation per point.
        With ``partial``, as far along it as the arm can go (see ArmPlanner.plan_cartesian)."""
        here = self._position(start, ctx.base, frame)
        points = line(here, target, self.planner.config.cartesian_step_m)
        return self.planner.plan_cartesian(
            start, frame, points, [rotation_at(p) for p in points], ctx, partial=partial
        )

    def _approach(
        self, start: FloatArray, goal: FloatArray, reference: FloatArray, ctx: CheckContext
    ) -> FloatArray:
        """Free-space path to ``goal``: direct, else through the operation's reference pose
        (as OceanWATERS' joint-space pre-configurations), else through the unstowed "safe"
        configuration (the paper's reason for having one), else RRT*. The path may end a whole
        turn of the hand or scoop yaw away from ``goal`` (the same pose): continue from its
        last row."""
        planner = self.planner
        # The hand and scoop yaw turn a full turn either way: the goal as solved (near the
        # operation's reference turn) or the same pose a whole turn nearer to where the joints
        # are now (after an earlier operation left the wrist a turn away).
        goals = [goal]
        near = planner.unwrap(goal, start)
        if not np.allclose(near, goal):
            goals.append(near)
        safe = np.array([UNSTOWED[j] for j in ARM_JOINTS])
        for end in goals:
            if planner.path_valid(np.vstack([start, end]), ctx):
                planner.stats.direct_segments += 1
                return np.vstack([start, end])
            for vias in ([reference], [safe, reference], [safe]):
                turned = [planner.unwrap(v, end) for v in vias]
                path = np.vstack([start, *turned, end])
                if all(planner.is_valid(v, ctx) for v in turned) and (
                    planner.path_valid(path, ctx)
                ):
                    planner.stats.direct_segments += len(vias) + 1
                    return path
        return planner.plan_free(start, goal, ctx)

    def _start(self, q: FloatArray, terrain: HeightMap | None) -> FloatArray:
        arm = self.planner.arm(q)
        ctx = self._ctx(q, terrain)
        if not self.planner.is_valid(arm, ctx):
            msg = f"the arm's current configuration is invalid: {self.planner.explain(arm, ctx)}"
            raise PlanningError(msg)
        return arm

    # ------------------------------------------------------------------------- operations
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
        planners = {
            "unstow": lambda q_: self.plan_unstow(q_, terrain),
            "stow": lambda q_: self.plan_stow(q_, terrain),
            "guarded_move": lambda q_: self.plan_guarded_move(q_, terrain, request or {}),
            "grind": lambda q_: self.plan_grind(q_, terrain, request or {}),
            "dig_circular": lambda q_: self.plan_dig_circular(q_, terrain, request or {}),
            "dig_linear": lambda q_: self.plan_dig_linear(q_, terrain, request or {}),
            "deliver_sample": lambda q_: self.plan_deliver_sample(q_, terrain, request or {}),
        }
        if name not in planners:
            msg = f"unknown operation {name!r}; known: {', '.join(planners)}"
            raise PlanningError(msg)
        lift = self._lift_off(q, terrain)
        if lift is None:
            return planners[name](q)
        plan = planners[name](self.planner.full(lift[-1], q))
        plan.segments.insert(0, PathSegment("lift_off", lift))
        plan.notes.append("started with a tool in the terrain: lifted it out first")
        return plan

    def _lift_off(self, q: FloatArray, terrain: HeightMap | None) -> FloatArray | None:
        """(n, 6) rad path lifting a tool off the terrain, or None when no tool is near it."""
        arm = self.planner.arm(q)
        tools = (SCOOP_LINK, GRINDER_LINK)
        if terrain is None:
            return None
        near = self.model.collision_report(q, terrain, tools, CONTACT_CLEARANCE)
        if near.terrain_link is None and self.planner.is_valid(arm, self._ctx(q, terrain)):
            return None
        ctx = CheckContext(
            np.asarray(q, dtype=np.float64),
            terrain,
            tuple(link for link in ARM_LINKS if link not in tools),
            self.planner.config.terrain_margin_m,
        )
        if not self.planner.is_valid(arm, ctx):
            msg = f"the arm's current configuration is invalid: {self.planner.explain(arm, ctx)}"
            raise PlanningError(msg)
        frame = SCOOP_TIP_FRAME if near.terrain_link == SCOOP_LINK else GRINDER_TIP_FRAME
        penetration = max(near.terrain_penetration - CONTACT_CLEARANCE, 0.0)
        here = self._position(arm, q, frame)
        rotation = self._rotation(arm, q, frame)
        target = here + np.array([0.0, 0.0, penetration + LIFT_OFF_CLEARANCE])
        try:
            path = self._cartesian(arm, frame, target, lambda _: rotation, ctx)
        except PlanningError as error:
            # E.g. after an execution stopped half-way the wrist may be folded so that a
            # straight lift makes the hand touch the distal link: raise the whole arm with the
            # shoulder pitch instead.
            path = self._shoulder_lift(arm, q, frame, target[2], ctx, error)
        if not self.planner.is_valid(path[-1], self._ctx(q, terrain)):
            end = self.planner.explain(path[-1], self._ctx(q, terrain))
            msg = f"lifting {near.terrain_link} off the terrain did not free the arm: {end}"
            raise PlanningError(msg)
        return path

    def _shoulder_lift(
        self,
        arm: FloatArray,
        q: FloatArray,
        frame: str,
        height: float,
        ctx: CheckContext,
        cartesian_error: PlanningError,
    ) -> FloatArray:
        """(n, 6) rad: the shoulder pitch alone turned (the way that raises ``frame``) until
        ``frame`` is at ``height`` m, every state valid in ``ctx``."""
        pitch = ARM_JOINTS.index("j_shou_pitch")
        lower, upper = self.planner.lower[pitch], self.planner.upper[pitch]
        start_z = self._position(arm, q, frame)[2]
        for sign in (1.0, -1.0):
            path = [arm]
            current = arm.copy()
            while lower <= current[pitch] + sign * 0.01 <= upper:
                current = current.copy()
                current[pitch] += sign * 0.01
                if not self.planner.is_valid(current, ctx):
                    break
                path.append(current)
                z = self._position(current, q, frame)[2]
                if z >= height:
                    return np.array(path)
                if z < start_z:
                    break  # this way lowers the tool
        msg = f"cannot lift the tool off the terrain: {cartesian_error}; nor with the shoulder"
        raise PlanningError(msg)

    def plan_unstow(self, q: FloatArray, terrain: HeightMap | None) -> OperationPlan:
        """Free-space motion to the unstowed ("safe") configuration."""
        return self._to_named("unstow", UNSTOWED, q, terrain)

    def plan_stow(self, q: FloatArray, terrain: HeightMap | None) -> OperationPlan:
        """Free-space motion to the stowed configuration."""
        return self._to_named("stow", STOWED, q, terrain)

    def _to_named(
        self, name: str, pose: Mapping[str, float], q: FloatArray, terrain: HeightMap | None
    ) -> OperationPlan:
        start = self._start(q, terrain)
        # The hand and scoop yaw turn freely (continuous in the original): reach the named
        # angle by the shorter way round from where the joint is.
        goal = self.planner.unwrap(np.array([pose[j] for j in ARM_JOINTS]), start)
        path = self.planner.plan_free(start, goal, self._ctx(q, terrain))
        return OperationPlan(name, [PathSegment(name, path)], {})

    def plan_guarded_move(
        self, q: FloatArray, terrain: HeightMap | None, request: Mapping[str, Any]
    ) -> OperationPlan:
        """Approach: the scoop tip to (x, y, z), its bottom turned against ``direction``; then
        the guarded descent: a straight line of ``search_distance`` along -direction."""
        p = effective_parameters("guarded_move", request)
        _finite(p, "x", "y", "z", "direction_x", "direction_y", "direction_z", "search_distance")
        normal = np.array([p["direction_x"], p["direction_y"], p["direction_z"]], dtype=float)
        if np.linalg.norm(normal) < 1e-6:
            msg = "direction=(0, 0, 0) is a zero vector; give the surface normal, e.g. (0, 0, 1)"
            raise PlanningError(msg)
        normal /= np.linalg.norm(normal)
        if p["search_distance"] <= 0:
            msg = f"search_distance={p['search_distance']:.3f} m must be > 0"
            raise PlanningError(msg)
        target = np.array([p["x"], p["y"], p["z"]], dtype=float)
        yaw = self._yaw(p["x"], p["y"])
        start = self._start(q, terrain)
        ctx = self._ctx(q, terrain)
        reference = self._reference(yaw, GUARDED_POSE)
        R0 = _align(self._rotation(reference, q, SCOOP_TIP_FRAME), 2, -normal)
        goal = self.planner.solve_ik(SCOOP_TIP_FRAME, target, R0, reference, ctx)
        approach = self._approach(start, goal, reference, ctx)
        dig = self._ctx(q, terrain, SCOOP_LINK)
        end = target - normal * float(p["search_distance"])
        # The search goes as deep as the arm can without the rest of it touching the terrain.
        descent = self._cartesian(
            approach[-1], SCOOP_TIP_FRAME, end, lambda _: R0, dig, partial=True
        )
        segments = [PathSegment("approach", approach), PathSegment("guarded", descent)]
        return OperationPlan("guarded_move", segments, p)

    def plan_grind(
        self, q: FloatArray, terrain: HeightMap | None, request: Mapping[str, Any]
    ) -> OperationPlan:
        """Two grinder passes of ``length`` at ``depth`` below the ground, grinder vertical."""
        p = effective_parameters("grind", request)
        _finite(p, "x", "y", "depth", "length", "ground_position")
        _depth(p["depth"], MAX_GRIND_DEPTH, "grinder")
        _length(p["length"])
        x, y, ground = float(p["x"]), float(p["y"]), float(p["ground_position"])
        yaw = self._yaw(x, y)
        heading = np.array([math.cos(yaw), math.sin(yaw), 0.0])
        right = np.array([math.sin(yaw), -math.cos(yaw), 0.0])
        direction = heading if p["parallel"] else right
        # The second pass is beside the first: to the left of a radial trench, further out from
        # the lander for a trench across the arm.
        shift = -right if p["parallel"] else heading
        bottom = ground - float(p["depth"])
        corners = [
            np.array([x, y, bottom]),
            np.array([x, y, bottom]) + direction * p["length"],
            np.array([x, y, bottom]) + direction * p["length"] + shift * GRIND_PASS_SHIFT,
            np.array([x, y, bottom]) + shift * GRIND_PASS_SHIFT,
        ]
        self._yaw(*corners[1][:2])
        self._yaw(*corners[2][:2])
        start = self._start(q, terrain)
        reference = self._reference(yaw, GRIND_POSE)
        R0 = self._rotation(reference, q, GRINDER_TIP_FRAME)

        def vertical(point: FloatArray) -> FloatArray:
            return _rz(self._yaw(point[0], point[1]) - yaw) @ R0

        above = corners[0] + [0.0, 0.0, APPROACH_HEIGHT + float(p["depth"])]
        ctx = self._ctx(q, terrain)
        dig = self._ctx(q, terrain, GRINDER_LINK)
        goal = self.planner.solve_ik(GRINDER_TIP_FRAME, above, R0, reference, ctx)
        segments = [PathSegment("approach", self._approach(start, goal, reference, ctx))]
        arm = segments[0].waypoints[-1]
        labels = ("descend", "pass_1", "shift", "pass_2")
        for label, corner in zip(labels, corners, strict=True):
            path = self._cartesian(arm, GRINDER_TIP_FRAME, corner, vertical, dig)
            segments.append(PathSegment(label, path))
            arm = path[-1]
        exit_point = corners[3] + [0.0, 0.0, APPROACH_HEIGHT + float(p["depth"])]
        path = self._cartesian(arm, GRINDER_TIP_FRAME, exit_point, vertical, dig)
        segments.append(PathSegment("retract", path))
        return OperationPlan("grind", segments, p)

    def plan_dig_linear(
        self, q: FloatArray, terrain: HeightMap | None, request: Mapping[str, Any]
    ) -> OperationPlan:
        """Rasping cut: the scoop dips in to ``depth``, cuts ``length`` radially, lifts out."""
        p = effective_parameters("dig_linear", request)
        _finite(p, "x", "y", "depth", "length", "ground_position")
        _depth(p["depth"], MAX_SCOOP_DEPTH, "scoop")
        _length(p["length"])
        x, y, ground = float(p["x"]), float(p["y"]), float(p["ground_position"])
        yaw = self._yaw(x, y)
        heading = np.array([math.cos(yaw), math.sin(yaw), 0.0])
        bottom = ground - float(p["depth"])
        cut_start = np.array([x, y, bottom])
        cut_end = cut_start + heading * p["length"]
        self._yaw(*cut_end[:2])
        start = self._start(q, terrain)
        errors = []
        for pitch in DIG_LINEAR_PITCHES:
            reference = self._reference(yaw, (math.pi / 2, -math.pi / 2, pitch, 0.0, math.pi / 2))
            try:
                segments = self._linear_cut(
                    q, terrain, start, reference, cut_start, cut_end, ground
                )
            except PlanningError as error:
                errors.append(str(error))
                continue
            p["scoop_pitch_deg"] = round(math.degrees(pitch))
            return OperationPlan("dig_linear", segments, p)
        msg = f"no scoop attitude can make this cut; with the preferred one: {errors[0]}"
        raise PlanningError(msg)

    def _linear_cut(
        self,
        q: FloatArray,
        terrain: HeightMap | None,
        start: FloatArray,
        reference: FloatArray,
        cut_start: FloatArray,
        cut_end: FloatArray,
        ground: float,
    ) -> list[PathSegment]:
        """Approach, lower, dip in, cut, lift out and retract, holding the scoop attitude of
        ``reference`` (turned with the shoulder yaw)."""
        yaw = float(reference[0])
        heading = np.array([math.cos(yaw), math.sin(yaw), 0.0])
        R0 = self._rotation(reference, q, SCOOP_TIP_FRAME)

        def level(point: FloatArray) -> FloatArray:
            return _rz(self._yaw(point[0], point[1]) - yaw) @ R0

        # Dip in and lift out at 45 degrees between 5 cm above the ground and the cut's depth.
        rise = ground + 0.05 - float(cut_start[2])
        entry = cut_start - heading * rise + [0.0, 0.0, rise]
        above = entry + np.array([0.0, 0.0, APPROACH_HEIGHT - 0.05])
        out = cut_end + heading * rise + [0.0, 0.0, rise]
        ctx = self._ctx(q, terrain)
        dig = self._ctx(q, terrain, SCOOP_LINK)
        goal = self.planner.solve_ik(SCOOP_TIP_FRAME, above, R0, reference, ctx)
        segments = [PathSegment("approach", self._approach(start, goal, reference, ctx))]
        arm = segments[0].waypoints[-1]
        steps = (
            ("lower", entry, ctx),
            ("dip_in", cut_start, dig),
            ("cut", cut_end, dig),
            ("lift_out", out, dig),
            ("retract", out + np.array([0.0, 0.0, APPROACH_HEIGHT - 0.05]), dig),
        )
        for label, point, check in steps:
            path = self._cartesian(arm, SCOOP_TIP_FRAME, point, level, check)
            segments.append(PathSegment(label, path))
            arm = path[-1]
        return segments

    def plan_dig_circular(
        self, q: FloatArray, terrain: HeightMap | None, request: Mapping[str, Any]
    ) -> OperationPlan:
        """A 120 degree scoop sweep whose lowest point is at (x, y, ground - depth): about the
        wrist (distal pitch) when parallel, about the hand (hand yaw) when perpendicular."""
        p = effective_parameters("dig_circular", request)
        _finite(p, "x", "y", "depth", "ground_position")
        _depth(p["depth"], MAX_SCOOP_DEPTH, "scoop")
        x, y, ground = float(p["x"]), float(p["y"]), float(p["ground_position"])
        yaw = self._yaw(x, y)
        parallel = bool(p["parallel"])
        joint = ARM_JOINTS.index("j_dist_pitch" if parallel else "j_hand_yaw")
        reference = self._reference(
            yaw, CIRCULAR_PARALLEL_POSE if parallel else CIRCULAR_PERPENDICULAR_POSE
        )
        # Centre the sweep on the scoop tip's lowest point, turning the way its mouth faces.
        angles = np.linspace(-math.pi, math.pi, 361)
        lowest, sign = self._lowest(reference, q, joint, angles)
        reference[joint] += lowest - sign * CIRCULAR_SWEEP / 2
        reference_aimed = reference.copy()
        target = np.array([x, y, ground - float(p["depth"])])
        start = self._start(q, terrain)
        ctx = self._ctx(q, terrain)
        dig = self._ctx(q, terrain, SCOOP_LINK)
        sweep = sign * np.linspace(0.0, CIRCULAR_SWEEP, 121)
        R_hand = self._rotation(reference, q, "l_hand")
        hand = self._position(reference, q, "l_hand")
        arm = reference
        for _ in range(4):
            tips = []
            for a in sweep:
                swept = arm.copy()
                swept[joint] += a
                tips.append(self._position(swept, q, SCOOP_TIP_FRAME))
            deepest = min(tips, key=lambda t: t[2])
            error = target - deepest
            if np.linalg.norm(error) < 5e-4:
                break
            hand = hand + error
            R = _rz(self._yaw(hand[0], hand[1]) - yaw) @ R_hand
            arm = self.planner.solve_ik("l_hand", hand, R, arm, ctx)
        else:
            msg = f"cannot place the sweep's lowest point at ({x:.3f}, {y:.3f}, {target[2]:.3f}) m"
            raise PlanningError(msg)
        approach = self._approach(start, arm, reference_aimed, ctx)
        arm = approach[-1]
        end = arm.copy()
        end[joint] += sweep[-1]
        swept = self.planner.plan_joint_sweep(arm, end, dig)
        segments = [PathSegment("approach", approach), PathSegment("sweep", swept)]
        return OperationPlan("dig_circular", segments, p)

    def _lowest(
        self, reference: FloatArray, q: FloatArray, joint: int, angles: FloatArray
    ) -> tuple[float, float]:
        """(offset of ``joint`` putting the scoop tip lowest, direction of turning that moves
        the tip the way the scoop's mouth faces there)."""
        best = (np.inf, 0.0)
        for a in angles:
            arm = reference.copy()
            arm[joint] += a
            best = min(best, (float(self._position(arm, q, SCOOP_TIP_FRAME)[2]), float(a)))
        arm = reference.copy()
        arm[joint] += best[1]
        ahead = arm.copy()
        ahead[joint] += 1e-3
        velocity = self._position(ahead, q, SCOOP_TIP_FRAME) - self._position(
            arm, q, SCOOP_TIP_FRAME
        )
        mouth = self._rotation(arm, q, SCOOP_TIP_FRAME)[:, 0]
        return best[1], 1.0 if float(velocity @ mouth) >= 0 else -1.0

    def plan_deliver_sample(
        self, q: FloatArray, terrain: HeightMap | None, request: Mapping[str, Any]
    ) -> OperationPlan:
        """Carry the scoop upright to the pour point, then tip it to pour: over the sample dock
        (use_defaults) or at (x, y, z) to discard."""
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
        _finite(p, "x", "y", "z")
        point = np.array([p["x"], p["y"], p["z"]], dtype=float)
        start = self._start(q, terrain)
        ctx = self._ctx(q, terrain)
        heading = math.atan2(point[1] - SHOULDER_XY[1], point[0] - SHOULDER_XY[0])
        errors = []
        goals = []
        # The scoop's heading over the pour point is free: the first heading (in order of
        # preference) that straight joint moves reach and tip is taken; a sampled path (RRT*)
        # only when no heading has one.
        for phi in (0.0, heading, math.pi - math.pi / 4, -math.pi / 4, math.pi / 2, -math.pi / 2):
            x_axis = np.array([math.cos(phi), math.sin(phi), 0.0])
            z_axis = np.array([0.0, 0.0, -1.0])
            carry_R = np.column_stack([x_axis, np.cross(z_axis, x_axis), z_axis])
            pour_R = carry_R @ _ry(-POUR_TILT)
            try:
                carry = self.planner.solve_ik(SCOOP_TIP_FRAME, point, carry_R, start, ctx)
                pour = self.planner.solve_ik(SCOOP_TIP_FRAME, point, pour_R, carry, ctx)
            except PlanningError as error:
                errors.append(str(error))
                continue
            # The tip first: a heading whose pour needs a detour is usually refuted there.
            tip = self.planner.plan_straight(carry, pour, ctx)
            approach = None if tip is None else self.planner.plan_straight(start, carry, ctx)
            if approach is not None and tip is not None:
                return self._delivery(approach, tip, p)
            goals.append((carry, pour))
        for carry, pour in goals:
            try:
                approach = self.planner.plan_free(start, carry, ctx)
                tip = self.planner.plan_free(carry, pour, ctx)
            except PlanningError as error:
                errors.append(str(error))
                continue
            return self._delivery(approach, tip, p)
        msg = f"no way to pour at ({point[0]:.3f}, {point[1]:.3f}, {point[2]:.3f}) m: {errors[0]}"
        raise PlanningError(msg)

    @staticmethod
    def _delivery(approach: FloatArray, tip: FloatArray, p: dict[str, Any]) -> OperationPlan:
        segments = [PathSegment("approach", approach), PathSegment("pour", tip)]
        return OperationPlan("deliver_sample", segments, p)
