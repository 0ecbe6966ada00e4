"""The report's faults section and its battery figure, made from a run's bags (no ROS).

What the mission injected and when (``report.json``'s ``fault_schedule``, written by the
mission), when each fault bit was first set on each owl_msgs status topic (bit names from the
messages' own constants), how the mission ended, the energy over the steps and the battery at
the end; ``battery.png``: state of charge and remaining useful life over the mission with the
injections and detections marked. :func:`read_fault_recording` reads the bags
(:func:`ow_power.bagread.read_messages`), :func:`fault_recording_from_messages` takes messages
the report read already with its other topics; :func:`fault_summary` computes the section;
:func:`plot_battery` only draws.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ow_mission.errors import OwMissionError
from ow_mission.plots import _pyplot
from ow_power.bagread import read_messages
from ow_power.errors import BagReadError
from ow_runtime.names import (
    ARM_FAULTS_STATUS,
    BATTERY_REMAINING_USEFUL_LIFE,
    BATTERY_STATE_OF_CHARGE,
    PAN_TILT_FAULTS_STATUS,
    POWER_FAULTS_STATUS,
    SYSTEM_FAULTS_STATUS,
)
from owl_msgs.msg import (
    ArmFaultsStatus,
    PanTiltFaultsStatus,
    PowerFaultsStatus,
    SystemFaultsStatus,
)

#: The status topics, their message classes (whose constants name the bits), in report order.
STATUS_TOPICS: dict[str, type] = {
    ARM_FAULTS_STATUS: ArmFaultsStatus,
    PAN_TILT_FAULTS_STATUS: PanTiltFaultsStatus,
    POWER_FAULTS_STATUS: PowerFaultsStatus,
    SYSTEM_FAULTS_STATUS: SystemFaultsStatus,
}
SOC_TOPIC = BATTERY_STATE_OF_CHARGE
RUL_TOPIC = BATTERY_REMAINING_USEFUL_LIFE
#: The topics :func:`fault_recording_from_messages` uses.
TOPICS = (*STATUS_TOPICS, SOC_TOPIC, RUL_TOPIC)


class FaultReportError(OwMissionError):
    """The bags cannot be read for the faults section."""


def bit_names(message_class: type) -> dict[int, str]:
    """bit value -> name of the constants of an owl_msgs status message (``NONE`` left out)."""
    return {
        int(getattr(message_class, name)): name
        for name in dir(message_class)
        if name.isupper() and isinstance(getattr(message_class, name), int) and name != "NONE"
    }


@dataclass
class FaultRecording:
    """What the bags hold for the faults section.

    Attributes:
        status: topic -> (stamp s, bitmask) of every status message, in time order.
        soc: (stamp s, state of charge 0-1) of ``/battery_state_of_charge``.
        rul: (stamp s, remaining useful life s) of ``/battery_remaining_useful_life``.
    """

    status: dict[str, list[tuple[float, int]]] = field(default_factory=dict)
    soc: list[tuple[float, float]] = field(default_factory=list)
    rul: list[tuple[float, float]] = field(default_factory=list)


def read_fault_recording(bags: Sequence[Path]) -> FaultRecording:
    """Read the status topics, SOC and RUL of a run's (split) bags.

    Raises:
        FaultReportError: a bag is unreadable.
    """
    try:
        messages = read_messages(bags, TOPICS)
    except BagReadError as exc:
        msg_text = f"cannot read {[str(b) for b in bags]}: {exc}"
        raise FaultReportError(msg_text) from exc
    return fault_recording_from_messages(messages)


def fault_recording_from_messages(
    messages: Mapping[str, Sequence[tuple[int, Any]]],
) -> FaultRecording:
    """The :class:`FaultRecording` of messages read already (e.g. with the report's other topics).

    A message's time is its header stamp, or its bag time when the stamp is zero (the
    detector's first, latched status).

    Args:
        messages: topic -> (bag time ns, message) in time order, as
            :func:`ow_power.bagread.read_messages` returns for (at least) :data:`TOPICS`.
    """

    def series(topic: str) -> list[tuple[float, Any]]:
        found = []
        for bag_ns, msg in messages.get(topic, []):
            stamp = float(msg.header.stamp.sec) + 1e-9 * float(msg.header.stamp.nanosec)
            found.append((stamp if stamp > 0 else bag_ns * 1e-9, msg.value))
        return sorted(found, key=lambda item: item[0])

    recording = FaultRecording(
        soc=[(t, float(value)) for t, value in series(SOC_TOPIC)],
        rul=[(t, float(value)) for t, value in series(RUL_TOPIC)],
    )
    for topic in STATUS_TOPICS:
        status = [(t, int(value)) for t, value in series(topic)]
        if status:
            recording.status[topic] = status
    return recording


@dataclass(frozen=True)
class Detection:
    """One fault bit of one status topic over the run.

    Attributes:
        topic: the status topic.
        bit: the bit's value.
        name: its owl_msgs constant (e.g. ``HARDWARE``).
        set_s: s (sim), first time it was set.
        cleared_s: s (sim), first time it was clear again after that, or None.
    """

    topic: str
    bit: int
    name: str
    set_s: float
    cleared_s: float | None

    def to_json(self) -> dict[str, Any]:
        """One entry of ``report.json``'s ``faults.detections``."""
        return {
            "topic": self.topic,
            "bit": self.bit,
            "name": self.name,
            "set_s": self.set_s,
            "cleared_s": self.cleared_s,
        }


def detections(recording: FaultRecording) -> list[Detection]:
    """Every bit set at some time on a status topic, in order of the first time it was set."""
    found = []
    for topic, message_class in STATUS_TOPICS.items():
        series = recording.status.get(topic, [])
        for bit, name in sorted(bit_names(message_class).items()):
            set_s = next((t for t, value in series if value & bit), None)
            if set_s is None:
                continue
            cleared_s = next((t for t, value in series if t > set_s and not value & bit), None)
            found.append(Detection(topic, bit, name, set_s, cleared_s))
    return sorted(found, key=lambda d: (d.set_s, list(STATUS_TOPICS).index(d.topic), d.bit))


def _last(series: Sequence[tuple[float, float]]) -> float | None:
    return series[-1][1] if series else None


def fault_summary(document: Mapping[str, Any], recording: FaultRecording) -> dict[str, Any]:
    """``report.json``'s ``faults``: the schedule as run, the detections (each with the delay
    from the last change applied at or before it), how the mission ended, and the energy over
    the steps and the battery at the end."""
    schedule = list(document.get("fault_schedule", []))
    applied = sorted(float(f["applied_s"]) for f in schedule if f.get("applied_s") is not None)
    found = []
    for detection in detections(recording):
        entry = detection.to_json()
        before = [t for t in applied if t <= detection.set_s]
        entry["after_injection_s"] = detection.set_s - before[-1] if before else None
        found.append(entry)
    steps = list(document.get("steps", []))
    failed = next((s for s in steps if not s.get("success")), None)
    return {
        "schedule": schedule,
        "detections": found,
        "ended": {
            "success": bool(document.get("success")),
            "failed_step": None if failed is None else failed["step"],
            "message": "" if failed is None else str(failed.get("message", "")),
            "error": str(document.get("error", "")),
        },
        "end": {
            "sim_time_s": float(document.get("sim_time_s", 0.0)),
            "energy_wh": sum(float(s.get("energy_wh") or 0.0) for s in steps),
            "mechanical_energy_j": sum(float(s.get("mechanical_energy_j") or 0.0) for s in steps),
            "soc_start": recording.soc[0][1] if recording.soc else None,
            "soc": _last(recording.soc),
            "rul_s": _last(recording.rul),
        },
    }


def _fmt(value: Any, fmt: str) -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "-"
    return format(value, fmt)


def markdown_lines(faults: Mapping[str, Any]) -> list[str]:
    """The faults section of ``report.md`` from ``report.json``'s ``faults``."""
    lines = ["## Faults", ""]
    schedule = faults["schedule"]
    if not schedule:
        lines += ["No fault was scheduled (the mission file's `faults` is empty).", ""]
    else:
        lines += [
            "| injected (mission file) | due, sim s | applied, sim s | result |",
            "|---|---:|---:|---|",
        ]
        for f in schedule:
            if f.get("error"):
                result = f"REFUSED by /faults: {f['error']}"
            elif f.get("applied_s") is None:
                result = "not applied: the mission ended first"
            else:
                result = "applied"
            lines.append(
                f"| {f['description']} | {_fmt(f.get('due_s'), '.2f')} "
                f"| {_fmt(f.get('applied_s'), '.2f')} | {result} |"
            )
        lines.append("")
    if faults["detections"]:
        lines += [
            "Detected: the first simulation time each bit was set on its status topic (the "
            "detector's stamps), and when it was clear again.",
            "",
            "| topic | bit | set at, sim s | after the injection, s | cleared at, sim s |",
            "|---|---|---:|---:|---:|",
        ]
        for d in faults["detections"]:
            lines.append(
                f"| `{d['topic']}` | {d['name']} ({d['bit']}) | {d['set_s']:.2f} "
                f"| {_fmt(d.get('after_injection_s'), '.2f')} | {_fmt(d['cleared_s'], '.2f')} |"
            )
    else:
        lines.append("No fault bit was set on any status topic.")
    lines.append("")
    ended = faults["ended"]
    if ended["failed_step"] is not None:
        lines.append(f"Ended: step **{ended['failed_step']}** failed: {ended['message']}")
    elif ended["error"]:
        lines.append(f"Ended: {ended['error']}")
    else:
        lines.append("Ended: every step succeeded.")
    end = faults["end"]
    lines += [
        "",
        f"At the end (t = {end['sim_time_s']:.1f} s sim): energy with P0 over the steps "
        f"{end['energy_wh']:.4f} Wh (mechanical, signed: {end['mechanical_energy_j']:.1f} J); "
        f"state of charge {_fmt(end['soc'], '.4f')} (at the start "
        f"{_fmt(end['soc_start'], '.4f')}); remaining useful life {_fmt(end['rul_s'], '.0f')} s.",
        "",
    ]
    return lines


def plot_battery(
    recording: FaultRecording,
    faults: Mapping[str, Any],
    windows: Sequence[tuple[str, float, float]],
    png_path: Path,
) -> None:
    """SOC and RUL over the mission, the steps shaded, applied faults and detections marked."""
    plt = _pyplot()
    fig, (ax_soc, ax_rul) = plt.subplots(2, 1, sharex=True, figsize=(9, 5.5), dpi=110)
    ax_soc.plot(
        [t for t, _ in recording.soc], [100 * v for _, v in recording.soc], color="tab:blue"
    )
    ax_soc.set_ylabel("state of charge [%]")
    ax_rul.plot(
        [t for t, _ in recording.rul], [v / 3600 for _, v in recording.rul], color="tab:purple"
    )
    ax_rul.set_ylabel("remaining useful life [h]")
    ax_rul.set_xlabel("simulation time [s]")
    for ax in (ax_soc, ax_rul):
        for i, (_, start, end) in enumerate(windows):
            ax.axvspan(start, end, color="0.9" if i % 2 else "0.8", lw=0)
        for f in faults["schedule"]:
            if f.get("applied_s") is not None and not f.get("error"):
                ax.axvline(f["applied_s"], color="tab:red", lw=1.2, ls="--")
        for d in faults["detections"]:
            ax.axvline(d["set_s"], color="tab:orange", lw=1.0, ls=":")
        ax.grid(alpha=0.3)
    for name, start, end in windows:
        ax_soc.annotate(
            name,
            ((start + end) / 2, 1.0),
            xycoords=("data", "axes fraction"),
            ha="center",
            va="bottom",
            fontsize=6,
        )
    fig.suptitle(
        "Battery over the mission (red dashed: fault applied; orange dotted: detected)",
        fontsize=9,
    )
    fig.tight_layout()
    fig.savefig(png_path, dpi=fig.dpi)  # not rcParams: progpy.visualize sets 300 on import
    plt.close(fig)
