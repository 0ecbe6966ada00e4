"""Conversions between ROS messages and the ROS-free power model."""

from __future__ import annotations

from typing import Any

from ow_msgs.msg import Power
from ow_power.model import PowerSample


def joint_state_fields(msg: Any) -> tuple[float, list[str], tuple[float, ...], tuple[float, ...]]:
    """``(stamp s, names, velocity rad/s, effort N m)`` of a ``sensor_msgs/JointState``."""
    return msg.header.stamp.to_sec(), list(msg.name), tuple(msg.velocity), tuple(msg.effort)


def power_message(sample: PowerSample, header: Any) -> Power:
    """The ``ow_msgs/Power`` of a sample, with ``header`` (the joint state's) as its header."""
    return Power(
        header=header,
        name=list(sample.names),
        joint_power=sample.joint_power_w.tolist(),
        mechanical_power=sample.mechanical_power_w,
        mechanical_power_abs=sample.mechanical_power_abs_w,
        auxiliary_power=sample.auxiliary_power_w,
        total_power=sample.total_power_w,
        electrical_power=sample.electrical_power_w,
        energy=sample.energy_j,
        mechanical_energy=sample.mechanical_energy_j,
        mechanical_energy_abs=sample.mechanical_energy_abs_j,
        electrical_energy=sample.electrical_energy_j,
    )
