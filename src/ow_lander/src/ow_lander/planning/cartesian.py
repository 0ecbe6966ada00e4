"""Planning in a tool frame's Cartesian space: IK goals on the seed's kinematic branch, and
Cartesian lines (IK every waypoint, seeded by the previous solution). No ROS.

States are arm vectors ``arm: (6,) rad`` (see :mod:`ow_lander.planning.validity`); points are in
base_link, m.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

from ow_description.description import ARM_JOINTS
from ow_description.errors import IKError
from ow_lander.config import PlannerConfig
from ow_lander.errors import PlanningError
from ow_lander.planning.stats import PlanStats
from ow_lander.planning.validity import CheckContext, StateChecker, densify, segment_steps

FloatArray = npt.NDArray[np.float64]

#: IK targets whose random-restart outcome a planner keeps (the oldest are dropped together).
RESTART_OUTCOMES_KEPT = 256


class CartesianPlanner:
    """IK goals and Cartesian lines of a tool frame (not thread-safe, like the model).

    Args:
        checker: state and path validity (and the model whose IK is used).
        config: planner settings (joint resolution, IK restarts, jump limit, seed).
        stats: counts of the owning planner, to which the Cartesian waypoints are added.
    """

    def __init__(self, checker: StateChecker, config: PlannerConfig, stats: PlanStats) -> None:
        self.checker = checker
        self.model = checker.model
        self.config = config
        self.stats = stats
        self._restart_outcomes: dict[
            tuple[str, bytes, bytes | None, bytes], FloatArray | IKError
        ] = {}
        self._branch_solutions: dict[tuple[str, bytes, bytes | None, bytes], list[FloatArray]] = {}

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
        previous one), so the solution keeps the seed's elbow and wrist branch; one IK from the
        seed and then seeded random restarts (``ik_restarts``) are the fallback. When that
        solution collides, the other branches the random restarts find are tried, the nearest
        to the seed first (as MoveIt samples its IK for a valid goal state).

        Raises:
            PlanningError: unreachable, or every solution found collides (with the reason).
        """
        checker = self.checker
        target = np.asarray(position, dtype=np.float64)
        arm = self._ik_continuation(frame, target, rotation, seed_arm, ctx)
        if arm is None:
            try:
                q = self._ik_anywhere(frame, target, rotation, seed_arm, ctx.base)
            except IKError as error:
                raise PlanningError(str(error)) from error
            arm = checker.unwrap(checker.arm(q), seed_arm)
        if checker.is_valid(arm, ctx):
            return arm
        for other in self._branches(frame, target, rotation, seed_arm, ctx.base):
            if checker.is_valid(other, ctx):
                return other
        msg = (
            f"placing {frame} at ({target[0]:.3f}, {target[1]:.3f}, {target[2]:.3f}) m is not "
            f"possible without a collision: {checker.explain(arm, ctx)}"
        )
        raise PlanningError(msg)

    def _branches(
        self,
        frame: str,
        target: FloatArray,
        rotation: FloatArray | None,
        seed_arm: FloatArray,
        base: FloatArray,
    ) -> list[FloatArray]:
        """(6,) rad, the distinct IK solutions of the target from seeded random starts, each
        continuous joint at the turn nearest ``seed_arm``, nearest to ``seed_arm`` first. They
        do not depend on ``seed_arm``'s arm joints until sorted, so they are kept per target as
        :meth:`_restarted`'s outcomes are."""
        checker = self.checker
        key = self._key(frame, target, rotation, checker.full(seed_arm, base))
        found = self._branch_solutions.get(key)
        if found is None:
            found = self.model.ik_solutions(
                frame,
                target,
                checker.full(seed_arm, base),
                rotation=rotation,
                joints=ARM_JOINTS,
                restarts=self.config.ik_restarts,
                seed=self.config.seed,
            )
            if len(self._branch_solutions) >= RESTART_OUTCOMES_KEPT:
                self._branch_solutions.clear()
            self._branch_solutions[key] = found
        arms = [checker.unwrap(checker.arm(q), seed_arm) for q in found]
        return sorted(arms, key=lambda arm: float(np.abs(arm - seed_arm).sum()))

    def _ik_continuation(
        self,
        frame: str,
        target: FloatArray,
        rotation: FloatArray | None,
        seed_arm: FloatArray,
        ctx: CheckContext,
    ) -> FloatArray | None:
        checker = self.checker
        here = self.model.fk(checker.full(seed_arm, ctx.base), frame)
        n = max(1, int(np.ceil(np.linalg.norm(target - here[:3, 3]) / 0.05)))
        arm = np.asarray(seed_arm, dtype=np.float64)
        for i in range(1, n + 1):
            point = here[:3, 3] + (target - here[:3, 3]) * (i / n)
            try:
                q = self.model.ik(
                    frame,
                    point,
                    checker.full(arm, ctx.base),
                    rotation=rotation,
                    joints=ARM_JOINTS,
                    restarts=0,
                    max_iterations=100,
                )
            except IKError:
                return None
            arm = checker.unwrap(checker.arm(q), arm)
        return arm

    def _ik_anywhere(
        self,
        frame: str,
        target: FloatArray,
        rotation: FloatArray | None,
        seed_arm: FloatArray,
        base: FloatArray,
    ) -> FloatArray:
        """(9,) rad, IK jumping from ``seed_arm`` straight to the target, else from seeded
        random starts (:meth:`_restarted`); the joints IK does not move keep ``base``'s values.

        Raises:
            IKError: no start converged.
        """
        q0 = self.checker.full(seed_arm, base)
        try:
            return self.model.ik(
                frame, target, q0, rotation=rotation, joints=ARM_JOINTS, restarts=0
            )
        except IKError:
            pass
        found = self._restarted(frame, target, rotation, q0)
        if isinstance(found, IKError):
            raise IKError(str(found))
        idx = self.checker.idx
        q0[idx] = found[idx]
        return q0

    def prepare(
        self, frame: str, position: FloatArray, rotation: FloatArray | None, base: FloatArray
    ) -> None:
        """Work out the random-restart IK of a target ahead of the requests that may need it
        (what :meth:`solve_ik` falls back to), so that none of them pays for it: the answers
        are the same with or without (see :meth:`_restarted`).

        Args:
            frame: frame to place.
            position: (3,) m, in base_link.
            rotation: (3, 3) in base_link, or None for the position alone.
            base: (9,) rad, the configuration of the joints IK does not move.
        """
        target = np.asarray(position, dtype=np.float64)
        self._restarted(frame, target, rotation, np.array(base, dtype=np.float64))

    def _restarted(
        self, frame: str, target: FloatArray, rotation: FloatArray | None, q0: FloatArray
    ) -> FloatArray | IKError:
        """The outcome of IK from seeded random starts only: a (9,) rad solution (its arm
        joints are what matters) or the error. It does not depend on ``q0``'s arm joints (every
        start replaces them) nor on joints off ``frame``'s chain (the grinder's spin, the
        antenna), so it is kept per target and the values of the chain's other joints: a
        repeated target costs nothing and gives the answer it gave the first time. (The dock's
        pour poses are on an elbow branch no continuation reaches, and are asked for on every
        delivery.)"""
        key = self._key(frame, target, rotation, q0)
        found = self._restart_outcomes.get(key)
        if found is None:
            try:
                found = self.model.ik(
                    frame,
                    target,
                    q0,
                    rotation=rotation,
                    joints=ARM_JOINTS,
                    restarts=self.config.ik_restarts,
                    seed=self.config.seed,
                    try_q0=False,
                )
            except IKError as error:
                found = error
            if len(self._restart_outcomes) >= RESTART_OUTCOMES_KEPT:
                self._restart_outcomes.clear()
            self._restart_outcomes[key] = found
        return found

    def _key(
        self, frame: str, target: FloatArray, rotation: FloatArray | None, q0: FloatArray
    ) -> tuple[str, bytes, bytes | None, bytes]:
        """What a random-restart IK outcome depends on: the frame, the target and the values
        of the joints on the frame's chain that IK does not move (``q0`` (9,) rad)."""
        fixed = np.setdiff1d(self.model.chain_columns(frame), self.checker.idx)
        return (
            frame,
            target.tobytes(),
            None if rotation is None else np.asarray(rotation, dtype=np.float64).tobytes(),
            q0[fixed].tobytes(),
        )

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
        checker = self.checker
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
                guess = np.clip(3 * previous - 3 * out[-2] + out[-3], checker.lower, checker.upper)
            elif len(out) > 2:
                guess = np.clip(2 * previous - out[-2], checker.lower, checker.upper)
            try:
                q = self.model.ik(
                    frame,
                    np.asarray(position, dtype=np.float64),
                    checker.full(guess, ctx.base),
                    rotation=rotation,
                    joints=ARM_JOINTS,
                    restarts=0,
                    max_iterations=100,
                )
            except IKError as error:
                failure = (k, "breaks", error)
                break
            arm = checker.unwrap(checker.arm(q), previous)
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
        bad = checker.first_invalid_index(states, ctx)
        if bad is not None:
            # The waypoint whose step holds the invalid state (state 0 is the start).
            ends = np.cumsum(segment_steps(path, self.config.joint_resolution_rad))
            k = int(np.searchsorted(ends, bad))
            failure = (k, "is blocked", PlanningError(checker.explain(states[bad], ctx)))
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
