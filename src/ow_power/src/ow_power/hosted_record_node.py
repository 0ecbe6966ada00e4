"""The recorder as a component of another node (rospy wiring only): the mission's process
records its run itself, one Python process (~40 MB of PSS) fewer during the steps.

It records exactly as the record node (:class:`ow_power.record_node.RecorderNode`), with its
``status`` and ``progress`` under :data:`RECORD_NAMESPACE` as that node's, and its parameters
there for ``rosparam``. rospy gives a process one subscription per topic, typed as its first
subscriber asked: the recorder's ``rospy.AnyMsg`` would hand the host's own callbacks raw bytes.
So the host names the recorded topics it takes itself, with their classes (``typed``), and the
recorder subscribes to those typed and writes their messages serialised again, byte for byte
what was published, whichever subscribes first.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import rospy

from ow_power.config import RecorderConfig
from ow_power.record_node import STATUS_PERIOD_S, RecorderNode, bag_directory

#: Where the hosted recorder's ``status``, ``progress`` and parameters are: the record node's.
RECORD_NAMESPACE = "/record"


class HostedRecorder:
    """A recorder in this node, recording from construction until :meth:`close`.

    Publishes ``<namespace>/status`` every :data:`~ow_power.record_node.STATUS_PERIOD_S` s of
    wall time from a thread of its own, and serves ``<namespace>/progress``.

    Args:
        params: the record node's private parameters (:class:`RecorderConfig`).
        namespace: of its status, progress and parameters.
        environ: the environment ``output_dir`` defaults from (``ROS_HOME``; None: this
            process's).
        typed: topic -> message class of every topic this node subscribes to itself, now or
            later (those not recorded are ignored).

    Attributes:
        directory: where the bags go.

    Raises:
        ConfigError: a bad parameter (named).
        RecorderError: the bag directory cannot be created.
    """

    def __init__(
        self,
        params: Mapping[str, Any],
        namespace: str = RECORD_NAMESPACE,
        environ: Mapping[str, str] | None = None,
        typed: Mapping[str, Any] | None = None,
    ) -> None:
        config = RecorderConfig.from_dict(dict(params))
        self.directory = bag_directory(config, dict(os.environ if environ is None else environ))
        rospy.set_param(namespace, dict(params))
        self._recorder = RecorderNode(config, self.directory, namespace, typed)
        self._closed: list[Path] | None = None
        self._stop = threading.Event()
        self._status = threading.Thread(target=self._publish, name="record_status", daemon=True)
        self._status.start()

    @property
    def run_name(self) -> str:
        """Common name of the run's files."""
        return self._recorder.run_name

    def _publish(self) -> None:
        while not self._stop.wait(STATUS_PERIOD_S):
            self._recorder.publish_status()

    def close(self) -> list[Path]:
        """Stop recording and close the open file (once; later calls return the same files).

        Returns:
            every file of the run, in order.

        Raises:
            RecorderError: the open file cannot be closed (it stays as ``.bag.active``).
        """
        if self._closed is None:
            self._stop.set()
            self._status.join()
            try:
                self._closed = self._recorder.close()
            finally:
                self._recorder.publish_status()
        return self._closed
