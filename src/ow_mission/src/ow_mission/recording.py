"""What a mission's bags hold for its pictures (no ROS): :func:`read_recording` reads the joint
positions, the terrains and the ground-detector samples of a run's (split) bags
(:func:`ow_power.bagread.read_messages`); :func:`recording_from_messages` takes them from
messages read already with other topics.
"""

from __future__ import annotations

import bisect
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ow_description.terrain import HeightMap
from ow_mission.errors import ReplayError
from ow_power.bagread import read_messages
from ow_power.errors import BagReadError
from ow_runtime.names import ARM_GROUND_DETECTOR, GUARDED_MOVE_RESULT, JOINT_STATES, TERRAIN_TOPIC

FloatArray = npt.NDArray[np.float64]

JOINT_STATES_TOPIC = JOINT_STATES
TERRAIN_TOPIC = TERRAIN_TOPIC
DETECTOR_TOPIC = ARM_GROUND_DETECTOR
GUARDED_RESULT_TOPIC = GUARDED_MOVE_RESULT
#: The topics :func:`recording_from_messages` uses.
TOPICS = (JOINT_STATES_TOPIC, TERRAIN_TOPIC, DETECTOR_TOPIC, GUARDED_RESULT_TOPIC)


@dataclass(frozen=True)
class DetectorSample:
    """One ``/arm/ground_detector`` message (ow_msgs/GroundDetectorSignal).

    Attributes:
        t_s: s, simulation time of the sample.
        detector: "velocity" or "force".
        signal: m/s or N.
        moving_average: same unit.
        threshold: same unit.
        contact: True at the sample where contact was declared.
    """

    t_s: float
    detector: str
    signal: float
    moving_average: float
    threshold: float
    contact: bool


@dataclass
class Recording:
    """A run's bags, as the report's figures need them.

    Attributes:
        bags: the files read, in recording order.
        joint_t: (N,) s, stamps of ``/joint_states``.
        joint_names: names of the columns of ``joint_positions``.
        joint_positions: (N, n) rad.
        terrains: (stamp s, terrain) of every ``/sim/terrain`` message, in time order.
        detector: the ``/arm/ground_detector`` samples (empty when none was recorded).
        contacts: (stamp s, (3,) m) of successful ``/guarded_move_result`` messages.
    """

    bags: list[Path]
    joint_t: FloatArray
    joint_names: list[str]
    joint_positions: FloatArray
    terrains: list[tuple[float, HeightMap]] = field(default_factory=list)
    detector: list[DetectorSample] = field(default_factory=list)
    contacts: list[tuple[float, FloatArray]] = field(default_factory=list)

    def joints_at(self, t_s: float) -> dict[str, float]:
        """rad by name: the last joint state at or before ``t_s`` (the first one before it)."""
        i = max(int(np.searchsorted(self.joint_t, t_s, side="right")) - 1, 0)
        return dict(zip(self.joint_names, self.joint_positions[i].tolist(), strict=True))

    def terrain_at(self, t_s: float) -> HeightMap | None:
        """The last terrain published at or before ``t_s`` (the first one before it)."""
        if not self.terrains:
            return None
        stamps = [t for t, _ in self.terrains]
        i = max(bisect.bisect_right(stamps, t_s) - 1, 0)
        return self.terrains[i][1]


def stamp_s(msg: Any) -> float:
    """s, the header stamp of a message read with rosbags."""
    return float(msg.header.stamp.sec) + 1e-9 * float(msg.header.stamp.nanosec)


def read_recording(bags: Sequence[Path]) -> Recording:
    """Read the joint states, terrains, detector samples and contacts of ``bags``.

    Raises:
        ReplayError: a bag is unreadable, or there is no ``/joint_states``.
    """
    try:
        messages = read_messages(bags, TOPICS)
    except BagReadError as exc:
        msg = f"cannot read {[str(b) for b in bags]}: {exc}"
        raise ReplayError(msg) from exc
    return recording_from_messages(messages, bags)


def recording_from_messages(
    messages: Mapping[str, Sequence[tuple[int, Any]]],
    bags: Sequence[Path] = (),
    joints: bool = True,
) -> Recording:
    """The :class:`Recording` of messages read already (e.g. with the report's other topics).

    Terrains are stamped with their bag time (the receipt time on the simulation clock: the
    first, latched one may carry a zero header stamp).

    Args:
        messages: topic -> (bag time ns, message) in time order, as
            :func:`ow_power.bagread.read_messages` returns for (at least) :data:`TOPICS`.
        bags: the files they were read from, in order.
        joints: False accepts messages without ``/joint_states`` (a recording of the terrains,
            the detector and the contacts only, its joint arrays empty).

    Raises:
        ReplayError: there is no ``/joint_states`` (and ``joints``).
    """
    joint_states = messages.get(JOINT_STATES_TOPIC, [])
    if not joint_states and joints:
        msg_text = f"no {JOINT_STATES_TOPIC} in {[str(b) for b in bags]}"
        raise ReplayError(msg_text)
    names = list(joint_states[0][1].name) if joint_states else []
    stamps = []
    rows = []
    for _, msg in joint_states:
        position = dict(zip(msg.name, msg.position, strict=False))
        stamps.append(stamp_s(msg))
        rows.append([position.get(n, np.nan) for n in names])
    recording = Recording(list(bags), np.zeros(0), [], np.zeros((0, 0)))
    for bag_ns, msg in messages.get(TERRAIN_TOPIC, []):
        heights = np.asarray(msg.heights, dtype=np.float64).reshape(msg.rows, msg.cols)
        terrain = HeightMap(heights, msg.resolution, msg.origin_x, msg.origin_y)
        recording.terrains.append((bag_ns * 1e-9, terrain))
    for _, msg in messages.get(DETECTOR_TOPIC, []):
        recording.detector.append(
            DetectorSample(
                stamp_s(msg),
                str(msg.detector),
                float(msg.signal),
                float(msg.moving_average),
                float(msg.threshold),
                bool(msg.contact),
            )
        )
    for _, msg in messages.get(GUARDED_RESULT_TOPIC, []):
        if msg.success:
            p = msg.position
            recording.contacts.append((stamp_s(msg), np.array([p.x, p.y, p.z])))
    order = np.argsort(np.asarray(stamps), kind="stable")
    recording.joint_t = np.asarray(stamps)[order]
    recording.joint_names = names
    positions = np.asarray(rows, dtype=np.float64).reshape(len(rows), len(names))
    recording.joint_positions = positions[order]
    recording.terrains.sort(key=lambda item: item[0])
    recording.detector.sort(key=lambda s: s.t_s)
    return recording
