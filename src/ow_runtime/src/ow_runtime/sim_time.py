"""Waiting for this node's simulation clock (rospy only)."""

from __future__ import annotations

import time

import rospy

from ow_runtime.names import STAMP_SLACK_S


def wait_for_clock(stamp: float, timeout_s: float) -> bool:
    """Wait (``timeout_s`` of wall time at most) until this node's clock reads ``stamp`` (s, sim);
    whether it does. rospy's clock has no condition to wait on: it is polled."""
    deadline = time.monotonic() + timeout_s
    while rospy.get_time() < stamp - STAMP_SLACK_S:
        if time.monotonic() > deadline:
            return False
        time.sleep(0.001)
    return True
