"""The messages of chosen topics of a run's (split) ROS 1 bags, read in one pass (rosbags, no ROS).

A run's report needs a dozen topics of the same bags for its power figures, its replay and its
faults section: :func:`read_messages` opens each file once, parses each message type's definition
once for the whole run (the definitions in the bags, so any type reads without generated
messages), deserialises the messages of the wanted topics only (the joint states and the power
with :mod:`ow_power.bagdecode`'s faster decoders) and returns them per topic::

    from ow_power.bagread import read_messages

    messages = read_messages(sorted(Path("runs/today/bags").glob("*.bag")), [POWER])
    for bag_ns, msg in messages[POWER]:
        print(bag_ns, msg.total_power)

Each topic's messages are in bag-time order; messages at the same bag time keep the order of the
files, then the order in their file. A latched message the recorder wrote again at the start of
each later split file (:class:`ow_power.bagwriter.SplitBagWriter`) is returned once per file,
at that file's time, as rosbags' ``AnyReader`` returns it.
"""

from __future__ import annotations

import struct
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

from rosbags.interfaces import Connection
from rosbags.rosbag1 import Reader, ReaderError
from rosbags.serde import SerdeError
from rosbags.typesys import Stores, TypesysError, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore

from ow_power.bagdecode import Decoder, fast_decoder
from ow_power.errors import BagReadError

#: topic -> (bag time ns, deserialised message) of each of its messages, in time order.
TopicMessages = dict[str, list[tuple[int, Any]]]


class _Types:
    """One typestore for a whole run: each message type's definition is parsed once."""

    def __init__(self) -> None:
        self.store: Typestore = get_typestore(Stores.EMPTY)
        #: msgtype -> MD5 of the definition registered for it.
        self.md5: dict[str, str] = {}
        #: msgtype -> its fast decoder (:mod:`ow_power.bagdecode`), None: rosbags' deserialiser.
        self.decoders: dict[str, Decoder | None] = {}

    def register(self, connection: Connection, path: Path) -> None:
        """Know ``connection``'s type, checked against its MD5.

        Raises:
            BagReadError: the definition does not parse or match its MD5, or an earlier bag of
                the run had another definition of the same type.
        """
        known = self.md5.get(connection.msgtype)
        if known is None:
            self.store.register(get_types_from_msg(connection.msgdef.data, connection.msgtype))
            _, md5 = self.store.generate_msgdef(connection.msgtype)
            if md5 != connection.digest:
                msg = (
                    f"{path}: the definition of {connection.msgtype} on {connection.topic} has "
                    f"MD5 {md5}, the bag says {connection.digest}"
                )
                raise BagReadError(msg)
            self.md5[connection.msgtype] = md5
            self.decoders[connection.msgtype] = fast_decoder(self.store, connection.msgtype)
        elif known != connection.digest:
            msg = (
                f"{path}: {connection.topic} has {connection.msgtype} with MD5 "
                f"{connection.digest}, an earlier bag of the run has {known}"
            )
            raise BagReadError(msg)


def read_messages(bags: Sequence[Path | str], topics: Iterable[str]) -> TopicMessages:
    """Read the messages of ``topics`` from ``bags``, each file opened once.

    Args:
        bags: the run's bag files, in recording order (split files are consecutive in time).
        topics: topic names, e.g. ``/joint_states``.

    Returns:
        Every topic of ``topics`` -> ``(bag time ns, message)`` of each of its messages, in
        bag-time order (stable: equal times keep file order, then order within the file); an
        empty list for a topic no bag has. Messages are rosbags' message dataclasses.

    Raises:
        BagReadError: a file is missing, not a readable ROS 1 bag, or holds a message that does
            not deserialise with its connection's definition; the message names the file.
    """
    messages: TopicMessages = {topic: [] for topic in topics}
    types = _Types()
    for raw_path in bags:
        path = Path(raw_path)
        try:
            with Reader(path) as reader:
                connections = [c for c in reader.connections if c.topic in messages]
                for connection in connections:
                    types.register(connection, path)
                if not connections:  # an empty selection would mean every connection
                    continue
                deserialize, decoders = types.store.deserialize_ros1, types.decoders
                for connection, bag_ns, data in reader.messages(connections=connections):
                    decode = decoders[connection.msgtype]
                    msg = deserialize(data, connection.msgtype) if decode is None else decode(data)
                    messages[connection.topic].append((bag_ns, msg))
        except BagReadError:
            raise
        # rosbags asserts on some damaged index records; struct.error is a truncated message.
        except (
            ReaderError,
            SerdeError,
            TypesysError,
            OSError,
            ValueError,
            KeyError,
            AssertionError,
            struct.error,
        ) as exc:
            msg = f"cannot read {path}: {type(exc).__name__}: {exc}"
            raise BagReadError(msg) from exc
    for series in messages.values():
        series.sort(key=lambda item: item[0])
    return messages


def merge_messages(earlier: TopicMessages, later: TopicMessages) -> TopicMessages:
    """The messages :func:`read_messages` gives for bags ``A + B`` from its results for ``A``
    (``earlier``) and for ``B`` (``later``), on the same topics: each topic's messages in
    bag-time order, equal times keeping ``A``'s before ``B``'s (as one pass keeps the files'
    order). A run's closed split files can so be read before its last one is closed."""
    merged: TopicMessages = {}
    for topic in {*earlier, *later}:
        series = [*earlier.get(topic, []), *later.get(topic, [])]
        series.sort(key=lambda item: item[0])
        merged[topic] = series
    return merged
