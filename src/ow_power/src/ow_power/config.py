"""Configuration of the power and recorder nodes: frozen dataclasses built by pure ``from_dict()``.

The nodes read their private namespace once (``rospy.get_param("~")``) and pass the dict here;
``config/power.yaml`` holds the defaults below under the node names ``power`` and ``record``, so
``rosparam load config/power.yaml`` configures both. A missing key takes its default; an unknown
key, a wrong type or a value out of range raises :class:`~ow_power.errors.ConfigError` naming it.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, fields
from typing import Any

from ow_power.errors import ConfigError

#: Topics the recorder records by default (missing ones are simply absent from the bag).
DEFAULT_RECORD_TOPICS: tuple[str, ...] = (
    "/power",
    "/joint_states",
    "/guarded_move_result",
    "/arm/operation",
    "/sim/scoop_wrench",
    "/sim/grinder_wrench",
    "/sim/joint_damping",
)

#: Bag compressions the recorder writes. LZ4 is refused: ROS's own lz4 reader cannot read the
#: LZ4 chunks rosbags writes (see ENVIRONMENT.md).
COMPRESSIONS: tuple[str, ...] = ("none", "bz2")


def _check_keys(cls: type, params: Mapping[str, Any]) -> None:
    known = {f.name for f in fields(cls)}
    unknown = sorted(set(params) - known)
    if unknown:
        msg = f"unknown parameter {unknown[0]!r} (known: {', '.join(sorted(known))})"
        raise ConfigError(msg)


def _number(
    params: Mapping[str, Any],
    key: str,
    default: float,
    *,
    low: float = -math.inf,
    low_inclusive: bool = True,
    high: float = math.inf,
) -> float:
    """``params[key]`` as a finite float within [low, high] (or (low, high] when not inclusive)."""
    value = params.get(key, default)
    if isinstance(value, bool) or not isinstance(value, int | float):
        msg = f"parameter {key!r} must be a number, got {value!r}"
        raise ConfigError(msg)
    value = float(value)
    too_low = value < low if low_inclusive else value <= low
    if not math.isfinite(value) or too_low or value > high:
        bracket = "[" if low_inclusive else "("
        msg = f"parameter {key!r} = {value} is outside {bracket}{low}, {high}]"
        raise ConfigError(msg)
    return value


def _string(params: Mapping[str, Any], key: str, default: str) -> str:
    value = params.get(key, default)
    if not isinstance(value, str):
        msg = f"parameter {key!r} must be a string, got {value!r}"
        raise ConfigError(msg)
    return value


def _names(params: Mapping[str, Any], key: str, default: tuple[str, ...]) -> tuple[str, ...]:
    value = params.get(key, list(default))
    if not isinstance(value, list | tuple) or not all(isinstance(v, str) and v for v in value):
        msg = f"parameter {key!r} must be a list of non-empty strings, got {value!r}"
        raise ConfigError(msg)
    if len(set(value)) != len(value):
        msg = f"parameter {key!r} lists a name twice: {value!r}"
        raise ConfigError(msg)
    return tuple(value)


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
        """Validate a parameter dict (missing keys take their defaults).

        Raises:
            ConfigError: unknown key, wrong type or value out of range; the message names the key.
        """
        _check_keys(cls, params)
        return cls(
            auxiliary_power_w=_number(params, "auxiliary_power_w", cls.auxiliary_power_w, low=0.0),
            motor_efficiency=_number(
                params,
                "motor_efficiency",
                cls.motor_efficiency,
                low=0.0,
                low_inclusive=False,
                high=1.0,
            ),
            joints=_names(params, "joints", cls.joints),
            max_dt_s=_number(params, "max_dt_s", cls.max_dt_s, low=0.0, low_inclusive=False),
        )


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
        """Validate a parameter dict (missing keys take their defaults).

        Raises:
            ConfigError: unknown key, wrong type or value out of range; the message names the key.
        """
        _check_keys(cls, params)
        prefix = _string(params, "prefix", cls.prefix)
        if not prefix or "/" in prefix:
            msg = f"parameter 'prefix' = {prefix!r} must be a non-empty file name without '/'"
            raise ConfigError(msg)
        topics = _names(params, "topics", cls.topics)
        if not topics:
            msg = "parameter 'topics' is empty: nothing to record"
            raise ConfigError(msg)
        compression = _string(params, "compression", cls.compression).lower()
        if compression not in COMPRESSIONS:
            msg = (
                f"parameter 'compression' = {compression!r} is not one of {COMPRESSIONS} "
                "(lz4 bags written by rosbags are unreadable by ROS's rosbag tools)"
            )
            raise ConfigError(msg)
        queue_size = params.get("queue_size", cls.queue_size)
        if isinstance(queue_size, bool) or not isinstance(queue_size, int) or queue_size < 1:
            msg = f"parameter 'queue_size' must be an integer >= 1, got {queue_size!r}"
            raise ConfigError(msg)
        return cls(
            output_dir=_string(params, "output_dir", cls.output_dir),
            prefix=prefix,
            topics=topics,
            split_duration_s=_number(params, "split_duration_s", cls.split_duration_s, low=0.0),
            split_size_mb=_number(params, "split_size_mb", cls.split_size_mb, low=0.0),
            compression=compression,
            queue_size=queue_size,
        )
