"""The recorder node: topics into split ROS 1 bags with rosbags (rospy wiring only)."""

from __future__ import annotations

import json
import os
import signal
import sys
import threading
from pathlib import Path
from types import FrameType
from typing import Any

import rospy
from std_msgs.msg import String

from ow_msgs.srv import RecorderProgress, RecorderProgressRequest, RecorderProgressResponse
from ow_power.bagwriter import SplitBagWriter, record_time_ns
from ow_power.config import RecorderConfig
from ow_power.errors import ConfigError, RecorderError
from ow_runtime.latched import latched_publisher
from ow_runtime.node import init_node, signal_shutdown

#: s of wall time between two ``~status`` messages.
STATUS_PERIOD_S = 1.0


def bag_directory(config: RecorderConfig, environ: dict[str, str]) -> Path:
    """Where the bags go: ``output_dir`` (``~`` expanded) or ``$ROS_HOME/bags``.

    Args:
        config: the recorder configuration.
        environ: the process environment (for ``ROS_HOME`` and ``HOME``).
    """
    if config.output_dir:
        return Path(os.path.expanduser(config.output_dir))
    ros_home = environ.get("ROS_HOME") or os.path.join(environ.get("HOME", "."), ".ros")
    return Path(ros_home) / "bags"


class RecorderNode:
    """Records topics of any type into ROS 1 bags that ``rosbag`` and rosbags read.

    Messages are written as received (serialised bytes, type, MD5 and definition from the
    connection header). A message whose first field is a Header is written at its
    ``header.stamp``; others (and stamps of 0) at the receipt time on the ROS clock (simulation
    time under ``/use_sim_time``). Latched publishers' connections are flagged ``latching=1``
    and their last message is repeated at the start of every file. Files are split by message
    time and size; each closed file is a complete ``.bag``, the open one is ``.bag.active``.
    SIGINT and SIGTERM close the open file and exit; SIGKILL loses the open file only.

    ROS API:
        Subscribes:
            every topic of ``~topics`` (any type, rospy.AnyMsg).
        Publishes:
            ``~status`` (std_msgs/String, latched): JSON ``{"run", "active", "closed",
            "messages"}``, every second of wall time and whenever a file is closed.
        Services:
            ``~progress`` (ow_msgs/RecorderProgress): per topic written so far, the newest
            record time (s) and the message count; a mission waits on it before stopping the
            stack, so every message its last state caused is in the bags.
        Parameters (private, read once; see :class:`~ow_power.config.RecorderConfig`):
            ``~output_dir`` (str, default ``$ROS_HOME/bags``), ``~prefix`` (str, default ``ow``),
            ``~topics`` (list of str), ``~split_duration_s`` (float, s, default 60, 0 = off),
            ``~split_size_mb`` (float, MB, default 100, 0 = off), ``~compression``
            (``none`` | ``bz2``), ``~queue_size`` (int, messages per topic, default 1000).
    """

    def __init__(self, config: RecorderConfig, directory: Path) -> None:
        """Subscribe to the topics; the first message creates the first file.

        Raises:
            RecorderError: the bag directory cannot be created.
        """
        self._status = latched_publisher("~status", String, queue_size=1)
        self._messages = 0
        self._progress: dict[str, tuple[int, int]] = {}  # topic -> (newest ns, messages)
        self._bags = SplitBagWriter(
            directory,
            prefix=config.prefix,
            split_duration_s=config.split_duration_s,
            split_size_mb=config.split_size_mb,
            compression=config.compression,
            on_closed=self._on_closed,
        )
        self._subscribers = [
            rospy.Subscriber(
                topic,
                rospy.AnyMsg,
                self._on_message,
                callback_args=topic,
                queue_size=config.queue_size,
            )
            for topic in config.topics
        ]
        self._progress_service = rospy.Service("~progress", RecorderProgress, self._on_progress)

    @property
    def run_name(self) -> str:
        """Common name of the run's files."""
        return self._bags.name

    def _on_message(self, msg: Any, topic: str) -> None:
        header = msg._connection_header
        msgdef = header["message_definition"]
        # The clock is read only for a message without a stamp (a Time object per message); on
        # simulation time a stamp of 0 is its start.
        stamp_ns = record_time_ns(msgdef, msg._buff, -1, not rospy.rostime.is_wallclock())
        if stamp_ns < 0:
            stamp_ns = rospy.get_rostime().to_nsec()
        try:
            written = self._bags.write(
                topic,
                header["type"],
                header["md5sum"],
                msgdef,
                stamp_ns,
                msg._buff,
                latching=header.get("latching", "0") == "1",
                callerid=header.get("callerid", ""),
            )
        except RecorderError as exc:
            rospy.logerr_throttle(5.0, f"record: {exc}")
            return
        if written:
            self._messages += 1
            newest, count = self._progress.get(topic, (stamp_ns, 0))
            self._progress[topic] = (max(newest, stamp_ns), count + 1)  # one thread per topic

    def _on_progress(self, request: RecorderProgressRequest) -> RecorderProgressResponse:
        progress = sorted(dict(self._progress).items())
        return RecorderProgressResponse(
            topics=[topic for topic, _ in progress],
            latest_s=[newest * 1e-9 for _, (newest, _) in progress],
            messages=[count for _, (_, count) in progress],
        )

    def _on_closed(self, path: Path) -> None:
        rospy.loginfo(f"record: closed {path}")
        self.publish_status()

    def publish_status(self) -> None:
        """Publish ``~status`` now."""
        active = self._bags.active_path
        status = {
            "run": self._bags.name,
            "active": str(active) if active else "",
            "closed": [str(p) for p in self._bags.closed_files],
            "messages": self._messages,
        }
        self._status.publish(String(data=json.dumps(status)))

    def close(self) -> list[Path]:
        """Stop writing and close the open file.

        Raises:
            RecorderError: the open file cannot be closed (it stays as ``.bag.active``).
        """
        self._progress_service.shutdown()
        for subscriber in self._subscribers:
            subscriber.unregister()
        return self._bags.close()


def main(argv: list[str] | None = None) -> int:
    """Record until SIGINT or SIGTERM; 1 on a configuration or file error."""
    # Our own handlers: a signal only sets an event, the main thread closes the bag.
    init_node("record", argv=argv, disable_signals=True)
    stop = threading.Event()

    def on_signal(signum: int, frame: FrameType | None) -> None:
        stop.set()

    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)
    try:
        config = RecorderConfig.from_dict(rospy.get_param("~", {}))
        directory = bag_directory(config, dict(os.environ))
        recorder = RecorderNode(config, directory)
    except (ConfigError, RecorderError) as exc:
        rospy.logfatal(f"record: {exc}")
        signal_shutdown(str(exc))
        return 1
    rospy.loginfo(
        f"record: {', '.join(config.topics)} -> {directory}/{recorder.run_name}_*.bag "
        f"(split every {config.split_duration_s} s / {config.split_size_mb} MB, "
        f"{config.compression})"
    )
    status = 0
    try:
        while not stop.wait(STATUS_PERIOD_S) and not rospy.is_shutdown():
            recorder.publish_status()
    finally:
        try:
            closed = recorder.close()
            rospy.loginfo(f"record: stopped; {len(closed)} bag(s) in {directory}")
        except RecorderError as exc:
            rospy.logerr(f"record: {exc}")
            status = 1
        recorder.publish_status()
        signal_shutdown("recorder stopped")  # without rospy's 0.1 s sleep
    return status


if __name__ == "__main__":
    sys.exit(main())
