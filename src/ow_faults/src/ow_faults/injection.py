"""The injected faults as a validated, frozen value, free of ROS.

The ``/faults`` dynamic_reconfigure server (``cfg/Faults.cfg``) holds OceanWATERS' fault
parameters (spec section 6.2); :data:`PARAMETERS` is the same table here
(a unit test checks it against the generated ``ow_faults.cfg.FaultsConfig``). Every consumer
turns the server's configuration into a :class:`FaultSet`::

    faults = FaultSet.from_dict(config)       # the server's dict (its "groups" key is ignored)
    faults.locked_joints                      # frozenset({"j_shou_pitch"})
    faults = faults.changed({"signal_noise_failure": 0.2})

Changes are checked before they reach the server: :func:`FaultSet.changed` refuses an unknown
name, a value of the wrong type or outside its range, a custom power profile that is missing or
malformed, and re-connecting cells, each with a :class:`~ow_faults.errors.FaultError` naming the
value and the limit. dynamic_reconfigure's own server would clamp a value silently.

Custom power profiles (``custom_fault_profile``) are CSV files with the header ``Index, wattage``:
row ``Index`` k (integers from 0) draws ``wattage`` W during second k after activation; after
the last row the profile draws nothing. A relative name is looked up in
:data:`PROFILE_DIR`.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Mapping
from dataclasses import dataclass, fields, replace
from pathlib import Path
from typing import Any

from ow_faults.errors import FaultError

#: Directory of the shipped custom power profiles (``src/ow_faults/config``).
PROFILE_DIR = Path(__file__).resolve().parents[2] / "config"

#: Lockable joints by the prefix of their ``<prefix>_joint_locked_failure`` parameter.
ARM_LOCKS = ("shou_yaw", "shou_pitch", "prox_pitch", "dist_pitch", "hand_yaw", "scoop_yaw")
ANTENNA_LOCKS = ("ant_pan", "ant_tilt")

#: What the forced power faults do to the battery: the state of charge a low-SOC fault drains
#: to and the share of charge an instantaneous capacity loss takes (OceanWATERS' power node's
#: 0.095 and 0.052), and the temperature a thermal failure holds the cells at, degrees C (0.1
#: above OceanWATERS' 70.0: the estimate of a cell held at exactly 70 reads 69.99999999996 after
#: a step, below the detector's >= 70). Each lies beyond the detector's threshold (SOC 0.1,
#: loss 0.05, 70 degrees C) so that the detector sees it.
FORCED_LOW_SOC = 0.095
FORCED_CAPACITY_LOSS = 0.052
FORCED_TEMPERATURE_C = 70.1


@dataclass(frozen=True)
class Parameter:
    """One fault parameter of the ``/faults`` server.

    Attributes:
        name: the parameter's name.
        group: its group in ``Faults.cfg``.
        kind: its Python type (bool, int, float or str).
        default: its default.
        minimum: lowest value (numbers), or None.
        maximum: highest value (numbers), or None.
        unit: unit of a number ("" for none).
    """

    name: str
    group: str
    kind: type
    default: Any
    minimum: float | None = None
    maximum: float | None = None
    unit: str = ""


def _table() -> dict[str, Parameter]:
    rows = [
        Parameter("arm_motion_continues_in_fault", "fault_behaviors", bool, False),
        Parameter("auto_clear_goal_errors", "fault_behaviors", bool, True),
        *(Parameter(f"{j}_joint_locked_failure", "ant_faults", bool, False) for j in ANTENNA_LOCKS),
        Parameter("camera_left_trigger_failure", "cam_faults", bool, False),
        *(Parameter(f"{j}_joint_locked_failure", "arm_faults", bool, False) for j in ARM_LOCKS),
        Parameter("enable", "ft_sensor_faults", bool, False),
        Parameter("zero_signal_failure", "ft_sensor_faults", bool, False),
        Parameter("signal_bias_failure", "ft_sensor_faults", float, 0.0, -1.0, 1.0, "N, N m"),
        Parameter("signal_noise_failure", "ft_sensor_faults", float, 0.0, 0.0, 1.0, "N, N m"),
        Parameter("high_power_draw", "power_faults", float, 1.0, 1.0, 360.0, "W"),
        Parameter("activate_high_power_draw", "power_faults", bool, False),
        Parameter("custom_fault_profile", "power_faults", str, "example_fault.csv"),
        Parameter("activate_custom_fault", "power_faults", bool, False),
        Parameter("battery_nodes_to_disconnect", "power_faults", int, 0, 0, 3, "cells"),
        Parameter("disconnect_battery_nodes", "power_faults", bool, False),
        Parameter("low_state_of_charge", "power_faults", bool, False),
        Parameter("instantaneous_capacity_loss", "power_faults", bool, False),
        Parameter("thermal_failure", "power_faults", bool, False),
    ]
    return {p.name: p for p in rows}


#: Every fault parameter of ``/faults`` by name, in ``Faults.cfg`` order.
PARAMETERS: dict[str, Parameter] = _table()


_KINDS = {bool: "a boolean", int: "an integer", float: "a number", str: "a string"}


def check_value(name: str, value: Any) -> Any:
    """``value`` for parameter ``name``, of its type and within its range.

    An int is accepted for a float parameter; nothing else is converted.

    Raises:
        FaultError: an unknown name (the known ones listed), a wrong type, a value out of range
            or not finite; the message names the value and the limit.
    """
    parameter = PARAMETERS.get(name)
    if parameter is None:
        msg = f"unknown fault parameter {name!r}; known: {', '.join(PARAMETERS)}"
        raise FaultError(msg)
    kind = parameter.kind
    ok = isinstance(value, kind) and (kind is bool or not isinstance(value, bool))
    if kind is float and isinstance(value, int) and not isinstance(value, bool):
        value, ok = float(value), True
    if not ok:
        msg = f"{name} = {value!r} must be {_KINDS[kind]}"
        raise FaultError(msg)
    if kind in (int, float):
        low, high, unit = parameter.minimum, parameter.maximum, parameter.unit
        if (
            not math.isfinite(value)
            or (low is not None and value < low)
            or (high is not None and value > high)
        ):
            msg = f"{name} = {value!r} {unit} is outside [{low:g}, {high:g}] {unit}".replace(
                "  ", " "
            )
            raise FaultError(msg)
    return value


@dataclass(frozen=True)
class FaultSet:
    """Every fault parameter of ``/faults`` at one time (OceanWATERS' names; defaults: none)."""

    arm_motion_continues_in_fault: bool = False
    auto_clear_goal_errors: bool = True
    ant_pan_joint_locked_failure: bool = False
    ant_tilt_joint_locked_failure: bool = False
    camera_left_trigger_failure: bool = False
    shou_yaw_joint_locked_failure: bool = False
    shou_pitch_joint_locked_failure: bool = False
    prox_pitch_joint_locked_failure: bool = False
    dist_pitch_joint_locked_failure: bool = False
    hand_yaw_joint_locked_failure: bool = False
    scoop_yaw_joint_locked_failure: bool = False
    enable: bool = False
    zero_signal_failure: bool = False
    signal_bias_failure: float = 0.0
    signal_noise_failure: float = 0.0
    high_power_draw: float = 1.0
    activate_high_power_draw: bool = False
    custom_fault_profile: str = "example_fault.csv"
    activate_custom_fault: bool = False
    battery_nodes_to_disconnect: int = 0
    disconnect_battery_nodes: bool = False
    low_state_of_charge: bool = False
    instantaneous_capacity_loss: bool = False
    thermal_failure: bool = False

    @classmethod
    def from_dict(cls, values: Mapping[str, Any]) -> FaultSet:
        """The fault set of a configuration (missing names keep their defaults).

        Args:
            values: parameter -> value, e.g. a dynamic_reconfigure configuration (its
                ``groups`` entry is ignored).

        Raises:
            FaultError: see :func:`check_value`; also a missing or malformed custom profile
                while ``activate_custom_fault`` is true.
        """
        return cls().changed(values)

    def changed(self, changes: Mapping[str, Any]) -> FaultSet:
        """This set with ``changes`` applied, every change checked (see :func:`check_value`).

        Raises:
            FaultError: a bad change, a missing or malformed custom profile while
                ``activate_custom_fault`` is (or becomes) true, or fewer cells to disconnect
                than are already disconnected (disconnection is irreversible).
        """
        checked = {n: check_value(n, v) for n, v in changes.items() if n != "groups"}
        new = replace(self, **checked)
        if new.activate_custom_fault and (
            "custom_fault_profile" in checked or "activate_custom_fault" in checked
        ):
            read_power_profile(new.custom_fault_profile)
        if self.disconnect_battery_nodes and (
            not new.disconnect_battery_nodes
            or new.battery_nodes_to_disconnect < self.battery_nodes_to_disconnect
        ):
            msg = (
                f"battery cells are disconnected ({self.battery_nodes_to_disconnect}); "
                "disconnection is irreversible: disconnect_battery_nodes stays true and "
                f"battery_nodes_to_disconnect at least {self.battery_nodes_to_disconnect}"
            )
            raise FaultError(msg)
        return new

    def as_dict(self) -> dict[str, Any]:
        """parameter -> value, every parameter."""
        return {f.name: getattr(self, f.name) for f in fields(self)}

    def active(self) -> dict[str, Any]:
        """The parameters that differ from their defaults (what is injected)."""
        default = FaultSet()
        return {n: v for n, v in self.as_dict().items() if getattr(default, n) != v}

    @property
    def locked_joints(self) -> frozenset[str]:
        """The joints (URDF names, ``j_<name>``) whose ``*_joint_locked_failure`` is set."""
        return frozenset(
            f"j_{j}"
            for j in (*ARM_LOCKS, *ANTENNA_LOCKS)
            if getattr(self, f"{j}_joint_locked_failure")
        )

    @property
    def wrist_faulted(self) -> bool:
        """Whether the F/T sensor output is changed (``enable`` and some fault of its group)."""
        return self.enable and (
            self.zero_signal_failure
            or self.signal_bias_failure != 0.0
            or self.signal_noise_failure != 0.0
        )

    @property
    def extra_load_w(self) -> float:
        """W, the constant injected load: ``high_power_draw`` while activated, else 0."""
        return self.high_power_draw if self.activate_high_power_draw else 0.0

    @property
    def cells_disconnected(self) -> int:
        """Battery cells disconnected (``battery_nodes_to_disconnect`` once activated)."""
        return self.battery_nodes_to_disconnect if self.disconnect_battery_nodes else 0


#: Joints that can be locked, URDF names, sorted (the order of ``/flags/joint_states``).
LOCKABLE_JOINTS: tuple[str, ...] = tuple(sorted(f"j_{j}" for j in (*ARM_LOCKS, *ANTENNA_LOCKS)))


@dataclass(frozen=True)
class PowerProfile:
    """A custom power-draw profile: ``watts[k]`` W during second ``k`` after activation.

    Attributes:
        path: the file read.
        watts: W, one per row (``Index`` k = 0, 1, ...); after the last row: nothing.
    """

    path: Path
    watts: tuple[float, ...]

    def load_at(self, elapsed_s: float) -> float:
        """W drawn ``elapsed_s`` s after activation (0 before 0 and after the last row ends)."""
        if not 0.0 <= elapsed_s < len(self.watts):
            return 0.0
        return self.watts[int(elapsed_s)]


def resolve_profile(name: str) -> Path:
    """The path of profile ``name``: absolute as given, relative in :data:`PROFILE_DIR`."""
    path = Path(name)
    return path if path.is_absolute() else PROFILE_DIR / path


def read_power_profile(name: str) -> PowerProfile:
    """Read and check a custom power-draw profile (header ``Index, wattage``).

    Raises:
        FaultError: the file is missing or unreadable, its header is not ``Index, wattage``,
            it has no rows, a row is not two numbers, an index is not an integer one above the
            previous (from 0), or a wattage is negative, above 360 W or not finite; the
            message names the file, the row and the value.
    """
    path = resolve_profile(name)
    try:
        with path.open(newline="") as stream:
            rows = [[cell.strip() for cell in row] for row in csv.reader(stream) if row]
    except OSError as error:
        msg = f"custom_fault_profile {name!r}: cannot read {path}: {error.strerror}"
        raise FaultError(msg) from error
    if not rows or [c.lower() for c in rows[0]] != ["index", "wattage"]:
        found = rows[0] if rows else "an empty file"
        msg = f"custom_fault_profile {path}: header must be 'Index, wattage', found {found}"
        raise FaultError(msg)
    if len(rows) < 2:
        msg = f"custom_fault_profile {path}: no data rows"
        raise FaultError(msg)
    limit = PARAMETERS["high_power_draw"].maximum or 0.0
    watts: list[float] = []
    for line, row in enumerate(rows[1:], start=2):
        try:
            index, wattage = (float(cell) for cell in row)
        except ValueError:
            msg = f"custom_fault_profile {path} line {line}: {row} is not two numbers"
            raise FaultError(msg) from None
        if index != len(watts):
            msg = (
                f"custom_fault_profile {path} line {line}: Index {row[0]} must be {len(watts)} "
                "(integers from 0, one per second)"
            )
            raise FaultError(msg)
        if not (math.isfinite(wattage) and 0.0 <= wattage <= limit):
            msg = (
                f"custom_fault_profile {path} line {line}: wattage {row[1]} W is outside "
                f"[0, {limit:g}] W"
            )
            raise FaultError(msg)
        watts.append(wattage)
    return PowerProfile(path, tuple(watts))
