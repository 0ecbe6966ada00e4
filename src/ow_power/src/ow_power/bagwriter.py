"""A ROS 1 bag writer that splits a run into closed files, free of ROS (rosbags only).

A run is a sequence of bags ``<prefix>_<start>_<index>.bag`` (``<start>`` the wall-clock start
time, ``YYYY-mm-dd-HH-MM-SS``; ``<index>`` 0000, 0001, ...). The file being written is named
``....bag.active`` and renamed to ``....bag`` once closed and indexed, so every ``.bag`` of a run
is complete and readable by ``rosbag`` and rosbags, and a hard kill loses only the open file.
A file is closed when its messages span ``split_duration_s`` of message time (messages stamped
0, received before the simulation clock started, do not open that window) or hold
``split_size_mb`` of data, and on :meth:`SplitBagWriter.close`. Nothing is ever overwritten: a run
whose name is taken gets a ``-1``, ``-2``... suffix, and rosbags opens files exclusively.

Messages arrive serialised (ROS 1 wire format) with their type, MD5 and full definition, exactly
what a ROS subscriber's connection header gives, so any message type is recorded unchanged.
Messages of latched publishers (``/tf_static``, ``/robot_description``, markers) are flagged
``latching=1`` in the bag's connection header, as ``rosbag record`` does, and the last one of each
(topic, publisher) is written again at the start of every later file of the run, so that each file
replays on its own with the robot, its static frames and the terrain.
"""

from __future__ import annotations

import functools
import os
import re
import struct
import threading
from collections.abc import Callable
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path

from rosbags.interfaces import Connection
from rosbags.rosbag1 import Writer, WriterError
from rosbags.rosbag1.reader import RecordType
from rosbags.rosbag1.writer import WriteChunk
from rosbags.typesys.msg import normalize_msgtype

from ow_power.errors import RecorderError

#: Suffix of the bag being written; it becomes ``.bag`` when the file is closed.
ACTIVE_SUFFIX = ".active"


#: The first field of a message definition, after comments and constants.
_FIRST_FIELD = re.compile(r"^\s*([\w/]+)(\[\d*\])?\s+(\w+)\s*$")
_STAMP = struct.Struct("<II")
#: Field types that are not messages.
_BUILTIN_TYPES = frozenset(
    (
        *(f"{kind}{bits}" for kind in ("int", "uint") for bits in (8, 16, 32, 64)),
        "float32",
        "float64",
        "string",
        "bool",
        "time",
        "duration",
        "byte",
        "char",
    )
)
_U32 = struct.Struct("<I")


def _first_field(definition: str) -> tuple[str, str | None] | None:
    """(type, array suffix or None) of the first field of one message's definition (its own
    part of a full definition), or None when it has none."""
    for line in definition.splitlines():
        text = line.split("#", 1)[0].strip()
        if not text:
            continue
        if text.startswith("=" * 10):  # the definitions of nested types begin
            return None
        field = _FIRST_FIELD.match(text)
        if field is None:  # a constant (``uint8 ADD=0``)
            continue
        return field.group(1), field.group(2)
    return None


def _is_header(field: tuple[str, str | None] | None) -> bool:
    return field is not None and field[0] in ("Header", "std_msgs/Header") and field[1] is None


@functools.lru_cache(maxsize=256)
def starts_with_header(msgdef: str) -> bool:
    """True when the message's first field is a ``std_msgs/Header`` (``Header header``).

    Remembered per definition: the recorder asks for every message, and reading the definition
    was a third of its time per message (a process sees a few dozen definitions).

    Args:
        msgdef: the full message definition, as in the connection header.
    """
    return _is_header(_first_field(msgdef))


@functools.lru_cache(maxsize=256)
def stamp_offset(msgdef: str) -> int:
    """Where a message's stamp is in its wire format: 4 (bytes, after ``header.seq``) when
    its first field is a Header; 8 when it is a list of messages that each start with a Header
    (``tf2_msgs/TFMessage``, ``visualization_msgs/MarkerArray``: the first one's stamp, after
    the list's length and its ``seq``); 0 when it has no stamp there.

    Args:
        msgdef: the full message definition, as in the connection header.
    """
    first = _first_field(msgdef)
    if _is_header(first):
        return 4
    if first is None or first[1] != "[]" or first[0] in _BUILTIN_TYPES:
        return 0
    name = first[0].rpartition("/")[2]
    for section in msgdef.split("\nMSG: ")[1:]:
        type_name, _, definition = section.partition("\n")
        if type_name.strip().rpartition("/")[2] == name:
            return 8 if _is_header(_first_field(definition)) else 0
    return 0


def header_stamp_ns(data: bytes) -> int:
    """ns, ``header.stamp`` of a serialised message whose first field is a Header.

    The wire format starts with the header's ``uint32 seq``, ``uint32 secs``, ``uint32 nsecs``.

    Raises:
        RecorderError: ``data`` is too short to hold a header.
    """
    if len(data) < 12:
        msg = f"a message of {len(data)} bytes cannot start with a Header (12 bytes at least)"
        raise RecorderError(msg)
    secs, nsecs = _STAMP.unpack_from(data, 4)
    return secs * 1_000_000_000 + nsecs


def record_time_ns(msgdef: str, data: bytes, arrival_ns: int, zero_is_a_time: bool = False) -> int:
    """ns, the bag time of a message: its stamp (:func:`stamp_offset`: ``header.stamp``, or
    the first transform's or marker's of a list of them) when it has one and it is set, else
    ``arrival_ns`` (the receipt time on the ROS clock).

    Stamps keep the times of a batch the simulation sends at once (its physics steps) instead
    of clumping them at the arrival time, and put ``/tf`` in the bag where its transforms hold
    (a viewer replaying the bag gets the robot's frames with its joint states): the recorder
    receives the simulation's outputs up to 0.5 s of sim time after they hold, and its clock
    ticks at 10 Hz in a mission.

    Args:
        msgdef: the full message definition, as in the connection header.
        data: the message in ROS 1 wire format.
        arrival_ns: ns, when the message arrived (simulation clock).
        zero_is_a_time: a stamp of 0 is a time (on simulation time: its start, e.g. the first
            joint state's and its ``/power``), not a stamp left unset. Taken as unset, the first
            ``/power`` went in at its arrival, which depended on the load (0 or 0.5 s).

    Raises:
        RecorderError: a message declared with a Header is too short to hold one.
    """
    offset = stamp_offset(msgdef)
    if offset == 4:
        stamp_ns = header_stamp_ns(data)
    elif offset == 8 and len(data) >= 16 and _U32.unpack_from(data, 0)[0] > 0:
        secs, nsecs = _STAMP.unpack_from(data, 8)
        stamp_ns = secs * 1_000_000_000 + nsecs
    else:
        return arrival_ns
    return stamp_ns if stamp_ns or zero_is_a_time else arrival_ns


def run_name(directory: Path, prefix: str, start: datetime) -> str:
    """A run name ``<prefix>_<YYYY-mm-dd-HH-MM-SS>[-n]`` no file in ``directory`` starts with.

    Args:
        directory: where the bags go.
        prefix: first part of the name.
        start: wall-clock start of the run.
    """
    base = f"{prefix}_{start:%Y-%m-%d-%H-%M-%S}"
    name, n = base, 0
    while any(directory.glob(f"{name}_*")):
        n += 1
        name = f"{base}-{n}"
    return name


def _message_record_start(connection_id: int) -> bytes:
    """The bytes of a message data record up to its time: the record header's length (38),
    then its fields ``op`` (2: message data), ``conn`` and the name of ``time``, each with its
    length, as rosbags' ``Header.write`` orders them."""
    return b"".join(
        (
            _U32.pack(38),
            _U32.pack(4) + b"op=" + bytes([RecordType.MSGDATA]),
            _U32.pack(9) + b"conn=" + _U32.pack(connection_id),
            _U32.pack(13) + b"time=",
        )
    )


class _Writer(Writer):
    """rosbags' writer, writing the same bytes with less work per message and memory.

    - A message's record is written from bytes made once per connection: rosbags built a
      record header (a dict, each field formatted) for every message and looked the connection
      up by equality in the list of connections, 8.5 us a message with 20 topics.
    - Of each chunk written to the file it keeps only what the bag's index needs at the end,
      the message count per connection. rosbags keeps a (time, offset) pair for every message
      until the file is closed, though the chunk's index records are written right after the
      chunk: a recorder of a whole mission (300 000 messages) grew by about 50 MB. The index
      at the close reads only ``len()`` of each connection's entries, which a ``range`` of
      that length gives.
    """

    def __init__(self, path: Path) -> None:
        super().__init__(path)
        #: connection id -> (the connection, the start of its message records)
        self._records: dict[int, tuple[Connection, bytes]] = {}

    def write(self, connection: Connection, timestamp: int, data: bytes | memoryview) -> None:
        """Append one message (``timestamp`` ns) of ``connection``, as rosbags does."""
        known = self._records.get(connection.id)
        if known is None or known[0] is not connection or not self.bio:
            super().write(connection, timestamp, data)  # checks it, and the file, once
            self._records[connection.id] = (connection, _message_record_start(connection.id))
            return
        chunk = self.chunks[-1]
        out = chunk.data
        chunk.connections[connection.id].append((timestamp, out.tell()))
        chunk.start = min(timestamp, chunk.start)
        chunk.end = max(timestamp, chunk.end)
        seconds, nanoseconds = divmod(timestamp, 1_000_000_000)
        out.write(known[1] + _STAMP.pack(seconds, nanoseconds) + _U32.pack(len(data)))
        out.write(data)
        if out.tell() > self.chunk_threshold:
            self.write_chunk(chunk)

    def write_chunk(self, chunk: WriteChunk) -> None:
        super().write_chunk(chunk)
        if chunk.pos != -1:  # written, its index records with it
            for cid, items in chunk.connections.items():
                chunk.connections[cid] = range(len(items))  # type: ignore[assignment]


@dataclass(frozen=True)
class _Message:
    """One serialised message and its connection (what :meth:`SplitBagWriter.write` takes)."""

    topic: str
    msgtype: str
    md5sum: str
    msgdef: str
    callerid: str
    latching: bool
    data: bytes


class SplitBagWriter:
    """Writes one run of serialised messages into consecutive, individually closed bag files.

    Thread-safe: :meth:`write` and :meth:`close` take one lock, so subscriber threads may call
    :meth:`write` while a signal handler's thread calls :meth:`close`.
    """

    def __init__(
        self,
        directory: Path | str,
        prefix: str = "ow",
        split_duration_s: float = 0.0,
        split_size_mb: float = 0.0,
        compression: str = "none",
        start: datetime | None = None,
        on_closed: Callable[[Path], None] | None = None,
    ) -> None:
        """Prepare a run; the first file is created by the first message.

        Args:
            directory: directory of the bags (created if missing).
            prefix: first part of every file name.
            split_duration_s: s of message time per file; 0 means no limit.
            split_size_mb: MB (1e6 bytes) of serialised messages per file; 0 means no limit.
            compression: ``none`` or ``bz2``.
            start: wall-clock time in the run name (default: now).
            on_closed: called with the path of every bag once it is closed and renamed.

        Raises:
            RecorderError: the directory cannot be created, or the compression is unknown.
        """
        self.directory = Path(directory)
        try:
            self.directory.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            msg = f"cannot create the bag directory {self.directory}: {exc}"
            raise RecorderError(msg) from exc
        if compression not in ("none", "bz2"):
            msg = f"compression {compression!r} is not 'none' or 'bz2'"
            raise RecorderError(msg)
        self.name = run_name(self.directory, prefix, start or datetime.now())
        self.split_duration_ns = int(split_duration_s * 1e9)
        self.split_size_bytes = int(split_size_mb * 1e6)
        self.compression = compression
        self.on_closed = on_closed
        #: Bags closed so far, in order.
        self.closed_files: list[Path] = []
        self._lock = threading.Lock()
        self._index = 0
        self._writer: _Writer | None = None
        self._connections: dict[tuple[str, str, str, str, bool], Connection] = {}
        #: The last message of each latched (topic, publisher), repeated in every new file.
        self._latched: dict[tuple[str, str], _Message] = {}
        #: ns, bag time of the latched messages repeated at the start of the open file (0: none).
        self._repeated_ns = 0
        self._file_start_ns = 0
        self._file_bytes = 0
        self._closed = False

    @property
    def active_path(self) -> Path | None:
        """The file being written (``.bag.active``), or None between files."""
        writer = self._writer
        return None if writer is None else writer.path

    def write(
        self,
        topic: str,
        msgtype: str,
        md5sum: str,
        msgdef: str,
        stamp_ns: int,
        data: bytes,
        latching: bool = False,
        callerid: str = "",
    ) -> bool:
        """Append one serialised message.

        Args:
            topic: topic name, e.g. ``/joint_states``.
            msgtype: ROS 1 type, ``pkg/Type`` (``pkg/msg/Type`` accepted too).
            md5sum: the type's MD5, as in the connection header.
            msgdef: the full message definition, as in the connection header.
            stamp_ns: ns, the bag time of the message (simulation clock).
            data: the message in ROS 1 wire format.
            latching: the publisher latches the topic (connection header ``latching: 1``): the
                connection is flagged so, and the message is repeated at the start of each
                later file until the same publisher sends another. A latched message stamped
                before the repeated copies of the open file is written at their time, after
                them, so that reading a file in time order ends with the latest state.
            callerid: the publishing node (connection header ``callerid``); "" leaves it out.

        Returns:
            False when the writer is closed already (the message is dropped), else True.

        Raises:
            RecorderError: a file cannot be created or written.
        """
        message = _Message(topic, msgtype, md5sum, msgdef, callerid, latching, data)
        with self._lock:
            if self._closed:
                return False
            if self._writer is not None and self._file_full(stamp_ns):
                self._close_file()
            if self._writer is None:
                self._open_file(stamp_ns)
                # Each file replays on its own: the latched state first, at the file's start.
                for repeated in self._latched.values():
                    if (repeated.topic, repeated.callerid) != (topic, callerid):
                        self._append(repeated, stamp_ns)
                        self._repeated_ns = stamp_ns
            if latching:
                # A latched message stamped before this file's repeated copies is newer than
                # they are: it must not be read back before them.
                stamp_ns = max(stamp_ns, self._repeated_ns)
            if self._file_start_ns == 0:
                # Stamp 0 means the simulation clock had not started: the window opens later.
                self._file_start_ns = stamp_ns
            if latching:
                self._latched[(topic, callerid)] = message
            self._append(message, stamp_ns)
            return True

    def _append(self, message: _Message, stamp_ns: int) -> None:
        writer = self._writer
        assert writer is not None
        key = (message.topic, message.msgtype, message.md5sum, message.callerid, message.latching)
        connection = self._connections.get(key)
        try:
            if connection is None:
                connection = writer.add_connection(
                    message.topic,
                    normalize_msgtype(message.msgtype),
                    msgdef=message.msgdef,
                    md5sum=message.md5sum,
                    callerid=message.callerid or None,
                    latching=1 if message.latching else None,
                )
                self._connections[key] = connection
            writer.write(connection, stamp_ns, message.data)
        except (WriterError, OSError) as exc:
            msg = f"cannot write {message.topic} to {writer.path}: {exc}"
            raise RecorderError(msg) from exc
        self._file_bytes += len(message.data)

    def close(self) -> list[Path]:
        """Close and rename the open file; later :meth:`write` calls drop their message.

        Returns:
            Every bag of the run, in order.

        Raises:
            RecorderError: the open file cannot be closed or renamed (it stays as ``.active``).
        """
        with self._lock:
            self._closed = True
            if self._writer is not None:
                self._close_file()
            return list(self.closed_files)

    def _file_full(self, stamp_ns: int) -> bool:
        by_time = (
            self.split_duration_ns > 0 and stamp_ns - self._file_start_ns >= self.split_duration_ns
        )
        by_size = self.split_size_bytes > 0 and self._file_bytes >= self.split_size_bytes
        return by_time or by_size

    def _open_file(self, stamp_ns: int) -> None:
        final = self.directory / f"{self.name}_{self._index:04d}.bag"
        active = final.with_name(final.name + ACTIVE_SUFFIX)
        if final.exists():
            msg = f"{final} exists already, not overwriting"
            raise RecorderError(msg)
        writer = _Writer(active)
        if self.compression == "bz2":
            writer.set_compression(Writer.CompressionFormat.BZ2)
        try:
            writer.open()
        except (WriterError, OSError) as exc:
            msg = f"cannot create bag {active}: {exc}"
            raise RecorderError(msg) from exc
        self._writer = writer
        self._connections = {}
        self._repeated_ns = 0
        self._file_start_ns = stamp_ns
        self._file_bytes = 0
        self._index += 1

    def _close_file(self) -> None:
        writer, self._writer = self._writer, None
        assert writer is not None
        active = writer.path
        final = active.with_name(active.name.removesuffix(ACTIVE_SUFFIX))
        try:
            writer.close()
            # link + unlink instead of rename: link fails rather than replace an existing bag.
            os.link(active, final)
            os.unlink(active)
        except (WriterError, OSError) as exc:
            msg = f"cannot close {active} as {final}: {exc}; the data stays in {active}"
            raise RecorderError(msg) from exc
        self.closed_files.append(final)
        if self.on_closed is not None:
            self.on_closed(final)
