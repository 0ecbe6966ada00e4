"""The harness itself: a private master, a real node via rosrun, a real service, clean teardown."""

import os
import signal
import socket
import subprocess
import sys
import xmlrpc.client
from pathlib import Path

import pytest
import rospy
from std_msgs.msg import String
from std_srvs.srv import Empty

from ow_bringup.processes import ignores_signal
from ow_bringup.stack import (
    NODE_ENVIRONMENT,
    NODE_PYTHON_OPTIMIZE,
    NodeProcess,
    RosMaster,
    node_command,
)
from ow_bringup.testing import HarnessError, RosStack


def test_master_is_private_and_sim_time_is_set(ros_master):
    assert ros_master.uri != "http://localhost:11311"
    assert os.environ["ROS_MASTER_URI"] == ros_master.uri
    assert ros_master.call("getParam", "/use_sim_time") is True


def test_node_started_with_rosrun_offers_its_service_and_is_stopped(ros_master):
    stack = RosStack(ros_master)
    # rosout's own services exist in every ROS install; it stands in for any node here.
    node = stack.start_node(
        "rosout", "rosout", name="harness_rosout", wait_for_services=["/harness_rosout/get_loggers"]
    )
    assert node.alive()
    stack.shutdown()
    assert not node.alive()
    assert "/harness_rosout/get_loggers" not in ros_master.services()
    # No stray process of the node's group survives.
    with pytest.raises(ProcessLookupError):
        os.killpg(node.proc.pid, 0)


@pytest.mark.parametrize(
    ("package", "executable"),
    [
        ("ow_power", "record"),
        ("ow_bringup", "monitors"),
        ("ow_mission", "monitors"),
        ("rosout", "rosout"),
    ],
)
def test_a_node_runs_as_the_program_rosrun_finds_for_it(package, executable):
    found = subprocess.run(
        ["rosrun", "--prefix", "echo", package, executable],
        capture_output=True,
        text=True,
        check=True,
    ).stdout.split()
    assert node_command(package, executable) == (found[0],)


def test_the_stacks_python_nodes_run_without_docstrings_and_one_blas_thread(ros_master):
    """PYTHONOPTIMIZE=2 (python -OO) in the environment of every node a stack starts: the
    node's Python reads it at start-up, so its modules load without their docstrings; and
    one OpenBLAS thread and one malloc arena, unless the user's environment says otherwise."""
    stack = RosStack(ros_master)
    node = stack.start_node(
        "ow_power", "power", name="harness_power", wait_for_topics=["/power"], timeout_s=60.0
    )
    try:
        environ = Path(f"/proc/{node.proc.pid}/environ").read_bytes().split(b"\0")
        assert f"PYTHONOPTIMIZE={NODE_PYTHON_OPTIMIZE}".encode() in environ
        assert NODE_PYTHON_OPTIMIZE == "2"
        for key, value in NODE_ENVIRONMENT.items():
            if key != "PYTHONOPTIMIZE":  # the user's own wins
                assert f"{key}={os.environ.get(key, value)}".encode() in environ
    finally:
        stack.shutdown()


def test_a_program_catkin_did_not_make_is_left_to_rosrun():
    assert node_command("ow_power", "no_such_node") == ("rosrun", "ow_power", "no_such_node")


def test_private_params_are_set_before_start_and_removed_after(ros_master):
    stack = RosStack(ros_master)
    stack.start_node(
        "rosout",
        "rosout",
        name="harness_params",
        params={"rate_hz": 5.0},
        wait_for_services=["/harness_params/get_loggers"],
    )
    assert ros_master.call("getParam", "/harness_params/rate_hz") == 5.0
    stack.shutdown()
    assert not ros_master.call("hasParam", "/harness_params/rate_hz")


def test_a_node_that_dies_reports_its_log(ros_master):
    stack = RosStack(ros_master)
    with pytest.raises(HarnessError, match=r"(?s)exited.*cannot read mission file"):
        stack.start_node(
            "ow_mission",
            "mission",
            name="harness_dies",
            args=["/nonexistent/mission.yaml"],
            wait_for_services=["/never"],
        )
    stack.shutdown()


def test_a_node_started_again_under_its_name_keeps_the_earlier_ones_log(ros_master):
    stack = RosStack(ros_master)
    for attempt in range(2):
        with pytest.raises(HarnessError, match=r"(?s)exited.*cannot read mission file"):
            stack.start_node(
                "ow_mission",
                "mission",
                name="harness_twice",
                args=[f"/nonexistent/mission_{attempt}.yaml"],
                wait_for_services=["/never"],
            )
    stack.shutdown()
    logs = [ros_master.log_dir / name for name in ("harness_twice.log", "harness_twice.1.log")]
    assert [f"mission_{k}.yaml" in log.read_text() for k, log in enumerate(logs)] == [True, True]


def test_service_call_through_the_stack(ros_master):
    # A tiny real service in a child process, started like a user's own node would be.
    code = (
        "import rospy\nfrom std_srvs.srv import Empty, EmptyResponse\n"
        "rospy.init_node('harness_echo')\n"
        "rospy.Service('/harness_echo/ping', Empty, lambda r: EmptyResponse())\nrospy.spin()\n"
    )
    proc = subprocess.Popen(["python", "-c", code], env=ros_master.env, start_new_session=True)
    try:
        stack = RosStack(ros_master)
        ping = stack.service("/harness_echo/ping", Empty, timeout_s=30)
        ping()
        assert rospy.get_name().startswith("/pytest")
    finally:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
        # Killed, it was still a subscriber of /clock on this worker's master.
        forgotten = ros_master.forget_unreachable()
    assert forgotten == ["/harness_echo"]


SCRIPT = """
import sys, time
from ow_bringup.stack import RosStack, private_master
with private_master() as master:
    stack = RosStack(master)
    try:
        node = stack.start_node("rosout", "rosout", name="orphan_check",
                                wait_for_services=["/orphan_check/get_loggers"])
        print(node.proc.pid, flush=True)
        time.sleep(600)
    finally:
        stack.shutdown()
"""


def test_a_terminated_script_stops_its_nodes(tmp_path):
    # SIGTERM (kill, pkill, a CI timeout) must not leave the nodes running without their master.
    script = subprocess.Popen(
        ["python", "-c", SCRIPT], stdout=subprocess.PIPE, text=True, start_new_session=True
    )
    try:
        node_pid = int(script.stdout.readline())
        os.kill(node_pid, 0)  # the node runs
        script.send_signal(signal.SIGTERM)
        assert script.wait(timeout=30) == 128 + signal.SIGTERM
        with pytest.raises(ProcessLookupError):
            os.killpg(node_pid, 0)
    finally:
        if script.poll() is None:
            os.killpg(script.pid, signal.SIGKILL)


def test_a_killed_node_leaves_nothing_on_the_master_for_later_stacks(ros_master):
    """A node killed before it could unregister stayed a subscriber of its topics on the
    master, and every later wait for all of a topic's subscribers to be connected ran out."""
    stack = RosStack(ros_master)
    node = stack.start_node(
        "rosout", "rosout", name="harness_killed", wait_for_services=["/harness_killed/get_loggers"]
    )
    _, subscribers, _ = ros_master.call("getSystemState")
    assert "/harness_killed" in dict(subscribers)["/rosout"]  # this process publishes /rosout
    node.signal(signal.SIGKILL)
    node.proc.wait(timeout=10)
    _, subscribers, _ = ros_master.call("getSystemState")
    assert "/harness_killed" in dict(subscribers)["/rosout"]  # still listed: it never said
    assert "/rosout" in ros_master.unconnected(["/rosout"])
    stack.shutdown()
    publishers, subscribers, services = ros_master.call("getSystemState")
    registered = [n for _, nodes in (*publishers, *subscribers, *services) for n in nodes]
    assert "/harness_killed" not in registered
    assert ros_master.unconnected(["/rosout"]) == []
    assert ros_master.forget("/harness_killed") == []  # nothing left: nothing to do


def test_a_module_leaves_no_subscription_of_this_process_to_the_next(ros_master):
    """A ``dynamic_reconfigure`` client a test left open kept this process subscribed to a PID
    server's topics; the next module's simulation had a subscriber it had not connected to
    while it started, and a wait for every connection saw it unconnected. A module's stack
    unregisters whatever this process registered during the module, and nothing it had
    before."""
    from dynamic_reconfigure.client import Client

    from ow_bringup.testing import module_stack, registered_topics

    before = registered_topics()
    me = rospy.get_name()
    with module_stack(ros_master) as stack:
        stack.start_node("ow_faults", "faults", wait_for_services=["/faults/set_parameters"])
        client = Client("/faults", timeout=30)  # left open, as test_faults_injection did
        assert client.get_configuration(timeout=30)["ant_pan_joint_locked_failure"] is False
        assert "/faults/parameter_updates" in ros_master.subscribed_by(me)
        status = rospy.Subscriber("/harness_status", String, lambda _: None)  # never unregistered
        assert ("sub", status.resolved_name) in registered_topics()
    assert registered_topics() == before
    subscribed = ros_master.subscribed_by(me)
    assert not subscribed & {"/faults/parameter_updates", "/faults/parameter_descriptions"}
    assert "/harness_status" not in subscribed
    again = rospy.Subscriber("/harness_status", String, lambda _: None)  # a new one works
    assert "/harness_status" in ros_master.subscribed_by(me)
    again.unregister()
    assert registered_topics() == before


def test_a_node_is_ready_only_on_what_it_registered_itself(ros_master):
    """A service another node offers does not make a node ready: a node of the same name that
    is still shutting down must not pass for the new one."""
    stack = RosStack(ros_master)
    stack.start_node(
        "rosout", "rosout", name="harness_first", wait_for_services=["/harness_first/get_loggers"]
    )
    services, _ = ros_master.offered_by("/harness_first")
    assert "/harness_first/get_loggers" in services
    with pytest.raises(HarnessError, match=r"did not offer \['/harness_first/get_loggers'\]"):
        stack.start_node(
            "rosout",
            "rosout",
            name="harness_second",
            wait_for_services=["/harness_first/get_loggers"],
            timeout_s=3.0,
        )
    stack.shutdown()


def test_a_modules_publishers_end_with_it_and_a_later_one_gets_its_own_queue(ros_master):
    """A test's publisher (``advertise``) is unregistered when its module's stack ends: rospy
    keeps one publisher per topic in the process, with its connections' queue size, and a
    /joint_states publisher with a queue of one left by an earlier module made a later
    module's nodes drop joint states."""
    from sensor_msgs.msg import JointState

    from ow_bringup.testing import advertise
    from ow_bringup.testing_node import unregister_endpoints

    topic = "/harness_states"
    manager = rospy.impl.registration.get_topic_manager()
    advertise(topic, JointState, queue_size=1)
    assert manager.get_publisher_impl(topic).queue_size == 1
    unregister_endpoints()  # what the module's stack does when it ends
    assert manager.get_publisher_impl(topic) is None
    publishers, _, _ = ros_master.call("getSystemState")
    assert topic not in dict(publishers)
    later = advertise(topic, JointState, queue_size=None)  # the next module's
    assert later.impl.queue_size is None
    unregister_endpoints()


def test_a_fault_a_module_left_injected_is_not_injected_in_the_next(ros_master):
    """The ``/faults`` server (dynamic_reconfigure) writes its configuration under ``/faults``
    and the ``faults`` node reads its launch-time faults from there. A module's stack puts the
    master's parameters back when it ends, so a fault a module left injected (a locked pan
    joint: a later module's camera tests saw PAN_TILT_EXECUTION_ERROR beside their
    CAMERA_GOAL_ERROR) is not injected from the start in the next; parameters that were there
    before keep their values."""
    from dynamic_reconfigure.client import Client

    from ow_bringup.testing import module_stack

    ros_master.set_param("/harness_kept", 1)
    at_start = []
    for leave_injected in (True, False):
        with module_stack(ros_master) as stack:
            stack.start_node("ow_faults", "faults", wait_for_services=["/faults/set_parameters"])
            client = Client("/faults", timeout=30)
            at_start.append(client.get_configuration(timeout=30)["ant_pan_joint_locked_failure"])
            if leave_injected:
                client.update_configuration({"ant_pan_joint_locked_failure": True})
                ros_master.set_param("/harness_kept", 2)
            client.close()
    assert at_start == [False, False]
    assert not ros_master.call("hasParam", "/faults")
    assert ros_master.call("getParam", "/harness_kept") == 1
    ros_master.delete_param("/harness_kept")


IGNORING_SIGINT = """
import signal, time
signal.signal(signal.SIGINT, signal.SIG_IGN)
print("ready", flush=True)
time.sleep(600)
"""


# Takes SIGINT as a program started from a shell does, whatever this process passes on (a
# worker of make test once passed SIGINT on ignored), and sleeps in short steps: Python runs a
# signal's handler between bytecodes, so a SIGINT that arrives after ``print`` but before a single
# long ``time.sleep`` starts is handled only when that sleep ends (1 child in ~70 under load kept
# sleeping, and was killed after the harness's 10 s).
PLAIN = """
import signal, time
signal.signal(signal.SIGINT, signal.default_int_handler)
print("ready", flush=True)
while True:
    time.sleep(0.05)
"""


def test_a_process_that_ignores_sigint_is_told_so_and_stopped_with_sigterm(tmp_path):
    ignoring = subprocess.Popen(
        ["python", "-c", IGNORING_SIGINT], stdout=subprocess.PIPE, start_new_session=True
    )
    plain = subprocess.Popen(
        ["python", "-c", PLAIN],
        stdout=subprocess.PIPE,
        start_new_session=True,
    )
    try:
        assert ignoring.stdout.readline() == b"ready\n"
        assert plain.stdout.readline() == b"ready\n"
        assert ignores_signal(ignoring.pid, signal.SIGINT)
        assert not ignores_signal(plain.pid, signal.SIGINT)
        assert not ignores_signal(ignoring.pid, signal.SIGTERM)
        log = tmp_path / "node.log"
        # not -SIGKILL after the timeout; the other leaves on SIGINT (KeyboardInterrupt)
        assert NodeProcess("ignoring", ignoring, log).stop() == -signal.SIGTERM
        assert NodeProcess("plain", plain, log).stop() == -signal.SIGINT
    finally:
        for proc in (ignoring, plain):
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait()


def test_a_master_that_inherited_sigint_ignored_is_stopped_without_waiting_for_the_kill(
    tmp_path,
):
    """A mission run in the background (``nohup rosrun ow_mission mission &``) starts its master
    with SIGINT ignored; rosmaster then never saw the harness's SIGINT and was killed after 10 s."""
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        master = RosMaster(tmp_path)
        master.start()
    finally:
        signal.signal(signal.SIGINT, previous)
    proc = master.proc
    assert proc is not None
    assert ignores_signal(proc.pid, signal.SIGINT)
    master.stop()
    assert proc.returncode == -signal.SIGTERM


def test_a_master_in_process_serves_other_processes_and_stops(tmp_path):
    """The mission's master runs on threads of its own process: a node in another process
    registers with it, the parameter server answers, and once stopped nothing listens."""
    master = RosMaster(tmp_path, in_process=True)
    master.start()
    try:
        assert master.proc is None
        master.set_param("/answer", 42)
        got = subprocess.run(
            ["rosparam", "get", "/answer"],
            env=master.env,
            capture_output=True,
            text=True,
            timeout=60,
            check=True,
        )
        assert got.stdout.strip() == "42"
        stack = RosStack(master)
        try:
            stack.start_node("ow_faults", "faults", wait_for_services=["/faults/set_parameters"])
            assert "/faults/parameter_updates" in master.published_topics()
            # The harness reads the system state without XML-RPC: the same answer as with it.
            code, _, over_xmlrpc = xmlrpc.client.ServerProxy(master.uri).getSystemState("/test")
            assert code == 1
            assert master.call("getSystemState") == over_xmlrpc
        finally:
            stack.shutdown()
    finally:
        master.stop()
    with pytest.raises(OSError):
        master.call("getSystemState")


def test_a_master_in_process_on_a_taken_port_fails_naming_it(tmp_path):
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        master = RosMaster(tmp_path, port=port, in_process=True)
        with pytest.raises(HarnessError, match=f"rosmaster on port {port} could not start"):
            master.start(timeout_s=10.0)


FAILING_MODULE = """
def test_fails_with_a_node_running(ros_stack):
    ros_stack.start_node(
        "rosout", "rosout", name="tail_rosout", wait_for_services=["/tail_rosout/get_loggers"]
    )
    assert False, "on purpose"


def test_passes(ros_stack):
    pass
"""


def test_a_failed_test_reports_the_end_of_its_modules_node_logs(tmp_path):
    """A failure under a loaded machine is rarely seen twice, and the node logs are gone with
    the session's temporary directory: the report of a failed test carries their ends."""
    (tmp_path / "conftest.py").write_text('pytest_plugins = ["ow_bringup.testing"]\n')
    (tmp_path / "test_failing.py").write_text(FAILING_MODULE)
    run = subprocess.run(
        [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-q", str(tmp_path)],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        timeout=120,
        check=False,
    )
    assert run.returncode == 1, run.stdout + run.stderr
    assert "1 failed, 1 passed" in run.stdout
    assert run.stdout.count("node tail_rosout (running), log end") == 1, run.stdout
