"""The bag files closed before a run ends, read while it ends (ow_mission.bag_prefetch): the
report gets the same messages as from one pass over every file. No ROS."""

from __future__ import annotations

import shutil
import weakref
from datetime import datetime
from pathlib import Path

from ow_mission.bag_prefetch import BagPrefetch
from ow_power.bagread import read_messages
from ow_power.synthetic import write_split_series

TOPICS = ("/a", "/state")


def _split_run(directory: Path) -> list[Path]:
    return write_split_series(directory, datetime(2025, 1, 2, 3, 4, 5))


def _values(found):
    return {topic: [(ns, msg.data) for ns, msg in series] for topic, series in found.items()}


def read(bags):
    return read_messages(bags, TOPICS)


def test_files_closed_later_are_read_after_and_merged(tmp_path):
    made = _split_run(tmp_path / "made")
    run = tmp_path / "run"
    run.mkdir()
    for path in made[:2]:
        shutil.copy(path, run)
    calls: list[list[str]] = []

    def reading(bags):
        calls.append([p.name for p in bags])
        return read(bags)

    prefetch = BagPrefetch(run, reading)
    shutil.copy(made[2], run)  # the recorder closes its last file as the stack stops
    bags = sorted(run.glob("*.bag"))
    assert _values(prefetch.messages(bags)) == _values(read(bags))
    assert calls == [[p.name for p in made[:2]], [made[2].name]]  # each file read once


def test_a_failed_prefetch_or_other_files_are_read_again(tmp_path):
    made = _split_run(tmp_path)
    calls: list[list[str]] = []

    def failing_once(bags):
        calls.append([p.name for p in bags])
        if len(calls) == 1:
            raise OSError("disk went away")
        return read(bags)

    prefetch = BagPrefetch(tmp_path, failing_once)
    assert _values(prefetch.messages(made)) == _values(read(made))
    assert calls == [[p.name for p in made]] * 2
    other = BagPrefetch(tmp_path, read)
    assert _values(other.messages(made[1:])) == _values(read(made[1:]))


class _Marker:
    """A message stand-in that can be watched for being freed."""


def test_the_prefetched_messages_are_handed_over_not_kept(tmp_path):
    # The report frees the high-rate topics before it forks its renderers: a prefetch holding
    # them kept ~100 MB alive in the default mission's report.
    made = _split_run(tmp_path)
    calls: list[list[str]] = []

    def reading(bags):
        calls.append([p.name for p in bags])
        return {"/a": [(0, _Marker())]} if len(bags) == len(made) else {"/a": []}

    prefetch = BagPrefetch(tmp_path, reading)
    messages = prefetch.messages(made)
    marker = weakref.ref(messages["/a"][0][1])
    del messages
    assert marker() is None  # nothing else held the prefetched message
    prefetch.messages(made)  # a second call reads every file again
    every = [p.name for p in made]
    assert calls == [every, [], every]  # the prefetch, the files closed since (none), again
