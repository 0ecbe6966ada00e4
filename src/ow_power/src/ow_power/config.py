"""Configuration of the power, recorder and battery nodes: frozen dataclasses from ``from_dict()``.

The nodes read their private namespace once (``rospy.get_param("~")``) and pass the dict here;
``config/power.yaml`` holds the defaults below under the node names ``power``, ``record`` and
``battery``, so ``rosparam load config/power.yaml`` configures all three (:data:`CONFIG_FILE`). A
missing key takes its default; unknown keys, wrong types and values out of range are validated by
the workspace's :class:`ow_runtime.params.Params` and reported together in one
:class:`~ow_power.errors.ConfigError` naming each key (``power/max_dt_s``, ``record/prefix``).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ow_power.errors import ConfigError
from ow_runtime.names import (
    ARM_END_EFFECTOR_FORCE_TORQUE,
    ARM_JOINT_ACCELERATIONS,
    ARM_JOINT_POSITIONS,
    ARM_JOINT_TORQUES,
    ARM_JOINT_VELOCITIES,
    ARM_OPERATION,
    ARM_POSE,
    BATTERY_REMAINING_USEFUL_LIFE,
    BATTERY_STATE_OF_CHARGE,
    BATTERY_TEMPERATURE,
    GUARDED_MOVE_RESULT,
    JOINT_STATES,
    PAN_TILT_POSITION,
    POWER,
    ROBOT_DESCRIPTION,
    SIM_GRINDER_WRENCH,
    SIM_SCOOP_WRENCH,
    TF,
    TF_STATIC,
)
from ow_runtime.params import Params

#: The power, recorder and battery nodes' parameter file (``src/ow_power/config/power.yaml``):
#: one section per node, ``power:``, ``record:`` and ``battery:``.
CONFIG_FILE = Path(__file__).resolve().parents[2] / "config" / "power.yaml"

#: OceanWATERS' telemetry made from the joint states (owl_msgs; the ow_lander telemetry node).
TELEMETRY_TOPICS: tuple[str, ...] = (
    ARM_JOINT_POSITIONS,
    ARM_JOINT_VELOCITIES,
    ARM_JOINT_ACCELERATIONS,
    ARM_JOINT_TORQUES,
    ARM_POSE,
    PAN_TILT_POSITION,
)
#: The battery node's topics, one message each per battery period.
BATTERY_TOPICS: tuple[str, ...] = (
    BATTERY_STATE_OF_CHARGE,
    BATTERY_REMAINING_USEFUL_LIFE,
    BATTERY_TEMPERATURE,
    "/battery_state",
)

#: Topics the recorder records by default (missing ones are simply absent from the bag).
DEFAULT_RECORD_TOPICS: tuple[str, ...] = (
    POWER,
    JOINT_STATES,
    GUARDED_MOVE_RESULT,
    ARM_OPERATION,
    SIM_SCOOP_WRENCH,
    SIM_GRINDER_WRENCH,
    "/sim/joint_damping",
    # OceanWATERS' telemetry (owl_msgs; the ow_lander telemetry node, the sim's wrist F/T).
    *TELEMETRY_TOPICS,
    ARM_END_EFFECTOR_FORCE_TORQUE,
    # For viewers (RViz through `rosbag play --clock`, Foxglove, Lichtblick): the frames, the
    # robot and the markers of ow_viz; the latched ones are repeated in every file of a run.
    TF,
    TF_STATIC,
    ROBOT_DESCRIPTION,
    "/viz/terrain",
    "/viz/tool_path",
    "/viz/ground_point",
)

#: Bag compressions the recorder writes. LZ4 is refused: ROS's own lz4 reader cannot read the
#: LZ4 chunks rosbags writes (see ENVIRONMENT.md).
COMPRESSIONS: tuple[str, ...] = ("none", "bz2")


@dataclass(frozen=True)
class PowerConfig:
    """Parameters of the power node (private namespace ``~``).

    Attributes:
        auxiliary_power_w: W, P0 of eq. 2 (OceanWATERS baseline: heating 20.6, instruments 9.6,
            sample handling 9.6, camera controller 1.6, computing 1.6).
        motor_efficiency: mechanical/electrical efficiency in (0, 1], for the electrical estimate.
        joints: joint names to sum over; empty means every joint of each message.
        max_dt_s: s, longest interval between joint states that is integrated; a longer gap
            (lost messages, a restarted simulation) is skipped rather than bridged.
    """

    auxiliary_power_w: float = 43.0
    motor_efficiency: float = 0.9
    joints: tuple[str, ...] = ()
    max_dt_s: float = 1.0

    @classmethod
    def from_dict(cls, params: Mapping[str, Any]) -> PowerConfig:
        """Validate the node's private namespace (a section of :data:`CONFIG_FILE`; missing keys
        take their defaults), every problem reported at once (:class:`~ow_runtime.params.Params`).

        Raises:
            ConfigError: naming each unknown key (with the nearest known one), wrong type or
                value out of range.
        """
        p = Params(params, "power", ConfigError)
        config = cls(
            auxiliary_power_w=p.non_negative("auxiliary_power_w", cls.auxiliary_power_w, unit="W"),
            motor_efficiency=p.number(
                "motor_efficiency", cls.motor_efficiency, low=0.0, low_inclusive=False, high=1.0
            ),
            joints=p.names("joints", cls.joints),
            max_dt_s=p.positive("max_dt_s", cls.max_dt_s, unit="s"),
        )
        p.finish()
        return config


@dataclass(frozen=True)
class RecorderConfig:
    """Parameters of the recorder node (private namespace ``~``).

    Attributes:
        output_dir: directory of the bags; empty means ``$ROS_HOME/bags`` (``~/.ros/bags``).
        prefix: first part of every bag name, ``<prefix>_<start time>_<index>.bag``.
        topics: topics to record, of any message type.
        split_duration_s: s of message time (simulation time) per bag file; 0 disables.
        split_size_mb: MB (1e6 bytes) of message data per bag file; 0 disables.
        compression: ``none`` or ``bz2``.
        queue_size: subscriber queue length per topic, in messages.
    """

    output_dir: str = ""
    prefix: str = "ow"
    topics: tuple[str, ...] = DEFAULT_RECORD_TOPICS
    split_duration_s: float = 60.0
    split_size_mb: float = 100.0
    compression: str = "none"
    queue_size: int = 1000

    @classmethod
    def from_dict(cls, params: Mapping[str, Any]) -> RecorderConfig:
        """Validate the node's private namespace (a section of :data:`CONFIG_FILE`; missing keys
        take their defaults), every problem reported at once (:class:`~ow_runtime.params.Params`).

        Raises:
            ConfigError: naming each unknown key (with the nearest known one), wrong type or
                value out of range.
        """
        p = Params(params, "record", ConfigError)
        prefix = p.string("prefix", cls.prefix)
        if not prefix or "/" in prefix:
            p.problem(f"{p.name('prefix')} = {prefix!r} must be a non-empty file name without '/'")
        topics = p.names("topics", cls.topics)
        if not topics:
            p.problem(f"{p.name('topics')} is empty: nothing to record")
        compression = p.string("compression", cls.compression).lower()
        if compression not in COMPRESSIONS:
            p.problem(
                f"{p.name('compression')} = {compression!r} is not one of "
                f"{', '.join(COMPRESSIONS)} (lz4 bags written by rosbags are unreadable by ROS's "
                "rosbag tools)"
            )
        config = cls(
            output_dir=p.string("output_dir", cls.output_dir),
            prefix=prefix,
            topics=topics,
            split_duration_s=p.non_negative("split_duration_s", cls.split_duration_s, unit="s"),
            split_size_mb=p.non_negative("split_size_mb", cls.split_size_mb, unit="MB"),
            compression=compression,
            queue_size=p.integer("queue_size", cls.queue_size, low=1),
        )
        p.finish()
        return config


#: Per-cell end-of-discharge voltages the cell model covers, V: ProgPy's Li-ion cell has an
#: open-circuit voltage between about 3 V (empty) and 4.2 V (full).
CELL_EOD_RANGE_V: tuple[float, float] = (2.5, 4.0)


@dataclass(frozen=True)
class BatteryConfig:
    """Parameters of the battery node (private namespace ``~``) and of ``ow_power.battery.Battery``.

    Defaults are OceanWATERS' (GSAP ``Battery`` model, 6S1P pack, ``system.cfg``).

    Attributes:
        initial_soc: state of charge at start, in (0, 1].
        temperature_c: degrees C, the cells' initial and ambient temperature.
        cells_in_series: cells of the pack, all in series (6S1P: 6).
        mobile_charge_c: C, the pack's mobile charge (GSAP/ProgPy ``qMobile``; charge is the
            same for every cell of a series string).
        internal_resistance_ohm: ohm, the pack's ohmic resistance (``Ro``), shared equally by
            the cells.
        eod_voltage_v: V, the pack's end-of-discharge voltage (``VEOD``); per cell it must lie
            in :data:`CELL_EOD_RANGE_V`.
        update_rate_hz: Hz of simulation time at which the battery is stepped, estimated and
            predicted (OceanWATERS' loop rate: 1 Hz).
        max_gap_s: s, longest interval between two ``/power`` stamps that is drained; after a
            longer gap (or a stamp going back) the battery restarts its period at the new stamp.
        voltage_noise_v: V, standard deviation of the noise on the measured pack voltage.
        temperature_noise_c: degrees C, standard deviation of the noise on the measured
            temperature.
        noise_seed: seed of the measurement noise (runs with the same seed are identical).
    """

    initial_soc: float = 0.95
    temperature_c: float = 20.0
    cells_in_series: int = 6
    mobile_charge_c: float = 80387.0
    internal_resistance_ohm: float = 0.0232
    eod_voltage_v: float = 18.0
    update_rate_hz: float = 1.0
    max_gap_s: float = 1.0
    voltage_noise_v: float = 0.0
    temperature_noise_c: float = 0.0
    noise_seed: int = 0

    @property
    def period_s(self) -> float:
        """s of simulation time between updates."""
        return 1.0 / self.update_rate_hz

    @classmethod
    def from_dict(cls, params: Mapping[str, Any]) -> BatteryConfig:
        """Validate the node's private namespace (a section of :data:`CONFIG_FILE`; missing keys
        take their defaults), every problem reported at once (:class:`~ow_runtime.params.Params`).

        Raises:
            ConfigError: naming each unknown key (with the nearest known one), wrong type or
                value out of range.
        """
        p = Params(params, "battery", ConfigError)
        cells = p.integer("cells_in_series", cls.cells_in_series, low=1, high=1000)
        eod_voltage_v = p.positive("eod_voltage_v", cls.eod_voltage_v, unit="V")
        low, high = CELL_EOD_RANGE_V
        if not low <= eod_voltage_v / cells <= high:
            p.problem(
                f"{p.name('eod_voltage_v')} = {eod_voltage_v:g} V is {eod_voltage_v / cells:g} V "
                f"per cell for {cells} cells, outside [{low:g}, {high:g}] V per cell (the range "
                "of the Li-ion cell model)"
            )
        config = cls(
            initial_soc=p.number(
                "initial_soc", cls.initial_soc, low=0.0, low_inclusive=False, high=1.0
            ),
            temperature_c=p.number(
                "temperature_c", cls.temperature_c, low=-100.0, high=100.0, unit="degC"
            ),
            cells_in_series=cells,
            mobile_charge_c=p.positive("mobile_charge_c", cls.mobile_charge_c, unit="C"),
            internal_resistance_ohm=p.positive(
                "internal_resistance_ohm", cls.internal_resistance_ohm, unit="ohm"
            ),
            eod_voltage_v=eod_voltage_v,
            update_rate_hz=p.positive("update_rate_hz", cls.update_rate_hz, unit="Hz"),
            max_gap_s=p.positive("max_gap_s", cls.max_gap_s, unit="s"),
            voltage_noise_v=p.non_negative("voltage_noise_v", cls.voltage_noise_v, unit="V"),
            temperature_noise_c=p.non_negative(
                "temperature_noise_c", cls.temperature_noise_c, unit="degC"
            ),
            noise_seed=p.integer("noise_seed", cls.noise_seed, low=0, high=2**63 - 1),
        )
        p.finish()
        return config
