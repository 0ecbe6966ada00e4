"""The motions every arm operation is made of, and the geometry they share. No ROS.

:class:`ArmMotions` wraps an :class:`~ow_lander.planning.planner.ArmPlanner` with the vocabulary of
the operations (:mod:`ow_lander.operations.planner`, :mod:`ow_lander.operations.ground`): where the
plan starts, the free-space approach, straight lines of a tool frame, lifting a tool out of the
terrain. Arm configurations ``arm`` are (6,) rad in ARM_JOINTS order; ``q`` is the full (9,) rad
configuration (pinocchio order) giving the joints the arm does not move. Points are in base_link, m.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import numpy.typing as npt

from ow_description.collision import ARM_LINKS
from ow_description.description import (
    ARM_JOINTS,
    GRINDER_LINK,
    GRINDER_TIP_FRAME,
    SCOOP_LINK,
    SCOOP_TIP_FRAME,
    UNSTOWED,
)
from ow_description.terrain import HeightMap
from ow_lander.errors import PlanningError
from ow_lander.operations.workspace import shoulder_yaw_for
from ow_lander.planning.planner import ArmPlanner
from ow_lander.planning.validity import CheckContext, densify

FloatArray = npt.NDArray[np.float64]

#: m, clearance above the terrain a tool is lifted to when an operation starts in contact (above
#: the depth of the link deepest in the terrain).
LIFT_OFF_CLEARANCE = 0.10
#: Straight down in base_link: the scoop tip frame's z when the scoop is level (its bottom down,
#: its mouth up: it keeps what it holds, docs/regolith.md).
DOWN = np.array([0.0, 0.0, -1.0])
#: rad, how far inside the travel of a continuous joint an approach ends when it can (a whole
#: turn further from where the joint is, if need be): room for the operation's own turns.
TURN_HEADROOM_RAD = math.pi
#: m, a tool closer than this to the terrain at the start of an operation is lifted off first
#: (it may sit in a dent it made, whose walls the next motion would scrape).
CONTACT_CLEARANCE = 0.02


def rz(angle: float) -> FloatArray:
    """(3, 3) rotation by ``angle`` rad about z."""
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def ry(angle: float) -> FloatArray:
    """(3, 3) rotation by ``angle`` rad about y."""
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def align(R: FloatArray, axis: int, target: FloatArray) -> FloatArray:
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


def turned(R_from: FloatArray, R_to: FloatArray, fraction: float) -> FloatArray:
    """``R_from`` (3, 3) turned by ``fraction`` (0 to 1) of the rotation taking it onto ``R_to``
    (3, 3), about that rotation's fixed axis: the orientations between two, evenly spaced."""
    relative = R_to @ R_from.T
    cos_angle = min(1.0, max(-1.0, (float(np.trace(relative)) - 1.0) / 2.0))
    angle = math.acos(cos_angle)
    if angle < 1e-9:
        return R_from.copy()
    axis = np.array(
        [
            relative[2, 1] - relative[1, 2],
            relative[0, 2] - relative[2, 0],
            relative[1, 0] - relative[0, 1],
        ]
    )
    if np.linalg.norm(axis) < 1e-9:  # a half turn: the axis is the eigenvector of eigenvalue 1
        values, vectors = np.linalg.eigh(relative + relative.T)
        axis = vectors[:, int(np.argmax(values))]
    axis = axis / np.linalg.norm(axis)
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    a = fraction * angle
    return (np.eye(3) + math.sin(a) * K + (1.0 - math.cos(a)) * K @ K) @ R_from


def angle_between(R_a: FloatArray, R_b: FloatArray) -> float:
    """rad, the angle of the rotation taking orientation ``R_a`` (3, 3) onto ``R_b``."""
    cos_angle = (float(np.trace(R_b @ R_a.T)) - 1.0) / 2.0
    return math.acos(min(1.0, max(-1.0, cos_angle)))


def line(start: FloatArray, end: FloatArray, step: float) -> list[FloatArray]:
    """Points from ``start`` (excluded) to ``end`` (included), at most ``step`` m apart."""
    start, end = np.asarray(start, dtype=np.float64), np.asarray(end, dtype=np.float64)
    n = max(1, math.ceil(float(np.linalg.norm(end - start)) / step - 1e-9))
    return [start + (end - start) * (i / n) for i in range(1, n + 1)]


#: rad, the largest turn of a tool between two waypoints of a Cartesian path that turns it.
TURN_STEP_RAD = 0.05

#: rad, how far past its first collision-free state an escape from a contact goes.
ESCAPE_MARGIN_RAD = 0.05


class ArmMotions:
    """The motions operations are planned from, with an :class:`ArmPlanner`.

    Args:
        planner: the planner (and through it the model) to use.
    """

    def __init__(self, planner: ArmPlanner) -> None:
        self.planner = planner
        self.model = planner.model
        i = self.model.index("j_shou_yaw")
        self.yaw_limits = (float(self.model.lower[i]), float(self.model.upper[i]))

    def context(
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

    @staticmethod
    def reference(yaw: float, pose: tuple[float, ...]) -> FloatArray:
        """(6,) rad, a reference pose (shoulder pitch ... scoop yaw) aimed by shoulder ``yaw``."""
        return np.array([yaw, *pose])

    def rotation(self, arm: FloatArray, q: FloatArray, frame: str) -> FloatArray:
        """(3, 3), orientation of ``frame`` in base_link with the arm at ``arm``."""
        return self.model.fk(self.planner.full(arm, q), frame)[:3, :3]

    def position(self, arm: FloatArray, q: FloatArray, frame: str) -> FloatArray:
        """(3,) m, position of ``frame`` in base_link with the arm at ``arm``."""
        return self.model.fk(self.planner.full(arm, q), frame)[:3, 3]

    def yaw(self, x: float, y: float) -> float:
        """rad, the shoulder yaw aiming the arm at (x, y) m (see :func:`shoulder_yaw_for`)."""
        return shoulder_yaw_for(x, y, *self.yaw_limits)

    def cartesian(
        self,
        start: FloatArray,
        frame: str,
        target: FloatArray,
        rotation_at: Callable[[FloatArray], FloatArray],
        ctx: CheckContext,
        partial: bool = False,
    ) -> FloatArray:
        """Straight line of ``frame`` from where it is to ``target``; orientation per point.
        With ``partial``, as far along it as the arm can go (see ArmPlanner.plan_cartesian)."""
        here = self.position(start, ctx.base, frame)
        points = line(here, target, self.planner.config.cartesian_step_m)
        return self.planner.plan_cartesian(
            start, frame, points, [rotation_at(p) for p in points], ctx, partial=partial
        )

    def approach(
        self, start: FloatArray, goal: FloatArray, reference: FloatArray, ctx: CheckContext
    ) -> FloatArray:
        """Free-space path to ``goal``: direct, else through the operation's reference pose
        (as OceanWATERS' joint-space pre-configurations), else through the unstowed "safe"
        configuration (the paper's reason for having one), else staged straight moves (directly
        or through that configuration, see ArmPlanner.plan_straight), else RRT*. The path may
        end a whole turn of the hand or scoop yaw away from ``goal`` (the same pose): continue
        from its last row."""
        planner = self.planner
        # The hand and scoop yaw turn a full turn either way: first the same pose a whole turn
        # nearer to where the joints are now (after an earlier operation left the wrist a turn
        # away), then the goal as solved (near the operation's reference turn).
        # Not so near that the operation after the approach (a sweep of the hand, a grind's
        # turns) would run into the end of the simulated joint's travel: repeated operations
        # wind the wrist up a turn at a time.
        goals = [goal]
        near = planner.unwrap(goal, start, headroom=TURN_HEADROOM_RAD)
        if not np.allclose(near, goal):
            goals.insert(0, near)
        safe = planner.safe
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
        # Staged straight moves (directly or through the safe pose) before a sampled path.
        for end in goals:
            straight = planner.plan_straight(start, end, ctx)
            if straight is not None:
                return straight
        return planner.plan_free(start, goal, ctx)

    def level_route(self, start: FloatArray, goal: FloatArray, ctx: CheckContext) -> FloatArray:
        """(n, 6) rad: straight joint moves from ``start`` to ``goal`` that keep the scoop's
        attitude as level as their ends: the direct move, else the shoulder and scoop yaws
        first, else the three pitches first.

        The scoop is level (mouth up) when the hand yaw is a whole number of turns and the
        three pitches sum to zero (the distal link horizontal, the hand below it), or at the
        half turn and pi; both conditions are linear in the joints, so a straight move between
        two level poses of the same family keeps the scoop level all the way, and so do these
        staged moves (each leg keeps the pitches, or moves them together).

        Raises:
            PlanningError: none of them is valid (the direct move's reason).
        """
        planner = self.planner
        pitches = [ARM_JOINTS.index(j) for j in ("j_shou_pitch", "j_prox_pitch", "j_dist_pitch")]
        yaws_first = goal.copy()
        yaws_first[pitches] = start[pitches]
        pitches_first = start.copy()
        pitches_first[pitches] = goal[pitches]
        for vias in ((), (yaws_first,), (pitches_first,)):
            path = np.vstack([start, *vias, goal])
            if planner.path_valid(path, ctx):
                planner.stats.direct_segments += len(path) - 1
                return path
        blocked = planner.first_invalid(np.vstack([start, goal]), ctx)
        reason = "" if blocked is None else f": {planner.explain(blocked, ctx)}"
        msg = f"no straight joint move keeps the scoop level to the goal{reason}"
        raise PlanningError(msg)

    def start(self, q: FloatArray, terrain: HeightMap | None) -> FloatArray:
        """(6,) rad, the arm joints of ``q``, where every plan starts (after :meth:`escape` and
        :meth:`lift_off`, which take the arm out of a contact).

        Raises:
            PlanningError: that configuration is invalid (the message says why).
        """
        arm = self.planner.arm(q)
        ctx = self.context(q, terrain)
        if not self.planner.is_valid(arm, ctx):
            msg = f"the arm's current configuration is invalid: {self.planner.explain(arm, ctx)}"
            raise PlanningError(msg)
        return arm

    def leaving(
        self, q: FloatArray, terrain: HeightMap | None, tools: bool = False
    ) -> tuple[CheckContext, dict[str, float]]:
        """The context of a move out of the terrain from ``q``, and how deep each link is in it.

        A link in the terrain at ``q`` (a burial, a dig or a guarded move stopped deep) may stay
        in it on the way out; every other link must stay above it; with ``tools`` the scoop and
        the grinder may touch it too (they are lifted off it).

        Returns:
            (the context, link -> m its deepest point is below the terrain, 0 when above).
        """
        depths = dict.fromkeys(ARM_LINKS, 0.0)
        if terrain is not None:
            contact = self.model.collision.terrain_contact
            depths = {link: contact(q, terrain, (link,))[1] for link in ARM_LINKS}
        free = {SCOOP_LINK, GRINDER_LINK} if tools else set()
        links = tuple(link for link in ARM_LINKS if link not in free and not depths[link] > 0.0)
        ctx = CheckContext(
            np.asarray(q, dtype=np.float64), terrain, links, self.planner.config.terrain_margin_m
        )
        return ctx, depths

    def escape(self, q: FloatArray, terrain: HeightMap | None) -> FloatArray | None:
        """(2, 6) rad, a straight move out of a configuration in which the arm touches the
        lander or itself, or None when it touches neither (or a joint is beyond its limits).

        The simulation has no arm-lander contacts, so a set-point beyond where the planner's
        model lets the arm go leaves the arm inside the lander's collision model (the shoulder
        yaw driven onto its -1.8 rad limit puts l_prox in the body), and no plan may start in
        collision. The escape follows the straight joint-space line towards the unstowed pose
        to ``ESCAPE_MARGIN_RAD`` past its first collision-free state; from that state on the
        line is checked against the terrain too, but for the links already in it (lifted out
        next, :meth:`lift_off`).

        Raises:
            PlanningError: no collision-free state on that line, or the terrain blocks it.
        """
        arm = self.planner.arm(q)
        body = self.context(q, None)
        if not self.planner.within_limits(arm) or self.planner.is_valid(arm, body):
            return None  # beyond a joint limit is no contact: refused with its reason later
        resolution = self.planner.config.joint_resolution_rad
        goal = np.array([UNSTOWED[j] for j in ARM_JOINTS])
        states = densify(np.vstack([arm, goal]), resolution)
        free = next((i for i, s in enumerate(states) if self.planner.is_valid(s, body)), None)
        if free is None:
            msg = (
                "the arm's current configuration is invalid and no straight move towards the "
                f"unstowed pose frees it: {self.planner.explain(arm, body)}"
            )
            raise PlanningError(msg)
        end = states[min(free + math.ceil(ESCAPE_MARGIN_RAD / resolution), len(states) - 1)]
        ctx, _ = self.leaving(q, terrain)
        blocked = self.planner.first_invalid(np.vstack([states[free], end]), ctx)
        if blocked is not None:
            msg = (
                "the arm's current configuration touches the lander and the move out of it is "
                f"blocked: {self.planner.explain(blocked, ctx)}"
            )
            raise PlanningError(msg)
        return np.vstack([arm, end])

    def lift_off(self, q: FloatArray, terrain: HeightMap | None) -> FloatArray | None:
        """(n, 6) rad path lifting the arm out of the terrain, or None when it is clear of it.

        A start in the terrain is a start: a tool within ``CONTACT_CLEARANCE`` of the terrain
        (or in it), or any link in it (buried, or left there by a dig or guarded move that
        stopped deep), is lifted with the tool tip straight up, its orientation kept, to
        ``LIFT_OFF_CLEARANCE`` above the depth of the deepest link; when the straight line is
        blocked, by the shoulder pitch alone. On the way out the links in the terrain at the
        start may stay in it, the others must stay above it (:meth:`leaving`); at the end every
        link is above it.

        Raises:
            PlanningError: the arm touches the lander or itself there, or cannot be freed.
        """
        if terrain is None:
            return None
        arm = self.planner.arm(q)
        tools = (SCOOP_LINK, GRINDER_LINK)
        near_link, _ = self.model.collision.terrain_contact(q, terrain, tools, CONTACT_CLEARANCE)
        if near_link is None and self.planner.is_valid(arm, self.context(q, terrain)):
            return None
        ctx, depths = self.leaving(q, terrain, tools=True)
        if not self.planner.is_valid(arm, ctx):
            msg = f"the arm's current configuration is invalid: {self.planner.explain(arm, ctx)}"
            raise PlanningError(msg)
        deepest = max(ARM_LINKS, key=lambda link: depths[link])
        stuck = near_link if depths[deepest] <= 0.0 else deepest
        frame = GRINDER_TIP_FRAME if stuck == GRINDER_LINK else SCOOP_TIP_FRAME
        here = self.position(arm, q, frame)
        rotation = self.rotation(arm, q, frame)
        height = float(here[2]) + depths[deepest] + LIFT_OFF_CLEARANCE
        full = self.context(q, terrain)
        try:
            path = self.cartesian(
                arm, frame, np.array([here[0], here[1], height]), lambda _: rotation, ctx
            )
        except PlanningError as error:
            # E.g. after an execution stopped half-way the wrist may be folded so that a
            # straight lift makes the hand touch the distal link: raise the whole arm with the
            # shoulder pitch instead.
            path, blocked = arm[None, :], f"a straight lift is blocked ({error})"
        else:
            blocked = "a straight lift leaves it in the terrain"
        if self.planner.is_valid(path[-1], full):
            return path
        # Still in the terrain (the elbow of a deep burial): the shoulder pitch raises the rest.
        raised = self._shoulder_lift(path[-1], q, frame, height, ctx, full)
        if raised is None:
            msg = (
                f"cannot lift {stuck} out of the terrain: {blocked}, and turning the shoulder "
                f"pitch does not free it ({self.planner.explain(path[-1], full)})"
            )
            raise PlanningError(msg)
        return np.vstack([path, raised[1:]])

    def _shoulder_lift(
        self,
        arm: FloatArray,
        q: FloatArray,
        frame: str,
        height: float,
        ctx: CheckContext,
        full: CheckContext,
    ) -> FloatArray | None:
        """(n, 6) rad from ``arm``: the shoulder pitch alone turned (the way that raises
        ``frame``) until ``frame`` is at ``height`` m and the arm is valid in ``full``, every
        state valid in ``ctx``; None when neither way gets there."""
        pitch = ARM_JOINTS.index("j_shou_pitch")
        lower, upper = self.planner.lower[pitch], self.planner.upper[pitch]
        start_z = self.position(arm, q, frame)[2]
        for sign in (1.0, -1.0):
            path = [arm]
            current = arm.copy()
            while lower <= current[pitch] + sign * 0.01 <= upper:
                current = current.copy()
                current[pitch] += sign * 0.01
                if not self.planner.is_valid(current, ctx):
                    break
                path.append(current)
                z = self.position(current, q, frame)[2]
                if z >= height and self.planner.is_valid(current, full):
                    return np.array(path)
                if z < start_z:
                    break  # this way lowers the tool
        return None
