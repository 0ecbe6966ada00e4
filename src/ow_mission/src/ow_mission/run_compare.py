"""Whether two mission runs are the same run: the numbers of their ``report.json`` (all but the
wall-clock ones) and the messages of their bags. A mission is a function of its file
(docs/determinism.md), so a replay of a failed mission must match the original exactly. No ROS:
the bags are read with ``rosbags``.

    python -m ow_mission.run_compare <run dir> <run dir> [topic ...]
"""

from __future__ import annotations

import json
import sys
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from rosbags.highlevel import AnyReader

from ow_faults.protocol import CHANGES_TOPIC
from ow_mission.mission import FAULT_STATUS_TOPICS
from ow_power.bagwriter import starts_with_header
from ow_runtime.names import (
    ARM_END_EFFECTOR_FORCE_TORQUE,
    BATTERY_REMAINING_USEFUL_LIFE,
    BATTERY_STATE_OF_CHARGE,
    BATTERY_TEMPERATURE,
    FLAGS_JOINT_STATES,
    JOINT_STATES,
    MATERIAL_INGESTED,
    POWER,
    REGOLITH_BUDGET,
    SIM_GRINDER_WRENCH,
    SIM_SCOOP_WRENCH,
    TERRAIN_TOPIC,
)

#: report.json entries that measure the machine, not the run.
WALL_CLOCK_KEYS = frozenset(
    {
        "wall_time_s",
        "real_time_factor",
        "peak_memory_mb",
        "report_seconds",
        "figures_seconds",
        "planning_time_s",
        "cpu_seconds_to_make",
        "seconds_to_make",
    }
)
#: report.json entries the figures add: made from the bags after the run, so a run whose
#: figures are not drawn (``figures: none``, or still being drawn) is the same run as one whose
#: figures are.
FIGURE_KEYS = frozenset({"replay"})
#: Topics compared by default: the simulation's streams (the carved terrains too), power, the
#: battery and the fault telemetry (the detector's status, stamped with the sim time of what
#: changed it; the flags).
TOPICS = (
    JOINT_STATES,
    TERRAIN_TOPIC,
    POWER,
    ARM_END_EFFECTOR_FORCE_TORQUE,
    SIM_SCOOP_WRENCH,
    SIM_GRINDER_WRENCH,
    BATTERY_STATE_OF_CHARGE,
    BATTERY_REMAINING_USEFUL_LIFE,
    BATTERY_TEMPERATURE,
    FLAGS_JOINT_STATES,
    CHANGES_TOPIC,
    *FAULT_STATUS_TOPICS,
    REGOLITH_BUDGET,
    MATERIAL_INGESTED,
)


def report_numbers(report: Any, path: str = "") -> dict[str, float]:
    """Every number of a ``report.json`` (loaded) by its path (``.steps[2].sim_end_s``), but
    the wall-clock ones, the figures' own (:data:`FIGURE_KEYS`) and the mission's
    configuration (where the run was written)."""
    if isinstance(report, dict):
        out: dict[str, float] = {}
        for key, item in report.items():
            if key not in WALL_CLOCK_KEYS and key not in FIGURE_KEYS and key != "config":
                out.update(report_numbers(item, f"{path}.{key}"))
        return out
    if isinstance(report, list):
        out = {}
        for index, item in enumerate(report):
            out.update(report_numbers(item, f"{path}[{index}]"))
        return out
    if isinstance(report, bool) or not isinstance(report, int | float):
        return {}
    return {path: report}


def raw_messages(run_dir: Path, topic: str) -> list[bytes]:
    """Every message of ``topic`` in the run's bags, as :func:`raw_topics` gives it."""
    return raw_topics(run_dir, [topic])[topic]


def raw_topics(run_dir: Path, topics: Iterable[str]) -> dict[str, list[bytes]]:
    """Every message of each of ``topics`` in the run's bags, serialised as recorded, in order,
    with a header's ``seq`` set to 0, read in one pass over the bags (each pass reads every
    chunk: the topics are interleaved in them). rospy numbers a publisher's messages per write
    and sends a latched message again to each new subscriber, each time with the next number:
    the ``seq`` a recorder gets depends on the order the subscribers connected in, not on the
    run. A latched topic's last message is repeated at the start of each bag file (each file
    stands alone), and where a file starts depends on which topic's message came first: such a
    repeat (the same bytes as the topic's message before it) is left out.

    A topic's messages come in the same order as when it is read alone: the readers merge their
    index entries by (time, chunk, offset) and the files in one fixed order, whichever
    connections are asked for.
    """
    messages: dict[str, list[bytes]] = {topic: [] for topic in topics}
    bags = sorted((run_dir / "bags").glob("*.bag"))
    if not bags:
        return messages
    with AnyReader(bags) as reader:
        connections = [c for c in reader.connections if c.topic in messages]
        headed = {id(c): starts_with_header(c.msgdef.data) for c in connections}
        for connection, _, raw in reader.messages(connections=connections):
            data = bytes(raw)
            if headed[id(connection)]:
                data = bytes(4) + data[4:]  # the header's uint32 seq comes first
            kept = messages[connection.topic]
            latched = getattr(connection.ext, "latching", 0)
            if not (latched and kept and kept[-1] == data):
                kept.append(data)
    return messages


def differences(a: Path, b: Path, topics: Iterable[str] = TOPICS) -> list[str]:
    """What differs between runs ``a`` and ``b`` (run directories); empty: the same run."""
    found = []
    numbers_a = report_numbers(json.loads((a / "report.json").read_text()))
    numbers_b = report_numbers(json.loads((b / "report.json").read_text()))
    for key in sorted(numbers_a.keys() | numbers_b.keys()):
        if numbers_a.get(key) != numbers_b.get(key):
            found.append(f"report{key}: {numbers_a.get(key)!r} != {numbers_b.get(key)!r}")
    topics = list(dict.fromkeys(topics))
    raw_a, raw_b = raw_topics(a, topics), raw_topics(b, topics)
    for topic in topics:
        messages_a, messages_b = raw_a[topic], raw_b[topic]
        first = next(
            (i for i, (x, y) in enumerate(zip(messages_a, messages_b, strict=False)) if x != y),
            None,
        )
        if first is not None:
            found.append(f"{topic}: message {first} differs")
        elif len(messages_a) != len(messages_b):
            found.append(f"{topic}: {len(messages_a)} messages != {len(messages_b)}")
    return found


def main(argv: list[str] | None = None) -> int:
    """Print what differs between two runs; 0 when they are the same run, 1 if not."""
    args = sys.argv[1:] if argv is None else argv
    if len(args) < 2:
        print(__doc__)
        return 2
    found = differences(Path(args[0]), Path(args[1]), args[2:] or TOPICS)
    for line in found:
        print(line)
    print("the same run" if not found else f"{len(found)} differences")
    return 1 if found else 0


if __name__ == "__main__":
    raise SystemExit(main())
