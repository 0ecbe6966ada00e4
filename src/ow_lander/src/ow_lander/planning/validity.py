"""Validity of arm states and joint-space paths for the planner: joint limits and collisions with
self, lander body, dock and terrain, paths checked state by state at a joint resolution. No ROS.

A measured start state a hair beyond a joint limit (a joint resting on its hard stop) is planned
from as if on the limit: :meth:`StateChecker.arm` clamps joints at most
:data:`START_LIMIT_TOLERANCE_RAD` beyond a limit onto it before any validity check.

States are arm vectors ``arm: (6,) rad`` in :data:`~ow_description.description.ARM_JOINTS` order;
the other joints (grinder, antenna) keep the values of a base configuration ``base: (9,)`` in
pinocchio order (see :mod:`ow_description.model`).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ow_description.batch_check import BatchTerrainCheck
from ow_description.collision import ARM_LINKS
from ow_description.description import ARM_JOINTS
from ow_description.model import LanderModel
from ow_description.terrain import HeightMap

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]

#: rad, how far beyond a joint limit a measured configuration may lie and still be planned from,
#: as if on the limit. A joint driven onto its hard stop rests on it or a hair beyond (the
#: simulator's limit constraint is soft, a real encoder reads noise); refusing that state would
#: leave the arm unable to move ever again. Anything further beyond is a real violation.
START_LIMIT_TOLERANCE_RAD = 0.05

#: States of a segment a yes/no path check looks at first (coarse to fine) before the rest: most
#: blocked motions show within them, and a batch of terrain checks costs its set-up per call.
COARSE_STATES = 16


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


def densify(waypoints: FloatArray, resolution: float) -> FloatArray:
    """(m, k) states along the polyline ``waypoints`` (n, k) with no joint step above
    ``resolution`` rad; every waypoint is kept."""
    points = np.asarray(waypoints, dtype=np.float64)
    steps = np.array(segment_steps(points, resolution), dtype=np.intp)
    if not len(steps):
        return points[:1].copy()
    # State i of segment s is points[s] + (i / n_s) * (points[s + 1] - points[s]), i = 1..n_s.
    segment = np.repeat(np.arange(len(steps)), steps)
    first = np.cumsum(steps) - steps
    fraction = (np.arange(len(segment)) - first[segment] + 1) / steps[segment]
    delta = points[1:] - points[:-1]
    out = points[segment] + fraction[:, None] * delta[segment]
    return np.concatenate([points[:1], out])


def segment_steps(waypoints: FloatArray, resolution: float) -> list[int]:
    """How many states :func:`densify` puts on each segment of ``waypoints`` (n, k)."""
    largest = np.abs(np.diff(waypoints, axis=0)).max(axis=1, initial=0.0)
    return np.maximum(1, np.ceil(largest / resolution - 1e-9)).astype(np.intp).tolist()


def _coarse_to_fine(n: int) -> npt.NDArray[np.intp]:
    """The indices 0..n-1 in bisection order: 0, then the multiples of the largest power of two
    below n, then the odd multiples of each smaller power of two in turn."""
    index = np.arange(n)
    # The largest power of two dividing each index (index 0 first of all).
    lowest_bit = np.where(index == 0, n + 1, index & -index)
    return np.argsort(-lowest_bit, kind="stable")


class StateChecker:
    """Arm states of one :class:`LanderModel`: to and from full configurations, joint limits,
    and the validity of states and paths (not thread-safe, like the model).

    Args:
        model: kinematics and collision model.
        resolution: rad, joint step at which paths are checked unless told otherwise.
    """

    def __init__(self, model: LanderModel, resolution: float) -> None:
        self.model = model
        self.resolution = resolution
        self.idx = model.arm_idx
        self.lower = model.lower[self.idx].copy()
        self.upper = model.upper[self.idx].copy()
        self._lower_tol = self.lower - 1e-9
        self._upper_tol = self.upper + 1e-9
        self._terrain_check = BatchTerrainCheck(model.model, model.collision)
        self._verdict_ctx: CheckContext | None = None
        self._verdicts: dict[tuple[bytes, bytes, float], bool] = {}
        #: (index, lower, upper) of the joints whose range spans a full turn.
        self._full_turn = [
            (j, float(self.lower[j]), float(self.upper[j]))
            for j in np.flatnonzero(self.upper - self.lower >= 2 * np.pi - 1e-6)
        ]

    def full(self, arm: FloatArray, base: FloatArray) -> FloatArray:
        """(9,) rad configuration: ``base`` with the arm joints set to ``arm`` (6,)."""
        q = np.array(base, dtype=np.float64)
        q[self.idx] = arm
        return q

    def arm(self, q: FloatArray) -> FloatArray:
        """(6,) rad arm joints of a (9,) configuration (e.g. the measured one every plan starts
        from), each joint at most :data:`START_LIMIT_TOLERANCE_RAD` beyond a limit put on the
        limit (see :meth:`onto_limits`)."""
        return self.onto_limits(np.asarray(q, dtype=np.float64)[self.idx])

    def onto_limits(self, arm: FloatArray) -> FloatArray:
        """A copy of ``arm`` (6,) rad with each joint that lies beyond a limit by at most
        :data:`START_LIMIT_TOLERANCE_RAD` moved onto that limit; joints further beyond are kept
        (the state stays invalid, and :meth:`explain` names them)."""
        out = np.array(arm, dtype=np.float64)
        clipped = np.minimum(np.maximum(out, self.lower), self.upper)
        near = np.abs(out - clipped) <= START_LIMIT_TOLERANCE_RAD + 1e-9
        out[near] = clipped[near]
        return out

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
        # A continuous joint holds any angle, but the simulated joint turns only so far.
        for j, lower, upper in self._full_turn:
            if not lower - 1e-9 <= arm[j] <= upper + 1e-9:
                problems.append(
                    f"{ARM_JOINTS[j]}={arm[j]:.3f} rad is beyond the joint's travel "
                    f"[{lower:.3f}, {upper:.3f}]"
                )
        report = self.model.collision_report(q, ctx.terrain, ctx.terrain_links, ctx.terrain_margin)
        if report.in_collision:
            problems.append(report.describe())
        return "; ".join(problems) or "valid"

    def first_invalid(
        self, waypoints: FloatArray, ctx: CheckContext, resolution: float | None = None
    ) -> FloatArray | None:
        """The first invalid state along the polyline at ``resolution`` rad (default: the
        checker's own), or None when the whole path is valid."""
        states = densify(waypoints, resolution or self.resolution)
        index = self.first_invalid_index(states, ctx)
        return None if index is None else states[index]

    def path_valid(
        self, waypoints: FloatArray, ctx: CheckContext, resolution: float | None = None
    ) -> bool:
        """True when every state along the polyline at ``resolution`` rad (default: the
        checker's own) is valid: the states of :meth:`first_invalid`. Segment by segment, each
        segment's limits and terrain at once, then its contacts coarse to fine, so that a
        blocked motion is usually rejected after a few checks. A segment's verdict is kept
        while ``ctx`` is the context asked about (a plan tries the same legs, e.g. to the
        unstowed pose, in several combinations)."""
        resolution = resolution or self.resolution
        points = np.asarray(waypoints, dtype=np.float64)
        verdicts = self._verdicts_in(ctx)
        for a, b in itertools.pairwise(points):
            key = (a.tobytes(), b.tobytes(), resolution)
            valid = verdicts.get(key)
            if valid is None:
                valid = self._segment_valid(densify(np.vstack([a, b]), resolution), ctx)
                verdicts[key] = valid
            if not valid:
                return False
        return len(points) > 1 or self.first_invalid_index(points, ctx) is None

    def _segment_valid(self, states: FloatArray, ctx: CheckContext) -> bool:
        """True when every row of ``states`` (m, 6) rad is valid: the first
        :data:`COARSE_STATES` of them in coarse-to-fine order (where a blocked motion usually
        shows), then the rest, each part's limits and terrain at once, then its contacts."""
        ordered = states[_coarse_to_fine(len(states))]
        for part in (ordered[:COARSE_STATES], ordered[COARSE_STATES:]):
            if not len(part):
                continue
            if self._limit_or_terrain_invalid(part, ctx).any():
                return False
            if self._first_contact(part, ctx, len(part)) is not None:
                return False
        return True

    def _verdicts_in(self, ctx: CheckContext) -> dict[tuple[bytes, bytes, float], bool]:
        """The segment verdicts kept for ``ctx`` (those of any other context are dropped)."""
        if self._verdict_ctx is not ctx:
            self._verdict_ctx = ctx
            self._verdicts = {}
        return self._verdicts

    def first_invalid_index(self, states: FloatArray, ctx: CheckContext) -> int | None:
        """The index of the first invalid row of ``states`` (m, 6) rad, or None."""
        bad = np.flatnonzero(self._limit_or_terrain_invalid(states, ctx))
        end = int(bad[0]) if len(bad) else len(states)
        contact = self._first_contact(states, ctx, end)
        if contact is not None:
            return contact
        return end if len(bad) else None

    def _limit_or_terrain_invalid(self, states: FloatArray, ctx: CheckContext) -> BoolArray:
        """(m,) True where a row of ``states`` (m, 6) rad is beyond a joint limit or has a
        checked link below the terrain (all rows at once)."""
        states = np.asarray(states, dtype=np.float64)
        bad = ~np.all((states >= self._lower_tol) & (states <= self._upper_tol), axis=1)
        if ctx.terrain is not None and len(states):
            Q = np.tile(np.asarray(ctx.base, dtype=np.float64), (len(states), 1))
            Q[:, self.idx] = states
            bad |= self._terrain_check.below(Q, ctx.terrain, ctx.terrain_links, ctx.terrain_margin)
        return bad

    def _first_contact(self, states: FloatArray, ctx: CheckContext, end: int) -> int | None:
        """The index of the first of the rows ``states[:end]`` (6,) rad where links touch each
        other, the lander body or the dock, or None."""
        Q = np.tile(np.asarray(ctx.base, dtype=np.float64), (end, 1))
        Q[:, self.idx] = states[:end]
        touches = self.model.collision.touches
        for i, q in enumerate(Q):
            if touches(q):
                return i
        return None

    def unwrap(self, arm: FloatArray, reference: FloatArray, headroom: float = 0.0) -> FloatArray:
        """``arm`` with each full-turn joint moved by whole turns to the value closest to
        ``reference`` that stays within its limits, and ``headroom`` rad inside them when a
        value that close exists (room for the motion that follows: a sweep of the hand from
        there must not run into the end of the simulated joint's travel)."""
        out = np.array(arm, dtype=np.float64)
        for j, lower, upper in self._full_turn:
            value = float(out[j])
            turns = round((float(reference[j]) - value) / (2 * math.pi))
            candidates = [value + 2 * math.pi * k for k in (turns, turns - 1, turns + 1)]
            inside = [c for c in candidates if lower <= c <= upper]
            roomy = [c for c in inside if lower + headroom <= c <= upper - headroom]
            if roomy or inside:
                out[j] = (roomy or inside)[0]
        return out
