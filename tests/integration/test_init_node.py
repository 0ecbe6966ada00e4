"""``ow_runtime.node``: a node's shutdown wakes rospy's registration thread once rospy's
shutdown flag is up, instead of leaving it to its 0.5 s wait (every node stopped ~0.5 s later);
``spin`` returns when the node shuts down; ``exit_now`` ends the process without Python's
teardown, its output and logs written; the node's TCPROS server keeps many connections waiting
while it accepts one.

The tests watch the waits, not the clock: with bare ``rospy.init_node`` one of the registration
thread's waits runs out its timeout after the flag is up; with ``init_node`` none does. ``spin``'s
last wait is woken by the shutdown, not run out."""

import os
import subprocess
import sys

import pytest

CHILD = """
import sys, threading, time
import rospy, rospy.core
from rospy.impl.registration import RegManager, get_registration_listeners
from ow_runtime.node import init_node

class Watched(threading.Condition):
    outcomes = []
    def wait(self, timeout=None):
        notified = super().wait(timeout)
        self.outcomes.append((notified, rospy.core.is_shutdown()))
        return notified

if sys.argv[1] == "ours":
    init_node("init_node_test", disable_signals=True)
else:
    rospy.init_node("init_node_test", disable_signals=True)
manager = next(m for m in get_registration_listeners().listeners if isinstance(m, RegManager))
old, manager.cond = manager.cond, Watched()
with old:
    old.notify_all()  # its next wait is on the watched condition
while not Watched.outcomes:
    with manager.cond:
        manager.cond.notify_all()
# rospy's cleanup (a pre-shutdown hook) wakes the thread before the flag is up: give it time to
# wait again, as the master calls of a node with more topics would.
rospy.core.add_preshutdown_hook(lambda reason: time.sleep(0.05))
rospy.signal_shutdown("test")
# A wait that ran out once the flag was up is what kept the node from stopping.
print(any(not notified and after_flag for notified, after_flag in Watched.outcomes))
"""


@pytest.mark.parametrize(("how", "waited_out"), [("ours", "False"), ("bare", "True")])
def test_a_node_s_registration_thread_is_woken_when_it_shuts_down(ros_master, how, waited_out):
    assert _words(ros_master, CHILD, how) == [waited_out]


def _words(master, code: str, *args: str) -> list[str]:
    """What a Python child running ``code`` on ``master`` prints, as words."""
    return subprocess.run(
        [sys.executable, "-c", code, *args],
        env=dict(os.environ, ROS_MASTER_URI=master.uri),
        capture_output=True,
        text=True,
        timeout=60,
        check=True,
    ).stdout.split()


SPIN_CHILD = """
import os, signal, threading
import rospy
import ow_runtime.node as init_node

waits = []

class Watched(threading.Event):
    def wait(self, timeout=None):
        woken = super().wait(timeout)
        waits.append(woken)
        return woken

init_node.threading.Event = Watched
init_node.init_node("spin_test")  # rospy's signal handlers, as a node has them
threading.Timer(0.2, os.kill, (os.getpid(), signal.SIGINT)).start()
init_node.spin()
print(rospy.core.is_shutdown(), waits[-1])
"""


def test_spin_returns_when_a_signal_shuts_the_node_down(ros_master):
    # Shut down, and the last wait woken, not run out.
    assert _words(ros_master, SPIN_CHILD) == ["True", "True"]


EXIT_CHILD = """
import atexit, logging, sys
from ow_runtime.node import exit_now

logging.basicConfig(filename=sys.argv[1], level=logging.INFO)
atexit.register(lambda: print("teardown ran"))
logging.getLogger("node").info("last words")
print("written", end="")
exit_now(3)
"""


def test_exit_now_writes_the_output_and_logs_and_skips_the_teardown(tmp_path):
    log = tmp_path / "node.log"
    proc = subprocess.run(
        [sys.executable, "-c", EXIT_CHILD, str(log)],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert proc.returncode == 3
    assert proc.stdout == "written"  # flushed; the atexit handler never ran
    assert "last words" in log.read_text()


BACKLOG_CHILD = """
import socket, sys, threading
import rospy
from rospy.impl import tcpros_base
from ow_runtime.node import init_node

stuck = threading.Event()
# The server's accept loop handles one connection at a time: hold it at the first.
tcpros_base.TCPROSServer._tcp_server_callback = lambda self, sock, addr: stuck.wait()
if sys.argv[1] == "ours":
    init_node("backlog_test", disable_signals=True)
else:
    rospy.init_node("backlog_test", disable_signals=True)
    tcpros_base.init_tcpros_server().start_server()
port = tcpros_base.init_tcpros_server().tcp_ros_server.port
clients = []
for _ in range(12):
    try:  # in the backlog: at once; its SYN dropped: not before the accept loop moves on
        clients.append(socket.create_connection(("127.0.0.1", port), timeout=2.0))
    except OSError:
        break
print(len(clients))
"""


@pytest.mark.parametrize(("how", "connected"), [("ours", "12"), ("bare", "7")])
def test_a_node_keeps_many_connections_waiting_while_it_accepts_one(ros_master, how, connected):
    """Twelve subscribers connecting at once while the node accepts the first: with rospy's
    backlog of 5 the kernel keeps six waiting and drops the rest's SYNs (each then retried
    after 1 s), with init_node's all of them wait."""
    assert _words(ros_master, BACKLOG_CHILD, how) == [connected]


REFUSING_CHILD = """
import rospy
from ow_runtime.node import exit_now, init_node

init_node("refusing_node")
rospy.Publisher("/refusing_topic", rospy.AnyMsg, queue_size=1)  # registered with the master
exit_now(1)  # as a main that refuses its parameters returns, rospy still running
"""


def test_a_node_that_exits_without_shutting_down_leaves_the_master(ros_master):
    """exit_now shuts rospy down first: the node unregisters, so the master never calls an
    address that another node's server may take next."""
    proc = subprocess.run(
        [sys.executable, "-c", REFUSING_CHILD],
        env=dict(os.environ, ROS_MASTER_URI=ros_master.uri),
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert proc.returncode == 1, proc.stderr
    assert "/refusing_topic" not in {name for name, _ in ros_master.call("getSystemState")[0]}


SLEEP_CHILD = """
import os, signal, sys, threading
import rospy, rospy.core, rospy.rostime
import ow_runtime.node as init_node

sleeps = []  # rospy's wall sleeps in the main thread
real = rospy.rostime.wallsleep
def watched(duration):
    if threading.current_thread() is threading.main_thread():
        sleeps.append(duration)
    real(duration)
rospy.rostime.wallsleep = watched
if sys.argv[1] == "ours":
    init_node.init_node("sleep_test")
else:
    rospy.init_node("sleep_test")
if sys.argv[2] == "signal":
    threading.Timer(0.2, os.kill, (os.getpid(), signal.SIGINT)).start()
    try:
        init_node.spin()
    except KeyboardInterrupt:  # rospy's handler chains to Python's
        pass
else:
    init_node.signal_shutdown("done") if sys.argv[1] == "ours" else rospy.signal_shutdown("done")
print(rospy.core.is_shutdown(), bool(sleeps))
"""


@pytest.mark.parametrize("how", ["signal", "call"])
@pytest.mark.parametrize(("node", "slept"), [("ours", "False"), ("bare", "True")])
def test_a_node_shuts_down_without_rospys_sleep_in_its_main_thread(ros_master, how, node, slept):
    """rospy's signal_shutdown ends with a 0.1 s sleep ("a hack until we get rid of all the
    extra threads") in the thread that calls it, the main thread for a signal: each node of a
    mission's stack paid it at its stop, then the mission. init_node's handlers and
    signal_shutdown run it on a thread of their own and return once the hooks have run."""
    assert _words(ros_master, SLEEP_CHILD, node, how) == ["True", slept]


CLOSED_CHILD = """
import sys
import rospy, rospy.core
from std_msgs.msg import Empty
from ow_runtime.node import init_node, quiet_at_shutdown, signal_shutdown

init_node("closed_test", disable_signals=True)
publisher = rospy.Publisher("/closed_test", Empty, queue_size=1)
callback = lambda: publisher.publish(Empty())
if sys.argv[1] == "ours":
    callback = quiet_at_shutdown(callback)
callback()  # while up: published
outcome = []

def late(reason):  # after rospy's cleanup closed the topics, before the shutdown flag
    try:
        outcome.append("dropped" if callback() is None else "returned")
    except rospy.ROSException as error:
        outcome.append(str(error).replace(" ", "_"))

rospy.core.add_preshutdown_hook(late)
signal_shutdown("test")
print(*outcome)
"""


@pytest.mark.parametrize(
    ("how", "outcome"), [("ours", "dropped"), ("bare", "publish()_to_a_closed_topic")]
)
def test_a_publish_that_meets_the_shutdown_is_dropped_not_raised(ros_master, how, outcome):
    """A callback that publishes in the window between rospy closing the node's topics and
    raising its shutdown flag: bare, its publish raised (rospy logged the traceback as a bad
    callback, over the node's reason to stop); wrapped, the message is dropped."""
    assert _words(ros_master, CLOSED_CHILD, how) == [outcome]


NOT_SHUT_DOWN_CHILD = """
import rospy
from ow_runtime.node import init_node, quiet_at_shutdown

init_node("not_shut_down_test", disable_signals=True)

@quiet_at_shutdown
def callback():
    raise rospy.ROSException("another failure")

try:
    callback()
except rospy.ROSException as error:
    print(str(error).replace(" ", "_"))
"""


def test_a_failure_while_the_node_is_up_is_raised(ros_master):
    assert _words(ros_master, NOT_SHUT_DOWN_CHILD) == ["another_failure"]
