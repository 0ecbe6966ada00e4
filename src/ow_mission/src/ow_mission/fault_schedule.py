"""A mission's fault schedule (the mission file's ``faults`` key), validated at load time, no ROS.

Each entry changes ``/faults`` parameters (OceanWATERS' names, checked by
:class:`ow_faults.injection.FaultSet`) at a simulation time: ``at_time_s`` from the start of the
simulation, or ``after_s`` (default 0) after the start of step ``at_step``::

    faults:
      - {at_step: grind, after_s: 3.0, set: {shou_pitch_joint_locked_failure: true}}
      - {at_time_s: 120.0, set: {high_power_draw: 200.0, activate_high_power_draw: true}}

:class:`ScheduleTimer` says which entries are due from the simulation time and the steps'
starts; :class:`AppliedFault` is what the run did with one (``report.json``'s
``fault_schedule``). ``ow_mission.fault_schedule_node`` applies them through ``/faults``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

from ow_faults.errors import FaultError
from ow_faults.injection import FaultSet
from ow_runtime.params import suggest

#: The mission's steps, in order (``ow_mission.mission.STEPS``; a unit test checks they agree).
MISSION_STEPS = (
    "unstow",
    "guarded_move",
    "grind",
    "dig_spoil",
    "discard_spoil",
    "grind_bottom",
    "dig_sample",
    "deliver_sample",
    "stow",
)
#: The keys of one entry.
ENTRY_KEYS = ("at_step", "after_s", "at_time_s", "set")


@dataclass(frozen=True)
class ScheduledFault:
    """One change of the fault parameters.

    Attributes:
        changes: parameter -> value (each checked against ``cfg/Faults.cfg``'s type and range).
        at_step: the step at whose start it is due, or None (``at_time_s``).
        after_s: s of simulation time after the step's start.
        at_time_s: s of simulation time from the start of the simulation, or None (``at_step``).
    """

    changes: dict[str, Any] = field(default_factory=dict)
    at_step: str | None = None
    after_s: float = 0.0
    at_time_s: float | None = None

    def due_s(self, step_starts: Mapping[str, float]) -> float | None:
        """s (sim) at which it is due, given the start of each step so far (None: its step has
        not started)."""
        if self.at_time_s is not None:
            return self.at_time_s
        start = step_starts.get(str(self.at_step))
        return None if start is None else start + self.after_s

    def describe(self) -> str:
        """E.g. ``shou_pitch_joint_locked_failure: true at grind + 3.0 s``."""
        what = ", ".join(f"{k}: {_yaml(v)}" for k, v in self.changes.items())
        when = (
            f"at t = {self.at_time_s:g} s"
            if self.at_time_s is not None
            else f"at {self.at_step} + {self.after_s:g} s"
        )
        return f"{what} {when}"


def _yaml(value: Any) -> str:
    return str(value).lower() if isinstance(value, bool) else repr(value)


def _number(value: Any) -> float | None:
    ok = isinstance(value, int | float) and not isinstance(value, bool)
    return float(value) if ok and math.isfinite(value) and value >= 0 else None


def parse_schedule(
    raw: Any, steps: Iterable[str], problem: Callable[[str], None]
) -> tuple[ScheduledFault, ...]:
    """The schedule of a mission file's ``faults`` value; each problem is passed to
    ``problem`` with a message naming the key and value (``mission/faults[0]/set: ...``), and
    the bad entry left out.

    Args:
        raw: the ``faults`` value (a list of mappings).
        steps: the mission's step names.
        problem: collects a problem.
    """
    if not isinstance(raw, list):
        problem(f"mission/faults must be a list of entries, got {raw!r}")
        return ()
    names = list(steps)
    schedule = []
    for i, entry in enumerate(raw):
        key = f"mission/faults[{i}]"
        if not isinstance(entry, Mapping):
            problem(f"{key} must be a mapping ({', '.join(ENTRY_KEYS)}), got {entry!r}")
            continue
        bad = [k for k in entry if k not in ENTRY_KEYS]
        for k in bad:
            problem(f"unknown key '{key}/{k}'{suggest(str(k), list(ENTRY_KEYS))}")
        parsed = _entry(key, entry, names, problem)
        if parsed is not None and not bad:
            schedule.append(parsed)
    return tuple(schedule)


def _entry(
    key: str, entry: Mapping[str, Any], steps: list[str], problem: Callable[[str], None]
) -> ScheduledFault | None:
    changes = entry.get("set")
    if not isinstance(changes, Mapping) or not changes:
        problem(f"{key}/set must map fault parameters to values, got {changes!r}")
        return None
    try:
        FaultSet().changed(changes)
    except FaultError as error:
        problem(f"{key}/set: {error}")
        return None
    step, time_s = entry.get("at_step"), entry.get("at_time_s")
    if (step is None) == (time_s is None):
        problem(f"{key} needs exactly one of at_step and at_time_s, got {dict(entry)!r}")
        return None
    if time_s is not None:
        at_time = _number(time_s)
        if at_time is None or "after_s" in entry:
            problem(f"{key}/at_time_s = {time_s!r} must be a number >= 0 s (without after_s)")
            return None
        return ScheduledFault(dict(changes), at_time_s=at_time)
    if step not in steps:
        problem(
            f"{key}/at_step = {step!r} is not a step of the mission (steps: "
            f"{', '.join(steps)}){suggest(str(step), steps)}"
        )
        return None
    after = _number(entry.get("after_s", 0.0))
    if after is None:
        problem(f"{key}/after_s = {entry.get('after_s')!r} must be a number >= 0 s")
        return None
    return ScheduledFault(dict(changes), at_step=str(step), after_s=after)


@dataclass
class AppliedFault:
    """What a run did with one entry of its schedule (``report.json``'s ``fault_schedule``).

    Attributes:
        index: the entry's index in the mission file's ``faults`` list.
        description: :meth:`ScheduledFault.describe`.
        changes: parameter -> value sent to ``/faults``.
        due_s: s (sim) at which it was due; None when it never came due (its step never
            started, or the mission ended first).
        applied_s: s (sim) from which it holds: its due time when the simulation was held
            for it (the lockstep), else the clock when the ``/faults`` server had accepted
            it; None when not applied.
        error: why the server refused it ("" when it did not).
    """

    index: int
    description: str
    changes: dict[str, Any]
    due_s: float | None = None
    applied_s: float | None = None
    error: str = ""

    @property
    def applied(self) -> bool:
        """True when the server accepted the change."""
        return self.applied_s is not None and not self.error

    def to_json(self) -> dict[str, Any]:
        """One entry of ``report.json``'s ``fault_schedule``."""
        return {
            "index": self.index,
            "description": self.description,
            "changes": dict(self.changes),
            "due_s": self.due_s,
            "applied_s": self.applied_s,
            "error": self.error,
        }


class ScheduleTimer:
    """Which entries of a schedule are due, from the simulation time and the steps' starts.

    Each entry comes due once: :meth:`due` hands it out at the first time it is called with a
    time at or after the entry's due time, in order of due time (then of the file).

    Args:
        schedule: the mission's entries, in the file's order.
    """

    def __init__(self, schedule: Iterable[ScheduledFault]) -> None:
        self.schedule = tuple(schedule)
        self._starts: dict[str, float] = {}
        self._handed: set[int] = set()

    def step_started(self, step: str, start_s: float) -> None:
        """Note the start (s, sim) of ``step``; a step run twice keeps its first start."""
        self._starts.setdefault(step, start_s)

    def due(self, now_s: float) -> list[tuple[int, ScheduledFault, float]]:
        """(index, entry, due s) of the entries due at or before ``now_s`` (s, sim) not handed
        out yet, earliest first; they are not handed out again."""
        ready = []
        for index, entry in enumerate(self.schedule):
            due_s = entry.due_s(self._starts)
            if index not in self._handed and due_s is not None and due_s <= now_s:
                ready.append((due_s, index, entry))
        ready.sort(key=lambda item: (item[0], item[1]))
        self._handed.update(index for _, index, _ in ready)
        return [(index, entry, due_s) for due_s, index, entry in ready]

    def next_due_s(self) -> float | None:
        """s (sim), the earliest due time of the entries not handed out yet whose time is known
        (an ``at_step`` entry's once its step has started); None when there is none."""
        times = [
            due_s
            for index, entry in enumerate(self.schedule)
            if index not in self._handed and (due_s := entry.due_s(self._starts)) is not None
        ]
        return min(times, default=None)

    def never_due(self) -> list[AppliedFault]:
        """The entries not handed out (the run ended first), as not applied."""
        return [
            AppliedFault(index, entry.describe(), dict(entry.changes))
            for index, entry in enumerate(self.schedule)
            if index not in self._handed
        ]
