"""Read a run's closed bag files while the run is still ending (its stack stopping), so that the
report afterwards reads only the files closed since. No ROS.

The recorder splits its bags by time and size, and each split file is complete once it is
renamed from ``.bag.active`` to ``.bag``. Stopping the stack is mostly waiting for processes to
exit, with a core to spare: :class:`BagPrefetch` reads the files closed by then in a thread
meanwhile, and :meth:`BagPrefetch.messages` adds the rest
(:func:`ow_power.bagread.merge_messages`): the same messages as one pass over every file.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Sequence
from pathlib import Path

from ow_power.bagread import TopicMessages, merge_messages

#: Reads bag files (in recording order) into messages per topic, e.g.
#: :func:`ow_mission.report.read_report_messages`.
Reader = Callable[[Sequence[Path]], TopicMessages]


class BagPrefetch:
    """The messages of a run's bag files, the files already closed read in a thread.

    Args:
        bag_dir: the run's bag directory.
        read: what reads files into messages.
    """

    def __init__(self, bag_dir: Path, read: Reader) -> None:
        self._read = read
        self.files = sorted(Path(bag_dir).glob("*.bag"))
        self._messages: TopicMessages | None = None
        self._thread = threading.Thread(target=self._prefetch, name="bag_prefetch", daemon=True)
        self._thread.start()

    def _prefetch(self) -> None:
        try:
            self._messages = self._read(self.files)
        except Exception:  # read again in messages(), where the error reaches the report
            self._messages = None

    def messages(self, bags: Sequence[Path]) -> TopicMessages:
        """What ``read(bags)`` gives: the prefetched files' messages with those of the rest of
        ``bags``; every file read again when the prefetch failed or ``bags`` does not begin
        with the files it read. The prefetched messages are handed over, not kept (the caller
        may free them; a second call reads every file).

        Raises:
            whatever ``read`` raises for ``bags``.
        """
        self._thread.join()
        done = len(self.files)
        prefetched, self._messages = self._messages, None
        if prefetched is None or [Path(b) for b in bags[:done]] != self.files:
            return self._read(bags)
        return merge_messages(prefetched, self._read(bags[done:]))
