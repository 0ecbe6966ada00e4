"""How an OceanWATERS action ends (HEAD's states and texts), free of ROS.

:func:`execution_outcome` decides, from an execution's :class:`ExecutionResult` and where the
arm stands at its end, whether the goal SUCCEEDED, was ABORTED or PREEMPTED, with OceanWATERS'
status text; :func:`breach_text` and :func:`success_text` are those texts. The rules
(OceanWATERS ``actions.py``, ``mixins.py``, ``arm_interface.py``):

* a guarded action (ArmMoveJointsGuarded, ArmMoveCartesianGuarded, ArmFindSurface) stopped by
  its force or torque threshold SUCCEEDED ("... trajectory stopped by a force of F N");
  one that reached its target without a breach SUCCEEDED too ("... completed without
  breaching ..."; ArmFindSurface: "No surface was found"); one that neither breached nor reached
  its target is ABORTED with :data:`NO_THRESHOLD_BREACH`;
* a move that ends away from its target is ABORTED ("Failed to reach intended pose", "Arm
  joints failed to reach intended target angles");
* ArmStop ends the running goal ABORTED (:data:`STOP_BEFORE_EXECUTION`,
  :data:`STOP_DURING_EXECUTION`); a cancel (which OceanWATERS ignores) ends it PREEMPTED.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np

from ow_lander.actions.owl import (
    CARTESIAN_TOLERANCE,
    ActionRequest,
    ArmState,
    angles_reached,
    pose_error,
)
from ow_lander.execution.monitor import ExecutionResult

#: ArmStop's texts.
ARM_STOPPED = "Arm trajectory stopped"
NOTHING_TO_STOP = "No arm trajectory to stop"
#: The texts of a goal that ArmStop ended before and during its execution.
STOP_BEFORE_EXECUTION = "Stop was called; trajectory will not be executed"
STOP_DURING_EXECUTION = "Stop was called; trajectory execution ceased"
#: A guarded action that neither tripped a threshold nor reached its target.
NO_THRESHOLD_BREACH = (
    "Arm failed to reach pose despite neither force nor torque thresholds being breached. "
    "Likely the thresholds were set too high or a planning error occurred. Try a lower threshold."
)
#: ArmFindSurface's end of its approach without a breach.
NO_SURFACE = "No surface was found"
#: ArmFindSurface's suffixes of a failure before and during its approach.
SETUP_FAILED = " - Setup trajectory failed"
APPROACH_FAILED = " - Surface approach trajectory failed"

Status = Literal["succeeded", "aborted", "preempted"]


@dataclass(frozen=True)
class Outcome:
    """How a goal ends.

    Attributes:
        status: "succeeded", "aborted" or "preempted".
        text: the goal's status text.
        before_approach: ArmFindSurface ended before its approach began (its result's distance,
            force and torque are then 0, as OceanWATERS reports them).
    """

    status: Status
    text: str
    before_approach: bool = False


def success_text(action: str) -> str:
    """The status text of an action that did what it was asked (no guard involved)."""
    if action.startswith("ArmMoveJoint"):
        return "Arm joints moved successfully"
    return f"{action} trajectory succeeded"


def breaches(force: float, torque: float, limits: tuple[float, float]) -> tuple[bool, bool]:
    """(force, torque): which threshold of ``limits`` (N, N m) the magnitudes ``force`` N and
    ``torque`` N m reach (OceanWATERS: ``>=``)."""
    return force >= limits[0], torque >= limits[1]


def unbreached_text(action: str) -> str:
    """The status text of a guarded action that reached its target without a breach."""
    return f"{action} trajectory completed without breaching force or torque thresholds"


def breach_text(action: str, force: float, torque: float, limits: tuple[float, float]) -> str:
    """OceanWATERS' text of a guarded action whose force ``force`` N and torque ``torque``
    N m are compared with ``limits`` (N, N m): what stopped it, or that nothing did."""
    by_force, by_torque = breaches(force, torque, limits)
    if not (by_force or by_torque):
        return unbreached_text(action)
    parts = [f"a force of {force:.2f} N"] if by_force else []
    parts += [f"a torque of {torque:.2f} Nm"] if by_torque else []
    return f"{action} trajectory stopped by {' and '.join(parts)}"


def surface_text(
    action: str, force: float, torque: float, request: ActionRequest, tip: np.ndarray
) -> str:
    """ArmFindSurface's text when a threshold stopped it with the scoop tip at ``tip`` (3,)."""
    assert request.wrench_limits is not None
    found = breach_text(action, force, torque, request.wrench_limits)
    return f"{found}. Surface found at ({tip[0]:.3f}, {tip[1]:.3f}, {tip[2]:.3f})"


class SurfaceApproach:
    """ArmFindSurface's progress during its execution: its approach begins once the scoop is
    at its setup pose (its tip within 0.01 m of the setup point, its bottom within 0.05 rad of
    facing against the normal; on the way there the tip may pass the point turned otherwise);
    before, OceanWATERS reports a distance, force and torque of 0.

    Args:
        request: the goal's request (its ``setup_point`` and ``surface_normal``).
    """

    def __init__(self, request: ActionRequest) -> None:
        assert request.setup_point is not None and request.surface_normal is not None
        self.setup_point = request.setup_point
        self.normal = request.surface_normal
        self.begun = False

    def update(self, X_base_tip: np.ndarray) -> None:
        """Take the scoop tip's pose (4, 4), base_link, of the latest joint state."""
        if not self.begun:
            gap = float(np.linalg.norm(X_base_tip[:3, 3] - self.setup_point))
            facing = float(-X_base_tip[:3, 2] @ self.normal)
            linear, angular = CARTESIAN_TOLERANCE
            self.begun = gap <= linear and facing >= math.cos(angular)


def execution_outcome(
    action: str,
    request: ActionRequest,
    result: ExecutionResult,
    state: ArmState,
    stop_called: bool,
    in_approach: bool = True,
) -> Outcome:
    """How the goal of ``action`` ends after executing ``request``: ``result`` of the
    execution, ``state`` where the arm stands (or is held) now, ``stop_called`` whether ArmStop
    was called during the goal; ``in_approach``: ArmFindSurface's execution had reached its
    approach (a failure before is its setup's)."""
    finding = action == "ArmFindSurface"
    suffix = (APPROACH_FAILED if in_approach else SETUP_FAILED) if finding else ""
    if result.fault is not None:
        return Outcome("aborted", result.message + suffix, finding and not in_approach)
    if result.stopped:
        if stop_called:
            text = STOP_DURING_EXECUTION + suffix
            return Outcome("aborted", text, finding and not in_approach)
        return Outcome("preempted", f"Action was preempted: {result.message}")
    limits = request.wrench_limits
    if limits is not None and request.breaches_at_once:
        return _at_once(action, request, result, state)
    if limits is not None and result.wrench is not None:  # a threshold stopped it
        force, torque = result.wrench
        if finding:
            return Outcome(
                "succeeded", surface_text(action, force, torque, request, state.X_base_tip[:3, 3])
            )
        return Outcome("succeeded", breach_text(action, force, torque, limits))
    unbreached = finding and result.reports_ground and not result.ground_found
    if not result.success and not unbreached:
        # The arm did not get there (a tracking error, a timeout): OceanWATERS' controllers
        # report no error, its end check fails; with our reason.
        if finding and not in_approach:
            return Outcome("aborted", f"Failed to reach setup pose. ({result.message})", True)
        return Outcome("aborted", f"{_missed_text(action, request)} ({result.message})")
    missed = _missed_target(request, state)
    if limits is not None:
        if missed is not None:
            return Outcome("aborted", f"{NO_THRESHOLD_BREACH} ({missed})")
        if finding:
            return Outcome("succeeded", NO_SURFACE)
        return Outcome("succeeded", unbreached_text(action))
    if missed is not None:
        return Outcome("aborted", f"{_missed_text(action, request)} ({missed})")
    return Outcome("succeeded", success_text(action))


def _at_once(
    action: str, request: ActionRequest, result: ExecutionResult, state: ArmState
) -> Outcome:
    """A guard that trips at its first check: the motion did not move (ArmFindSurface moved
    to its setup pose only); what it reports is the wrist reading now."""
    assert request.wrench_limits is not None
    if action != "ArmFindSurface":
        return Outcome(
            "succeeded", breach_text(action, state.force, state.torque, request.wrench_limits)
        )
    if not result.success:
        return Outcome("aborted", result.message + SETUP_FAILED, before_approach=True)
    assert request.setup_point is not None
    gap = float(np.linalg.norm(state.X_base_tip[:3, 3] - request.setup_point))
    if gap > CARTESIAN_TOLERANCE[0]:
        return Outcome(
            "aborted", f"Failed to reach setup pose. (the scoop tip is {gap:.4f} m from it)", True
        )
    tip = state.X_base_tip[:3, 3]
    return Outcome("succeeded", surface_text(action, state.force, state.torque, request, tip))


def _missed_text(action: str, request: ActionRequest) -> str:
    """OceanWATERS' text of a motion that did not end at its target (a task's failure has
    none: its own reason is the text)."""
    if request.wrench_limits is not None:
        return NO_THRESHOLD_BREACH
    if request.target_angles is not None:
        return "Arm joints failed to reach intended target angles"
    if request.target_pose is not None:
        return "Failed to reach intended pose"
    return f"{action} failed"


def _missed_target(request: ActionRequest, state: ArmState) -> str | None:
    """How the arm at ``state`` misses the target the request must end at, or None when it is
    there (OceanWATERS' tolerances: 0.05 rad a joint, 0.01 m and 0.05 rad a pose)."""
    linear, angular = CARTESIAN_TOLERANCE
    if request.target_angles is not None and not angles_reached(
        request.target_angles, state.angles
    ):
        error = np.abs((state.angles - request.target_angles + math.pi) % (2 * math.pi) - math.pi)
        return f"largest joint error {float(error.max()):.3f} rad, tolerance 0.05 rad"
    if request.target_pose is not None:
        distance, angle = pose_error(request.target_pose, state.X_base_tip)
        if distance > linear or angle > angular:
            return (
                f"the tool ended {distance:.4f} m and {angle:.4f} rad from the target "
                f"(tolerance {linear} m, {angular} rad)"
            )
    if request.approach_end is not None and request.surface_normal is not None:
        distance = float(np.linalg.norm(state.X_base_tip[:3, 3] - request.approach_end))
        bottom = state.X_base_tip[:3, 2]
        tilt = math.acos(max(-1.0, min(1.0, float(-bottom @ request.surface_normal))))
        if distance > linear or tilt > angular:
            return (
                f"the scoop tip ended {distance:.4f} m from the end of the approach and its "
                f"bottom {tilt:.4f} rad from facing against the normal (tolerance {linear} m, "
                f"{angular} rad)"
            )
    return None
