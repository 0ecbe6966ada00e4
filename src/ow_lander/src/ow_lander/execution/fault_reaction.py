"""How the arm and the antenna mast react to OceanWATERS' fault telemetry, free of ROS.

:class:`FaultReaction` is told the fault bitmasks (``/system_faults_status``,
``/arm_faults_status``, ``/pan_tilt_faults_status``) and the injector's behaviour parameters and
locked joints (``/faults/changes``), and answers:

* :meth:`FaultReaction.stop_reason`: why a running arm execution must stop now (an arm execution
  error while ``arm_motion_continues_in_fault`` is false; whatever that parameter says, no force
  data while the execution's guard watches the wrist F/T sensor), or None;
* :meth:`FaultReaction.refusal`: why a new goal or request of an action group is refused now (its
  goal error stands while ``auto_clear_goal_errors`` is false; for the arm groups, the stop reason
  of an execution that would watch the F/T sensor), or None;
* :meth:`FaultReaction.pan_tilt_error`: why a pan/tilt goal fails now (a locked antenna joint).

The bit values are owl_msgs' (``tests/unit/ow_lander/test_fault_reaction.py`` checks them against
the generated messages); this module imports no message.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field, replace
from typing import Any

from ow_description.description import ANTENNA_JOINTS
from ow_faults.protocol import LOCK_SUFFIX
from ow_lander.operations.registry import OPERATIONS

#: owl_msgs/SystemFaultsStatus bits read here.
ARM_GOAL_ERROR = 2
ARM_EXECUTION_ERROR = 4
TASK_GOAL_ERROR = 8
PAN_TILT_GOAL_ERROR = 64
PAN_TILT_EXECUTION_ERROR = 128
#: owl_msgs/ArmFaultsStatus bits read here.
HARDWARE = 1
NO_FORCE_DATA = 128
#: owl_msgs/PanTiltFaultsStatus bits.
PAN_JOINT_LOCKED = 1
TILT_JOINT_LOCKED = 2

#: The goal-error bit and name of each action group.
GOAL_ERRORS = {
    "arm": (ARM_GOAL_ERROR, "ARM_GOAL_ERROR"),
    "task": (TASK_GOAL_ERROR, "TASK_GOAL_ERROR"),
    "pan_tilt": (PAN_TILT_GOAL_ERROR, "PAN_TILT_GOAL_ERROR"),
}
#: The paper's services that move the arm without a task (the others are tasks): the arm
#: operations, and publish_trajectory (which plays a trajectory file).
ARM_SERVICES = frozenset(
    {*(spec.name for spec in OPERATIONS.values() if spec.group == "arm"), "publish_trajectory"}
)


def group_of(name: str) -> str:
    """The action group of an action (``TaskGrind`` -> task, ``PanTiltMoveJoints`` -> pan_tilt,
    ``ArmUnstow`` -> arm) or of a paper service (``grind`` -> task, ``unstow`` -> arm)."""
    if name.startswith("Task"):
        return "task"
    if name.startswith("PanTilt"):
        return "pan_tilt"
    if name.startswith("Arm") or name in ARM_SERVICES:
        return "arm"
    return "task"


def watches_force(name: str, ground_detector: str) -> bool:
    """Whether action or service ``name`` detects contact with the wrist F/T sensor (the
    guarded actions; ``guarded_move`` with the force ground detector)."""
    guarded = name == "ArmFindSurface" or name.endswith("Guarded")
    return guarded or (name == "guarded_move" and ground_detector == "force")


@dataclass
class FaultReaction:
    """The fault telemetry and behaviour parameters now (defaults: no fault, OceanWATERS'
    behaviour: the arm stops in a fault, a new goal clears its group's goal error).

    Attributes:
        system: SystemFaultsStatus bitmask.
        arm: ArmFaultsStatus bitmask.
        pan_tilt: PanTiltFaultsStatus bitmask.
        motion_continues: ``arm_motion_continues_in_fault``.
        auto_clear: ``auto_clear_goal_errors``.
        locked: the joints whose lock is injected (URDF names).
    """

    system: int = 0
    arm: int = 0
    pan_tilt: int = 0
    motion_continues: bool = False
    auto_clear: bool = True
    locked: frozenset[str] = field(default_factory=frozenset)

    def on_parameters(self, values: Mapping[str, Any]) -> None:
        """The ``/faults`` server's configuration (parameter -> value; others ignored)."""
        self.motion_continues = bool(
            values.get("arm_motion_continues_in_fault", self.motion_continues)
        )
        self.auto_clear = bool(values.get("auto_clear_goal_errors", self.auto_clear))
        self.locked = frozenset(
            f"j_{name[: -len(LOCK_SUFFIX)]}"
            for name, value in values.items()
            if name.endswith(LOCK_SUFFIX) and value is True
        )

    def arm_error(self) -> str | None:
        """The arm execution error standing, described with its faults and joints, or None
        (also while the arm's status, published just before the system's, has not arrived)."""
        if not self.system & ARM_EXECUTION_ERROR or not self.arm:
            return None
        causes = []
        if self.arm & HARDWARE:
            joints = sorted(self.locked - set(ANTENNA_JOINTS))
            what = " and ".join(joints) if joints else "a joint"
            causes.append(f"{what} locked (HARDWARE)")
        if self.arm & NO_FORCE_DATA:
            causes.append("no force data from the wrist F/T sensor (NO_FORCE_DATA)")
        if not causes:
            causes.append(f"arm faults {self.arm:#x}")
        return "arm execution error: " + "; ".join(causes)

    def with_locked(self, locked: Iterable[str]) -> FaultReaction:
        """This reaction once the detector reports arm joints of ``locked`` (URDF names, e.g.
        the simulation's flags) as HARDWARE, with the arm execution error it raises."""
        arm_locked = frozenset(locked) - set(ANTENNA_JOINTS)
        if not arm_locked:
            return self
        return replace(
            self,
            system=self.system | ARM_EXECUTION_ERROR,
            arm=self.arm | HARDWARE,
            locked=self.locked | arm_locked,
        )

    def stop_reason(self, watches_force: bool) -> str | None:
        """Why an arm execution must stop now, or None. ``watches_force``: its guard reads the
        wrist F/T sensor (a guarded action, the force ground detector)."""
        error = self.arm_error()
        if error is None:
            return None
        if not self.motion_continues:
            return f"{error} (arm_motion_continues_in_fault is false)"
        if watches_force and self.arm & NO_FORCE_DATA:
            return f"{error}: contact cannot be detected"
        return None

    def refusal(self, group: str, watches_force: bool = False) -> str | None:
        """Why a new goal or request of ``group`` ("arm", "task", "pan_tilt") is refused now,
        or None."""
        bit, name = GOAL_ERRORS[group]
        if self.system & bit and not self.auto_clear:
            # OceanWATERS' text, then what stands.
            return (
                f"Action group, {group.upper()}, is faulted. Use the FaultClear action to make "
                f"the group operable again. ({name} stands and auto_clear_goal_errors is false; "
                f"fault: {bit})"
            )
        if group == "pan_tilt":
            return self.pan_tilt_error()
        return self.stop_reason(watches_force)

    def pan_tilt_error(self) -> str | None:
        """The pan/tilt execution error standing (a locked antenna joint), or None."""
        if not self.system & PAN_TILT_EXECUTION_ERROR or not self.pan_tilt:
            return None
        bits = ((PAN_JOINT_LOCKED, "PAN_JOINT_LOCKED"), (TILT_JOINT_LOCKED, "TILT_JOINT_LOCKED"))
        causes = [
            f"{joint} locked ({name})"
            for joint, (bit, name) in zip(ANTENNA_JOINTS, bits, strict=True)
            if self.pan_tilt & bit
        ]
        return "pan/tilt execution error: " + "; ".join(causes or [f"faults {self.pan_tilt}"])
