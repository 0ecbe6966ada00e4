"""Synthetic runs with a closed-form energy, written as real bags without ROS (tests, benchmarks).

A run holds the arm joints at a constant torque and velocity, so eq. 1 gives
``P = sum_i tau_i * omega_i`` at every sample and eq. 4 gives ``E = P * duration`` exactly; the
power node, the recorder and the analysis must all reproduce these numbers.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path
from typing import Any

import numpy as np
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore

from ow_power.bagwriter import SplitBagWriter
from ow_power.config import PowerConfig
from ow_power.model import PowerIntegrator
from ow_runtime.names import ARM_OPERATION, JOINT_STATES, POWER

#: Source of the ow_msgs message definitions (the workspace's ``src/ow_msgs/msg``).
OW_MSGS_DIR = Path(__file__).resolve().parents[3] / "ow_msgs" / "msg"


def ow_typestore() -> Typestore:
    """The ROS 1 Noetic types plus every ow_msgs message, for serialising without genpy."""
    store = get_typestore(Stores.ROS1_NOETIC)
    for path in sorted(OW_MSGS_DIR.glob("*.msg")):
        store.register(get_types_from_msg(path.read_text(), f"ow_msgs/msg/{path.stem}"))
    return store


@dataclass(frozen=True)
class Segment:
    """One operation of a synthetic run.

    Attributes:
        name: operation name, e.g. ``grind``.
        duration_s: s of simulation time.
        velocity: rad/s per joint name (joints not listed are at rest).
        effort: N m per joint name.
    """

    name: str
    duration_s: float
    velocity: Mapping[str, float]
    effort: Mapping[str, float]

    def power_w(self) -> float:
        """W, eq. 1 summed over the joints (without P0)."""
        return sum(self.effort.get(j, 0.0) * w for j, w in self.velocity.items())


class BagMessages:
    """Serialises messages for :meth:`SplitBagWriter.write` from keyword fields."""

    def __init__(self, store: Typestore | None = None) -> None:
        """Use ``store`` (default :func:`ow_typestore`)."""
        self.store = store or ow_typestore()

    def serialize(self, msgtype: str, **fields: Any) -> tuple[str, str, str, bytes]:
        """``(ros1 type, md5, definition, bytes)`` of a message of ``msgtype`` (``pkg/msg/T``)."""
        msgdef, md5 = self.store.generate_msgdef(msgtype)
        msg = self.store.types[msgtype](**fields)
        ros1_type = msgtype.replace("/msg/", "/")
        return ros1_type, md5, msgdef, bytes(self.store.serialize_ros1(msg, msgtype))

    def header(self, stamp_ns: int, frame_id: str = "") -> Any:
        """A ``std_msgs/Header`` at ``stamp_ns``."""
        types = self.store.types
        stamp = types["builtin_interfaces/msg/Time"](
            sec=stamp_ns // 10**9, nanosec=stamp_ns % 10**9
        )
        return types["std_msgs/msg/Header"](seq=0, stamp=stamp, frame_id=frame_id)


def write_run(
    writer: SplitBagWriter,
    segments: Sequence[Segment],
    joints: Sequence[str],
    rate_hz: float = 100.0,
    start_s: float = 10.0,
    config: PowerConfig | None = None,
    with_power: bool = True,
) -> float:
    """Write joint states, power (as the power node would) and operation markers for a run.

    The first joint state of a segment carries that segment's velocity and effort, so every
    interval of the segment integrates its own constant power.

    Args:
        writer: destination (closed by the caller).
        segments: operations, back to back.
        joints: joint names, in message order.
        rate_hz: Hz, joint-state rate.
        start_s: s, simulation time of the first sample.
        config: power model for ``/power`` (default: defaults).
        with_power: also write ``/power``.

    Returns:
        s, simulation time of the last sample.
    """
    messages = BagMessages()
    integrator = PowerIntegrator(config or PowerConfig())
    period_ns = round(1e9 / rate_hz)
    t_ns = round(start_s * 1e9)

    def put(topic: str, msgtype: str, **fields: Any) -> None:
        ros1_type, md5, msgdef, data = messages.serialize(msgtype, **fields)
        writer.write(topic, ros1_type, md5, msgdef, t_ns, data)

    for op_id, segment in enumerate(segments):
        velocity = np.array([segment.velocity.get(j, 0.0) for j in joints])
        effort = np.array([segment.effort.get(j, 0.0) for j in joints])
        n = round(segment.duration_s * rate_hz)
        for k in range(n + 1):
            if k == 0:
                put(
                    ARM_OPERATION,
                    "ow_msgs/msg/Operation",
                    header=messages.header(t_ns),
                    id=op_id,
                    name=segment.name,
                    event=0,
                    parameters=json.dumps({"segment": op_id}),
                    success=False,
                    message="",
                    trajectory_file="",
                )
            if k > 0 or op_id == 0:
                if k > 0:
                    t_ns += period_ns
                put(
                    JOINT_STATES,
                    "sensor_msgs/msg/JointState",
                    header=messages.header(t_ns),
                    name=list(joints),
                    position=np.zeros(len(joints)),
                    velocity=velocity,
                    effort=effort,
                )
                if with_power:
                    s = integrator.update(t_ns * 1e-9, joints, velocity, effort)
                    put(
                        POWER,
                        "ow_msgs/msg/Power",
                        header=messages.header(t_ns),
                        name=list(s.names),
                        joint_power=s.joint_power_w,
                        mechanical_power=s.mechanical_power_w,
                        mechanical_power_abs=s.mechanical_power_abs_w,
                        auxiliary_power=s.auxiliary_power_w,
                        total_power=s.total_power_w,
                        electrical_power=s.electrical_power_w,
                        energy=s.energy_j,
                        mechanical_energy=s.mechanical_energy_j,
                        mechanical_energy_abs=s.mechanical_energy_abs_j,
                        electrical_energy=s.electrical_energy_j,
                    )
            if k == n:
                put(
                    ARM_OPERATION,
                    "ow_msgs/msg/Operation",
                    header=messages.header(t_ns),
                    id=op_id,
                    name=segment.name,
                    event=1,
                    parameters="",
                    success=True,
                    message="done",
                    trajectory_file="",
                )
    return t_ns * 1e-9


def write_split_series(directory: Path, start: datetime) -> list[Path]:
    """3 s of ``/a`` (std_msgs/Float64 at 10 Hz, value = t s) and ``/b`` (std_msgs/Int32 at 2 Hz,
    value = its 10 Hz index), and a latched ``/state`` (std_msgs/String "ready") published once,
    from t = 1 s; written by :class:`SplitBagWriter` in 1 s files, so that ``/state`` is written
    again at the start of each. The split files (3), in order."""
    writer = SplitBagWriter(directory, split_duration_s=1.0, start=start)
    messages = BagMessages()

    def put(topic: str, msgtype: str, t_ns: int, latching: bool = False, **fields: Any) -> None:
        ros1_type, md5, msgdef, data = messages.serialize(msgtype, **fields)
        writer.write(topic, ros1_type, md5, msgdef, t_ns, data, latching=latching)

    put("/state", "std_msgs/msg/String", 10**9, latching=True, data="ready")
    for k in range(30):
        t_ns = 10**9 + k * 10**8
        put("/a", "std_msgs/msg/Float64", t_ns, data=t_ns * 1e-9)
        if k % 5 == 0:
            put("/b", "std_msgs/msg/Int32", t_ns, data=k)
    return writer.close()
