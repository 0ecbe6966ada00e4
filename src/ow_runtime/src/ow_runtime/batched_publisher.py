"""A rospy publisher whose messages are written by a thread of its own, all those published
since its last write in one socket write per subscriber (rospy wiring only).

A node that publishes one message per joint state it receives (the power node's ``/power``)
gets them in batches: the simulation writes several joint states at once, and
rospy calls the callback for each in turn. Written in the callback (rospy's ``queue_size=None``)
each message is one socket write, which wakes the subscriber; rospy's queued publisher also
writes them one by one, and yields the processor after each (``time.sleep(0)``). Here the
callback only serialises and queues; the writer thread, which needs the GIL, runs once the
callbacks of the batch are done and the receiving thread waits on its socket again, and writes
the whole batch at once. TCPROS is a stream of length-prefixed messages: the subscribers receive
exactly the same messages, in the same order. Nothing is dropped: a subscriber that lags holds
the writer (and the queue grows) rather than losing messages.

It writes to the connections of a ``rospy.Publisher`` made with ``queue_size=None`` the way
``rospy.topics._PublisherImpl.publish`` does (rospy 1.15, the last ROS 1 release: its ``seq``,
``publock``, ``connections``, ``closed``, ``message_data_sent``); registration, handshakes and
``get_num_connections`` stay rospy's. Latched topics are not supported (use rospy's publisher).
"""

from __future__ import annotations

import threading
import warnings
from io import BytesIO
from typing import Any

import rospy
from rospy.msg import serialize_message

from ow_runtime.tcpros_write import write_or_drop


class BatchedPublisher:
    """Publishes ``msg_type`` messages on ``topic`` through a writer thread.

    Args:
        topic: the topic (resolved as rospy resolves it).
        msg_type: the message class.
    """

    def __init__(self, topic: str, msg_type: type) -> None:
        with warnings.catch_warnings():  # rospy warns of queue_size None
            warnings.simplefilter("ignore", SyntaxWarning)
            self.publisher = rospy.Publisher(topic, msg_type, queue_size=None)
        self._impl = self.publisher.impl
        self._buffer = BytesIO()
        self._ready = threading.Condition(threading.Lock())
        self._pending: list[bytes] = []
        threading.Thread(
            target=self._write_loop, name=f"{self._impl.resolved_name} writer", daemon=True
        ).start()
        rospy.on_shutdown(self._wake)

    def get_num_connections(self) -> int:
        """The number of subscribers connected (rospy's)."""
        return int(self.publisher.get_num_connections())

    def publish(self, msg: Any) -> None:
        """Queue ``msg`` for the subscribers (nothing without one); its header's ``seq`` is set
        as rospy sets it."""
        impl = self._impl
        if not impl.connections:
            return
        with impl.publock:
            impl.seq += 1
            buffer = self._buffer
            buffer.seek(0)
            buffer.truncate(0)
            serialize_message(buffer, impl.seq, msg)
            data = buffer.getvalue()
        with self._ready:
            first = not self._pending
            self._pending.append(data)
            if first:
                self._ready.notify()

    def _wake(self, *_: Any) -> None:
        with self._ready:
            self._ready.notify()

    def _write_loop(self) -> None:
        impl = self._impl
        while True:
            with self._ready:
                while not self._pending and not rospy.is_shutdown():
                    self._ready.wait(timeout=1.0)
                if not self._pending:
                    return  # shut down with nothing left
                data = b"".join(self._pending)
                self._pending.clear()
            with impl.publock:
                if impl.closed:
                    return
                for connection in list(impl.connections):
                    write_or_drop(connection, data, impl.resolved_name, rospy.logdebug)
                impl.message_data_sent += len(data)
