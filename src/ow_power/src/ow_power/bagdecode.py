"""Fast decoding of the run's high-rate message types from their ROS 1 bytes (rosbags' types).

A run's bags hold some 33 000 ``/joint_states`` and as many ``/power`` messages, and rosbags'
general deserialiser takes about 50 us for each (a check and a decode per joint name, a nested
dataclass per header). :func:`fast_decoder` makes a decoder for a type made only of a
``std_msgs/Header``, ``string[]``, ``float64[]`` and ``float64`` fields (both of those types,
whatever their order): it returns the same rosbags dataclass with the same values, decodes the
names once per distinct list of names, and reads each ``float64[]`` as one numpy view of the
bytes, as rosbags does. Tests compare it with rosbags' own deserialiser field by field.
"""

from __future__ import annotations

import struct
from collections.abc import Callable
from typing import Any

import numpy as np
from rosbags.interfaces import Nodetype
from rosbags.typesys.store import Typestore

_U32 = struct.Struct("<I")
_HEADER = struct.Struct("<3I")  # seq, stamp sec, stamp nanosec
_HEADER_TYPE = "std_msgs/msg/Header"
_TIME_TYPE = "builtin_interfaces/msg/Time"
_FLOAT64 = np.dtype("<f8")

#: A decoder: the ROS 1 bytes of one message -> rosbags' dataclass of it.
Decoder = Callable[[bytes], Any]


def _kind(field_type: tuple[Any, Any]) -> str | None:
    """ "header", "strings", "doubles" or "double" for the field types this module decodes."""
    node, detail = field_type
    if node == Nodetype.NAME and detail == _HEADER_TYPE:
        return "header"
    if node == Nodetype.BASE and detail == ("float64", 0):
        return "double"
    if node == Nodetype.SEQUENCE and detail[1] == 0 and detail[0][0] == Nodetype.BASE:
        element = detail[0][1]
        return {("string", 0): "strings", ("float64", 0): "doubles"}.get(element)
    return None


def fast_decoder(store: Typestore, msgtype: str) -> Decoder | None:
    """A decoder of ``msgtype`` (registered in ``store``), or None when the type has a field of
    another kind (rosbags' deserialiser then reads it)."""
    _, fields = store.fielddefs[msgtype]
    kinds = [_kind(field_type) for _, field_type in fields]
    if any(kind is None for kind in kinds) or kinds.count("header") > 1:
        return None
    message = store.types[msgtype]
    header = store.types.get(_HEADER_TYPE) if "header" in kinds else None
    time = store.types.get(_TIME_TYPE) if "header" in kinds else None
    # Consecutive float64 fields are read with one struct.
    steps: list[tuple[str, int]] = []
    for kind in kinds:
        if kind == "double" and steps and steps[-1][0] == "double":
            steps[-1] = ("double", steps[-1][1] + 1)
        else:
            steps.append((str(kind), 1))
    doubles = {count: struct.Struct(f"<{count}d") for kind, count in steps if kind == "double"}
    names: dict[bytes, tuple[str, ...]] = {}
    unpack_u32 = _U32.unpack_from

    def decode(data: bytes) -> Any:
        values: list[Any] = []
        offset = 0
        for kind, count in steps:
            if kind == "header":
                seq, sec, nanosec = _HEADER.unpack_from(data, offset)
                (length,) = unpack_u32(data, offset + 12)
                start = offset + 16
                offset = start + length
                frame_id = bytes(data[start:offset]).decode()
                values.append(header(seq, time(sec, nanosec), frame_id))  # type: ignore[misc]
            elif kind == "strings":
                (n,) = unpack_u32(data, offset)
                start = end = offset + 4
                for _ in range(n):
                    end += 4 + unpack_u32(data, end)[0]
                raw = bytes(data[start:end])
                decoded = names.get(raw)
                if decoded is None:
                    decoded = _strings(raw, n)
                    names[raw] = decoded
                values.append(list(decoded))
                offset = end
            elif kind == "doubles":
                (n,) = unpack_u32(data, offset)
                values.append(np.frombuffer(data, _FLOAT64, n, offset + 4))
                offset += 4 + 8 * n
            else:
                values.extend(doubles[count].unpack_from(data, offset))
                offset += 8 * count
        return message(*values)

    return decode


def _strings(raw: bytes, count: int) -> tuple[str, ...]:
    """``count`` length-prefixed UTF-8 strings, back to back in ``raw``."""
    out = []
    offset = 0
    for _ in range(count):
        (length,) = _U32.unpack_from(raw, offset)
        out.append(raw[offset + 4 : offset + 4 + length].decode())
        offset += 4 + length
    return tuple(out)
