"""OceanWATERS' fault detection rules (spec section 6.3), free of ROS: inputs in, bitmasks out.

:class:`FaultDetector` keeps the five status bitmasks of owl_msgs (bit values from the messages'
own constants) and updates them from what it is told:

============================  ==================================================  ===========
bit                           rule                                                source
============================  ==================================================  ===========
ArmFaultsStatus.HARDWARE      an arm joint flagged in ``/flags/joint_states``     flags (sim)
ArmFaultsStatus.NO_FORCE_DATA the F/T sensor's zero-signal fault is injected, or  injector /
                              no F/T reading for :data:`FT_TIMEOUT_S` of sim time observed
                              (flags stamped that long after the last reading,
                              and that long of flags arrived since it)
PanTilt PAN/TILT_JOINT_LOCKED j_ant_pan / j_ant_tilt flagged                      flags (sim)
Power LOW_STATE_OF_CHARGE     SOC <= :data:`LOW_SOC`                              observed
Power INSTANTANEOUS_CAP._LOSS |dSOC| / SOC_prev >= :data:`CAPACITY_LOSS` between  observed
                              consecutive SOC messages
Power THERMAL_FAULT           battery temperature >= :data:`THERMAL_C`            observed
Camera NO_IMAGE               a left trigger while the previous one still awaits  observed
                              its left image; a left image clears it
System ARM/CAMERA/PAN_TILT/   the subsystem's status is not 0                     derived
POWER_EXECUTION_ERROR
System ARM/TASK/CAMERA/       a goal of that action group was aborted; a later    observed
PAN_TILT_GOAL_ERROR           goal clears it when ``auto_clear_goal_errors``,
                              FaultClear clears it always
============================  ==================================================  ===========

The simulated F/T sensor is ideal: with nothing touching the tools it reads exactly zero, so a
signal stuck at zero cannot be told from a quiet one; NO_FORCE_DATA comes from the injector.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from ow_faults.errors import FaultError
from ow_faults.injection import ANTENNA_LOCKS, ARM_LOCKS, FaultSet
from owl_msgs.msg import ArmFaultsStatus, CameraFaultsStatus, PanTiltFaultsStatus, PowerFaultsStatus
from owl_msgs.msg import SystemFaultsStatus as System

#: OceanWATERS' detection thresholds: SOC at or below, relative SOC drop between two messages at
#: or above, battery temperature (degrees C) at or above.
LOW_SOC = 0.1
CAPACITY_LOSS = 0.05
THERMAL_C = 70.0
#: s of simulation time without an F/T reading (while joint flags arrive) that is NO_FORCE_DATA:
#: a sensor that stopped publishing. Long, because the two topics arrive on their own
#: connections: at 0.5 s a loaded machine delayed the readings enough to stop a mission's dig
#: with a false NO_FORCE_DATA (make test, load ~8); 30 s of sim is 0.75 s of wall time at 40x.
FT_TIMEOUT_S = 30.0


#: The action groups whose aborted goals are goal errors, with their bit.
def cleared_text(fault: int) -> str:
    """FaultClear's status text once goal error ``fault`` is cleared (OceanWATERS': "ARM goal
    faults have been cleared.")."""
    group = next(g for g, v in GOAL_ERRORS.items() if v == fault)
    return f"{group.upper()} goal faults have been cleared."


GOAL_ERRORS = {
    "arm": System.ARM_GOAL_ERROR,
    "task": System.TASK_GOAL_ERROR,
    "camera": System.CAMERA_GOAL_ERROR,
    "pan_tilt": System.PAN_TILT_GOAL_ERROR,
}
#: actionlib_msgs/GoalStatus values read here.
_PENDING, _ACTIVE, _ABORTED = 0, 1, 4

_ARM_JOINTS = frozenset(f"j_{j}" for j in ARM_LOCKS)
_PAN, _TILT = (f"j_{j}" for j in ANTENNA_LOCKS)


def action_group(action: str) -> str | None:
    """The goal-error group of an action name (``ArmUnstow`` -> arm), or None."""
    if action.startswith("Task"):
        return "task"
    if action.startswith("PanTilt"):
        return "pan_tilt"
    if action.startswith("Camera"):
        return "camera"
    if action.startswith("Arm"):
        return "arm"
    return None


@dataclass(frozen=True)
class FaultStatus:
    """The five bitmasks (owl_msgs ``value`` fields)."""

    arm: int = 0
    pan_tilt: int = 0
    power: int = 0
    system: int = 0
    camera: int = 0


class FaultDetector:
    """The detection rules' state; every ``on_*`` returns whether a bitmask changed."""

    def __init__(self) -> None:
        self._arm_hw = 0
        self._pan_tilt = 0
        self._power = 0
        self._goal_errors = 0
        self._injected_no_force = False
        self._last_ft_s: float | None = None
        self._flags_since_ft_s: float | None = None
        self._stale_ft = False
        self._soc: float | None = None
        self._camera = 0
        self._camera_pending = False
        self._faults = FaultSet()
        self._seen: dict[str, tuple[str, int]] = {}
        self._status = FaultStatus()

    @property
    def status(self) -> FaultStatus:
        """The bitmasks now."""
        return self._status

    def on_joint_flags(self, names: Sequence[str], flags: Sequence[bool], stamp_s: float) -> bool:
        """``/flags/joint_states`` at ``stamp_s`` s (also the clock of the F/T timeout)."""
        locked = {n for n, f in zip(names, flags, strict=True) if f}
        self._arm_hw = ArmFaultsStatus.HARDWARE if locked & _ARM_JOINTS else 0
        self._pan_tilt = (PanTiltFaultsStatus.PAN_JOINT_LOCKED if _PAN in locked else 0) | (
            PanTiltFaultsStatus.TILT_JOINT_LOCKED if _TILT in locked else 0
        )
        if self._last_ft_s is None:
            self._last_ft_s = stamp_s
        if self._flags_since_ft_s is None:
            self._flags_since_ft_s = stamp_s
        # Silent in stamps and in arrival order: the two topics arrive on threads of their own,
        # and a detector lagging a fast simulation may see flags stamped well after the newest
        # reading it has processed while readings are still on their way.
        self._stale_ft = (
            stamp_s - self._last_ft_s > FT_TIMEOUT_S
            and stamp_s - self._flags_since_ft_s > FT_TIMEOUT_S
        )
        return self._update()

    def on_wrist(self, stamp_s: float) -> bool:
        """An F/T reading at ``stamp_s`` s."""
        self._last_ft_s = stamp_s
        self._flags_since_ft_s = None
        self._stale_ft = False
        return self._update()

    def on_injected(self, faults: FaultSet) -> bool:
        """The injected faults (for NO_FORCE_DATA and ``auto_clear_goal_errors``)."""
        self._faults = faults
        self._injected_no_force = faults.enable and faults.zero_signal_failure
        return self._update()

    def on_soc(self, soc: float) -> bool:
        """A state of charge (0-1) message."""
        bits = self._power & ~(
            PowerFaultsStatus.LOW_STATE_OF_CHARGE | PowerFaultsStatus.INSTANTANEOUS_CAPACITY_LOSS
        )
        if soc <= LOW_SOC:
            bits |= PowerFaultsStatus.LOW_STATE_OF_CHARGE
        previous = self._soc
        if (
            previous is not None
            and previous > 0.0
            and abs(soc - previous) / previous >= CAPACITY_LOSS
        ):
            bits |= PowerFaultsStatus.INSTANTANEOUS_CAPACITY_LOSS
        self._soc = soc
        self._power = bits
        return self._update()

    def on_temperature(self, temperature_c: float) -> bool:
        """A battery temperature (degrees C) message."""
        bits = self._power & ~PowerFaultsStatus.THERMAL_FAULT
        if temperature_c >= THERMAL_C:
            bits |= PowerFaultsStatus.THERMAL_FAULT
        self._power = bits
        return self._update()

    def on_camera_trigger(self) -> bool:
        """A trigger of the left camera: NO_IMAGE when the previous trigger's left image has not
        arrived (so the first failed capture is not flagged, the second one is: OceanWATERS')."""
        if self._camera_pending:
            self._camera = CameraFaultsStatus.NO_IMAGE
        self._camera_pending = True
        return self._update()

    def on_camera_image(self) -> bool:
        """A left camera image: the trigger is answered, NO_IMAGE cleared."""
        self._camera = 0
        self._camera_pending = False
        return self._update()

    def on_goal_status(self, action: str, goal_id: str, status: int) -> bool:
        """The newest goal of ``action`` has ``status`` (actionlib_msgs/GoalStatus); only a
        change of goal or status counts (status arrays repeat)."""
        group = action_group(action)
        if group is None or self._seen.get(action) == (goal_id, status):
            return False
        self._seen[action] = (goal_id, status)
        bit = GOAL_ERRORS[group]
        if status == _ABORTED:
            self._goal_errors |= bit
        elif status in (_PENDING, _ACTIVE) and self._faults.auto_clear_goal_errors:
            self._goal_errors &= ~bit
        return self._update()

    def clear(self, fault: int) -> bool:
        """FaultClear: clear goal error ``fault`` (a *_GOAL_ERROR value).

        Raises:
            FaultError: ``fault`` is not one of the goal-error values.
        """
        values = sorted(GOAL_ERRORS.values())
        if fault not in values:
            # OceanWATERS' text, then the values it takes.
            msg = (
                f"Fault index, {fault}, is not valid. (fault = {fault} is not a goal error; "
                f"FaultClear takes one of {values})"
            )
            raise FaultError(msg)
        self._goal_errors &= ~fault
        return self._update()

    def _update(self) -> bool:
        no_force = self._injected_no_force or self._stale_ft
        arm = self._arm_hw | (ArmFaultsStatus.NO_FORCE_DATA if no_force else 0)
        system = self._goal_errors
        if arm:
            system |= System.ARM_EXECUTION_ERROR
        if self._pan_tilt:
            system |= System.PAN_TILT_EXECUTION_ERROR
        if self._power:
            system |= System.POWER_EXECUTION_ERROR
        if self._camera:
            system |= System.CAMERA_EXECUTION_ERROR
        status = FaultStatus(arm, self._pan_tilt, self._power, system, self._camera)
        changed = status != self._status
        self._status = status
        return changed
