"""``ow_runtime.status_timer.share_status_timer`` on a simulated clock driven by hand, in a
child process (its rospy time is its own): one status a period, and a clock set back (a
simulation restarted under running nodes) restarts the timer instead of ending its thread.

The servers are stand-ins with the three members the timer uses; ``test_actions`` runs it over
real ``actionlib`` servers on the stack's clock."""

import os
import subprocess
import sys

CHILD = """
import threading, time
import rospy
from rospy import rostime
from ow_runtime.status_timer import share_status_timer

class OwnTimer:
    stopped = False
    def shutdown(self):
        self.stopped = True

class Server:
    status_frequency = 10.0
    def __init__(self):
        self.status_timer = OwnTimer()
        self.statuses = []
    def publish_status_async(self, event):
        self.statuses.append(round(event.current_real.to_sec(), 3))

def set_time(t):
    # In whole nanoseconds, as the simulation stamps /clock (from_sec truncates 100.1 s to
    # 100.099999999 s, a nanosecond before the timer's period).
    rostime._set_rostime(rospy.Time(*divmod(round(t * 1e9), 10**9)))

def tick_to(t, server, count):
    # Set the clock to t and wait (at most 10 s) for the server's count-th status.
    set_time(t)
    deadline = time.monotonic() + 10.0
    while len(server.statuses) < count and time.monotonic() < deadline:
        time.sleep(0.001)

rostime.set_rostime_initialized(True)
set_time(100.0)
servers = [Server(), Server()]
timer = share_status_timer(servers)
print(all(server.status_timer.stopped for server in servers))
expected = []
for k in range(1, 6):  # one status a period
    expected.append(round(100.0 + 0.1 * k, 3))
    tick_to(expected[-1], servers[0], len(expected))
set_time(1.0)  # set back: the timer fires at the new time and goes on from it
expected.append(1.0)
tick_to(1.0, servers[0], len(expected))
for k in range(1, 6):
    expected.append(round(1.0 + 0.1 * k, 3))
    tick_to(expected[-1], servers[0], len(expected))
time.sleep(0.2)  # no extra status comes
print(timer.is_alive())
print(servers[0].statuses == servers[1].statuses == expected or servers[0].statuses)
timer.shutdown()
"""


def test_one_status_a_period_and_a_clock_set_back_restarts_the_timer():
    words = subprocess.run(
        [sys.executable, "-c", CHILD],
        env=dict(os.environ),
        capture_output=True,
        text=True,
        timeout=120,
        check=True,
    ).stdout.split("\n")
    assert words[:3] == ["True", "True", "True"], words
