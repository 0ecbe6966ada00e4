"""ROS wire format (TCPROS payloads) of the outputs, and the publisher that writes them in batches.

Building a genpy message and serialising it costs 10-60 us in Python (a TFMessage of nine frames
~60 us); these serialisers write the same bytes from cached constant parts and ``struct``, in
1-5 us. Each returns the payload of one message (without the 4-byte length prefix) for the
header sequence number ``seq`` it is given; tests compare them byte for byte with genpy. Only the
terrain (``ow_msgs/HeightMap``, on change) is still a genpy message.

No rospy here: :class:`BatchPublisher` writes to the connections of a rospy publisher that
:mod:`ow_sim_bullet.sim_node` makes.
"""

from __future__ import annotations

import struct
from collections.abc import Callable, Collection, Sequence
from typing import Any

from ow_runtime.tcpros_write import write_or_drop
from ow_sim_bullet.conversions import JointFrame, quaternion_from_matrix, stamp_parts
from ow_sim_bullet.tool_tracking import FloatArray, ToolSnapshot

_U32 = struct.Struct("<I")
_HEADER = struct.Struct("<3I")  # seq, stamp secs, stamp nsecs
_STAMP = struct.Struct("<2I")
_VECTOR3 = struct.Struct("<3d")
_QUATERNION = struct.Struct("<4d")
_WRENCH = struct.Struct("<6d")
_TOOL_STATE = struct.Struct("<15dB")  # pose (3 + 4), twist (3 + 3), depth, progress; material
_ZERO_WRENCH = _WRENCH.pack(*[0.0] * 6)


def _string(text: str) -> bytes:
    data = text.encode()
    return _U32.pack(len(data)) + data


def _doubles(values: FloatArray) -> bytes:
    return values.astype("<f8", copy=False).tobytes()


def clock(seq: int, time_s: float) -> bytes:
    """rosgraph_msgs/Clock at sim time ``time_s`` (s); ``seq`` is unused (no header)."""
    return _STAMP.pack(*stamp_parts(time_s))


class JointStateWire:
    """sensor_msgs/JointState of fixed joint names, empty frame_id.

    Args:
        names: joint names, in the order of the arrays given to :meth:`__call__`.
    """

    def __init__(self, names: Sequence[str]) -> None:
        count = _U32.pack(len(names))
        self._names = _string("") + count + b"".join(_string(n) for n in names) + count
        self._count = count
        self._length = len(names)

    def __call__(
        self,
        seq: int,
        time_s: float,
        position: FloatArray,
        velocity: FloatArray,
        effort: FloatArray,
    ) -> bytes:
        """The message; position rad, velocity rad/s, effort N m, each (n,)."""
        for values in (position, velocity, effort):
            if len(values) != self._length:
                msg = f"expected {self._length} joint values, got {len(values)}"
                raise ValueError(msg)
        count = self._count
        return b"".join(
            (
                _HEADER.pack(seq, *stamp_parts(time_s)),
                self._names,
                _doubles(position),
                count,
                _doubles(velocity),
                count,
                _doubles(effort),
            )
        )


class TfWire:
    """tf2_msgs/TFMessage of joint frames: one TransformStamped per frame, all stamped alike.

    Args:
        frames: the movable joints' frames (parent -> child).
        joint_index: for each frame, the index of its joint in the position arrays.
    """

    def __init__(self, frames: Sequence[JointFrame], joint_index: Sequence[int]) -> None:
        self._frames = list(frames)
        self._joint_index = list(joint_index)
        # Per frame: header seq (0: only a top-level header gets one), then after the stamp
        # frame_id, child_frame_id and the translation; the rotation follows.
        self._seq = _U32.pack(0)
        self._after_stamp = [
            _string(f.parent) + _string(f.child) + _VECTOR3.pack(*f.translation) for f in frames
        ]
        self._count = _U32.pack(len(self._frames))

    def __call__(self, seq: int, time_s: float, positions: FloatArray) -> bytes:
        """The message at sim time ``time_s`` for joint positions (rad); ``seq`` is unused."""
        stamp = self._seq + _STAMP.pack(*stamp_parts(time_s))
        angles = positions.tolist()
        parts = [self._count]
        for frame, k, after_stamp in zip(
            self._frames, self._joint_index, self._after_stamp, strict=True
        ):
            parts += (stamp, after_stamp, _QUATERNION.pack(*frame.rotation_at(angles[k])))
        return b"".join(parts)


class StampedWire:
    """Messages made of a std_msgs/Header with a fixed frame_id and doubles.

    Args:
        frame_id: the header's frame_id.
    """

    def __init__(self, frame_id: str) -> None:
        self._frame_id = _string(frame_id)

    def wrench(self, seq: int, time_s: float, force: FloatArray, torque: FloatArray) -> bytes:
        """geometry_msgs/WrenchStamped; force (3,) N, torque (3,) N m."""
        return (
            _HEADER.pack(seq, *stamp_parts(time_s))
            + self._frame_id
            + _WRENCH.pack(*force.tolist(), *torque.tolist())
        )

    def point(self, seq: int, time_s: float, x: float, y: float, z: float) -> bytes:
        """geometry_msgs/PointStamped; m."""
        return _HEADER.pack(seq, *stamp_parts(time_s)) + self._frame_id + _VECTOR3.pack(x, y, z)


class JointFlagsWire:
    """ow_msgs/JointStatesFlag of the locked joints, frame_id base_link. The flags
    change only when a fault locks or releases a joint, so the names and flags are serialised
    once per combination."""

    def __init__(self) -> None:
        self._frame_id = _string("base_link")
        self._bodies: dict[tuple[tuple[str, ...], tuple[bool, ...]], bytes] = {}

    def __call__(
        self, seq: int, time_s: float, names: tuple[str, ...], flags: tuple[bool, ...]
    ) -> bytes:
        """The message at sim time ``time_s``: ``flags[i]`` true when joint ``names[i]`` is
        locked (one entry each, as ``JointLocks.flags`` gives them)."""
        body = self._bodies.get((names, flags))
        if body is None:
            if len(names) != len(flags):
                msg = f"{len(names)} joint names but {len(flags)} flags"
                raise ValueError(msg)
            count = _U32.pack(len(names))
            body = b"".join(
                (count, *(_string(n) for n in names), count, bytes(bool(f) for f in flags))
            )
            self._bodies[(names, flags)] = body
        return _HEADER.pack(seq, *stamp_parts(time_s)) + self._frame_id + body


class ToolWire:
    """A tool's ow_msgs/ToolState (frame_id base_link) and its terrain-force model's
    geometry_msgs/WrenchStamped (frame_id the tool link) from its snapshots.

    Args:
        tool: "scoop" or "grinder".
        link: the tool's link.
    """

    def __init__(self, tool: str, link: str) -> None:
        self._state_head = _string("base_link") + _string(tool) + _string(link)
        self._link = _string(link)

    def state(self, seq: int, snapshot: ToolSnapshot, model: bool = False) -> bytes:
        """The tool's state in ``snapshot``; with ``model``, the depth the terrain-force model
        was given instead of the depth measured after the step."""
        pose = snapshot.X_base_link
        return b"".join(
            (
                _HEADER.pack(seq, *stamp_parts(snapshot.time)),
                self._state_head,
                _TOOL_STATE.pack(
                    *pose[:3, 3].tolist(),
                    *quaternion_from_matrix(pose[:3, :3]),
                    *snapshot.linear_velocity.tolist(),
                    *snapshot.angular_velocity.tolist(),
                    snapshot.model_depth if model else snapshot.depth,
                    snapshot.progress,
                    snapshot.material,
                ),
            )
        )

    def model_state(self, seq: int, snapshot: ToolSnapshot) -> bytes:
        """The state the terrain-force model was given in ``snapshot``'s step."""
        return self.state(seq, snapshot, model=True)

    def model_wrench(self, seq: int, snapshot: ToolSnapshot) -> bytes:
        """The model's wrench in ``snapshot`` (link frame, about the COM; zero: no model ran)."""
        wrench = snapshot.model_wrench
        values = (
            _ZERO_WRENCH
            if wrench is None
            else _WRENCH.pack(*(float(v) for v in wrench.force), *(float(v) for v in wrench.torque))
        )
        return _HEADER.pack(seq, *stamp_parts(snapshot.time)) + self._link + values


class BatchPublisher:
    """Publishes payloads serialised by this module on a rospy publisher, several per write.

    rospy's ``publish()`` costs ~8 us of Python a message on top of genpy's serialisation. This
    frames the payloads (length prefix) and writes them to the publisher's connections the way
    ``rospy.topics._PublisherImpl.publish`` does (rospy 1.15, the last ROS 1 release: its
    ``publock``, ``seq``, ``connections``, ``closed``, ``message_data_sent``). Registration,
    connection handshakes and ``get_num_connections`` stay rospy's.

    Messages are queued by :meth:`publish` and written by :meth:`flush`, all queued messages in
    one socket write: a loopback TCP write that wakes the subscriber costs 20-50 us of the
    simulation thread on a busy machine, much more than the message. TCPROS is a stream of
    length-prefixed messages, so subscribers receive exactly the same messages.

    A flush may be for some subscribers only (the nodes a lockstep step waits for): the others
    keep what was written to those, and get it, in order and whole, at the next flush for them
    or for everyone.

    Args:
        publisher: a ``rospy.Publisher`` made with ``queue_size=None`` (kept, and its ``impl``).
        is_shutdown: whether the process is shutting down (nothing is written then).
        log: debug log for dropped subscribers.
    """

    def __init__(
        self, publisher: Any, is_shutdown: Callable[[], bool], log: Callable[[str], None]
    ) -> None:
        self.publisher = publisher
        self._impl = publisher.impl
        self._is_shutdown = is_shutdown
        self._log = log
        self._pending: list[bytes] = []
        #: what the subscribers left out of a flush for some have not been written yet, by
        #: connection (rospy's transport), oldest first.
        self._behind: dict[Any, list[bytes]] = {}

    def _log_sim(self, text: str) -> None:
        self._log(f"sim: {text}")

    def publish(self, serialize: Callable[..., bytes], *args: Any) -> None:
        """Queue ``serialize(seq, *args)`` for the subscribers (not built if there is none)."""
        impl = self._impl
        if not impl.connections:
            return
        with impl.publock:
            impl.seq += 1
            payload = serialize(impl.seq, *args)
            self._pending += (_U32.pack(len(payload)), payload)

    def flush(self, only: Collection[str] | None = None) -> None:
        """Write the queued messages to every subscriber (blocks while a subscriber lags); a
        subscriber whose write fails is dropped, as rospy does.

        Args:
            only: the caller ids (node names) of the subscribers to write to now; the others'
                messages wait for a later flush. None: every subscriber, all it is owed.
        """
        if not self._pending and (only is not None or not self._behind):
            return
        impl = self._impl
        with impl.publock:
            data = b"".join(self._pending)
            self._pending.clear()
            if impl.closed or self._is_shutdown():
                self._behind.clear()
                return
            behind = self._behind
            for connection in list(impl.connections):
                if only is not None and connection.endpoint_id not in only:
                    if data:
                        behind.setdefault(connection, []).append(data)
                    continue
                owed = behind.pop(connection, None)
                out = data if owed is None else b"".join((*owed, data))
                if out:
                    write_or_drop(connection, out, impl.resolved_name, self._log_sim)
            if only is None:  # what is left was owed to connections closed since
                behind.clear()
            impl.message_data_sent += len(data)
