"""The power and recorder nodes on a real master, fed by joint states this test publishes.

Constant torque x constant velocity gives a closed-form power and energy; the recorder is stopped
with SIGINT (a complete bag) and with SIGKILL (only the open file lost).
"""

import json
import re
import signal
import subprocess
import time
import xmlrpc.client
from pathlib import Path

import pytest
import rospy
from rosbags.highlevel import AnyReader
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Header, String

from ow_bringup.testing import advertise, subscribe, wait_connected
from ow_msgs.msg import Operation, Power
from ow_msgs.srv import RecorderProgress

PERIOD_S = 0.01  # 100 Hz of simulation time, as the simulation publishes
P0_W = 43.0


def _wait(condition, what, timeout_s=20.0):
    deadline = time.monotonic() + timeout_s
    while not condition():
        if time.monotonic() > deadline:
            pytest.fail(f"timed out waiting for {what() if callable(what) else what}")
        time.sleep(0.02)


def _wait_connected(stack, node, topics):
    """Wait until ``node`` receives each of ``topics`` over an open connection (getBusInfo)."""
    uri = stack.master.call("lookupNode", node)

    def connected():
        _, _, info = xmlrpc.client.ServerProxy(uri).getBusInfo("/pytest")
        inbound = {c[4] for c in info if c[2] == "i" and c[5]}
        return set(topics) <= inbound

    _wait(connected, f"{node} connected to {topics}")


def _wait_sending(stack, node, topic, subscribers):
    """Wait until ``node`` writes ``topic`` to each of the ``subscribers`` (node names) over an
    open connection: a subscriber connected on its side is added on the publisher's side last,
    and what is published before then does not reach it."""
    uri = stack.master.call("lookupNode", node)

    def sending():
        _, _, info = xmlrpc.client.ServerProxy(uri).getBusInfo("/pytest")
        return set(subscribers) <= {c[1] for c in info if c[2] == "o" and c[4] == topic and c[5]}

    _wait(sending, f"{node} sending {topic} to {subscribers}")


def _wait_publishing(publisher, subscribers):
    """Wait until our ``publisher`` has a connection to each of the ``subscribers`` (node names;
    the publisher side adds them last). Counting connections is not enough: a subscriber of this
    process left by an earlier module counts too, and the named node could still miss the first
    messages."""

    def connected():
        return set(subscribers) <= {c.endpoint_id for c in publisher.impl.connections}

    _wait(connected, lambda: f"{publisher.name} connected to {subscribers}")


class Feeder:
    """Publishes /clock and joint states (and operation markers) under a topic prefix."""

    def __init__(self, joint_states_topic="/joint_states"):
        # Written in this thread (queue_size None): nothing is queued that a lagging writer
        # thread could drop. (make test: this test wrote 200 of its 201 joint states on both
        # connections, made with the queue of one of a /joint_states publisher an earlier
        # module had left registered in this process; see ow_bringup.testing.advertise.)
        self.clock = advertise("/clock", Clock, queue_size=None)
        self.joint_states = advertise(joint_states_topic, JointState, queue_size=None)
        self.operation = advertise("/arm/operation", Operation, queue_size=10, latch=True)

    def step(self, k, names, velocity, effort, start_s=100.0):
        stamp = rospy.Time.from_sec(start_s + k * PERIOD_S)
        self.clock.publish(Clock(clock=stamp))
        self.joint_states.publish(
            JointState(
                header=Header(stamp=stamp),
                name=names,
                position=[float(k)] * len(names),
                velocity=velocity,
                effort=effort,
            )
        )
        time.sleep(0.002)  # ~500 Hz of wall time: no subscriber queue overflows
        return stamp

    def marker(self, stamp, op_id, event):
        self.operation.publish(
            Operation(
                header=Header(stamp=stamp),
                id=op_id,
                name="dig_linear",
                event=event,
                parameters='{"depth": 0.01}',
                success=True,
                message="done",
            )
        )


class Status:
    def __init__(self, node_name):
        self.latest = {}
        self._sub = subscribe(f"/{node_name}/status", String, self._on)

    def _on(self, msg):
        self.latest = json.loads(msg.data)


def test_power_node_sums_the_configured_joints_by_name(ros_stack):
    ros_stack.start_node(
        "ow_power",
        "power",
        name="power_subset",
        params={"auxiliary_power_w": 10.0, "joints": ["j_b", "j_a"]},
        args=["joint_states:=/subset/joint_states", "power:=/subset/power"],
        wait_for_topics=["/subset/power"],
    )
    received = []
    sub = subscribe("/subset/power", Power, received.append)
    feeder = Feeder("/subset/joint_states")
    _wait_connected(ros_stack, "/power_subset", ["/subset/joint_states"])
    _wait_publishing(feeder.joint_states, ["/power_subset"])
    wait_connected(sub)  # the power node writes to it
    for k in range(101):  # 1 s; the joint order changes every message
        names = ["j_a", "j_c", "j_b"] if k % 2 else ["j_c", "j_b", "j_a"]
        # j_a: 20 N m x 0.1 rad/s = 2 W, j_b: -5 N m x 0.2 rad/s = -1 W, j_c (not summed) 90 W.
        values = {"j_a": (0.1, 20.0), "j_b": (0.2, -5.0), "j_c": (3.0, 30.0)}
        feeder.step(k, names, [values[n][0] for n in names], [values[n][1] for n in names])
    _wait(
        lambda: received and received[-1].header.stamp.to_sec() == pytest.approx(101.0),
        "the power of the last joint state",
    )
    last = received[-1]
    assert list(last.name) == ["j_b", "j_a"]
    assert list(last.joint_power) == pytest.approx([-1.0, 2.0])
    assert last.mechanical_power == pytest.approx(1.0)
    assert last.mechanical_power_abs == pytest.approx(3.0)
    assert last.total_power == pytest.approx(11.0)
    assert last.electrical_power == pytest.approx(3.0 / 0.9 + 10.0)
    assert last.mechanical_energy == pytest.approx(1.0)  # 1 W for 1 s of stamps
    assert last.energy == pytest.approx(11.0)
    sub.unregister()


def _missing_stamps(
    directory: Path, topics: list[str], expected: set[float]
) -> dict[str, list[float]]:
    """Per topic of ``topics`` in the bags in ``directory``, the ``expected`` header stamps (s,
    to the ms) it lacks."""
    with AnyReader(sorted(directory.glob("*.bag"))) as reader:
        seen: dict[str, set[float]] = {topic: set() for topic in topics}
        wanted = [c for c in reader.connections if c.topic in seen]
        for connection, _, raw in reader.messages(connections=wanted):
            stamp = reader.deserialize(raw, connection.msgtype).header.stamp
            seen[connection.topic].add(round(stamp.sec + 1e-9 * stamp.nanosec, 3))
    return {topic: sorted(expected - stamps) for topic, stamps in seen.items()}


def _transport_counts(stack, feed) -> str:
    """What each side of the feed's and the power node's connections counted (rospy's bus
    statistics): which of the test's writer, the power node's reader or its publisher lost
    messages, and whether a connection was replaced (more than one id)."""
    _, _, (pub_stats, sub_stats, _) = xmlrpc.client.ServerProxy(
        stack.master.call("lookupNode", "/power")
    ).getBusStats("/pytest")
    written = [(c.id, c.endpoint_id, c.stat_num_msg, not c.done) for c in feed.impl.connections]
    return (
        f"the test wrote /joint_states (id, node, messages, open): {written}; the power node "
        f"received (topic, [id, bytes, messages, drops, open]): {sub_stats}; it published "
        f"(topic, bytes, [id, bytes, messages, open]): {pub_stats}"
    )


def test_sigint_leaves_a_complete_bag_that_ros_tools_and_the_analysis_read(ros_stack, tmp_path):
    ros_stack.start_node(
        "ow_power",
        "power",
        name="power",
        params={"auxiliary_power_w": P0_W},
        wait_for_topics=["/power"],
    )
    recorder = ros_stack.start_node(
        "ow_power",
        "record",
        name="record_sigint",
        params={
            "output_dir": str(tmp_path),
            "prefix": "sigint",
            "split_duration_s": 0.0,
            "topics": ["/power", "/joint_states", "/arm/operation"],
        },
        wait_for_topics=["/record_sigint/status"],
    )
    status = Status("record_sigint")
    feeder = Feeder()
    # A witness of /power beside the recorder: if the recorder misses messages, whether the
    # power node published them says on which side they were lost.
    witnessed = []
    witness = subscribe("/power", Power, lambda m: witnessed.append(m.header.stamp.to_sec()))
    wait_connected(witness)
    _wait_connected(ros_stack, "/power", ["/joint_states"])
    _wait_connected(
        ros_stack, "/record_sigint", ["/clock", "/power", "/joint_states", "/arm/operation"]
    )
    _wait_publishing(feeder.joint_states, ["/power", "/record_sigint"])
    # Latched: a connection added after the START marker would get only the END one.
    _wait_publishing(feeder.operation, ["/record_sigint"])
    _wait_sending(ros_stack, "/power", "/power", ["/record_sigint"])
    names = ["j_shou_pitch", "j_prox_pitch"]
    n = 201  # 2 s
    for k in range(n):
        stamp = feeder.step(k, names, [0.1, -0.2], [50.0, 30.0])  # 5 W - 6 W = -1 W, |.| 11 W
        if k == 50:
            feeder.marker(stamp, 1, Operation.START)
        if k == 150:
            feeder.marker(stamp, 1, Operation.END)
    try:
        _wait(lambda: status.latest.get("messages") == 2 * n + 2, "")
    except pytest.fail.Exception:
        counts = _transport_counts(ros_stack, feeder.joint_states)  # while the recorder is up
        recorder.signal(signal.SIGINT)
        recorder.proc.wait(timeout=20)
        fed = {round(100.0 + k * PERIOD_S, 3) for k in range(n)}
        missing = _missing_stamps(tmp_path, ["/joint_states", "/power"], fed)
        pytest.fail(
            f"{status.latest.get('messages')} of {2 * n + 2} messages recorded; stamps of the "
            f"feed missing: {missing}; of /power as the test received it: "
            f"{sorted(fed - {round(t, 3) for t in witnessed})}; "
            f"{counts}"
        )
    witness.unregister()
    # How far each topic is written: what a mission waits on before it stops the stack.
    progress = rospy.ServiceProxy("/record_sigint/progress", RecorderProgress)()
    assert list(progress.topics) == ["/arm/operation", "/joint_states", "/power"]
    assert list(progress.messages) == [2, n, n]
    assert progress.latest_s[1] == progress.latest_s[2] == pytest.approx(stamp.to_sec())
    recorder.signal(signal.SIGINT)
    assert recorder.proc.wait(timeout=20) == 0
    bags = sorted(tmp_path.glob("*.bag"))
    assert len(bags) == 1 and not list(tmp_path.glob("*.active"))

    with AnyReader(bags) as reader:
        counts = {c.topic: c.msgcount for c in reader.connections}
    assert counts == {"/power": n, "/joint_states": n, "/arm/operation": 2}
    info = subprocess.run(
        ["rosbag", "info", str(bags[0])], capture_output=True, text=True, check=True
    ).stdout
    assert "ow_msgs/Power" in info and re.search(rf"/joint_states\s+{n} msgs", info)
    echo = subprocess.run(
        ["rostopic", "echo", "-b", str(bags[0]), "-n", "1", "/arm/operation"],
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    assert "dig_linear" in echo

    out = subprocess.run(
        ["rosrun", "ow_power", "analyze", str(tmp_path), "-o", str(tmp_path / "out")],
        capture_output=True,
        text=True,
        check=True,
    )
    assert "dig_linear" in out.stdout
    ops = json.loads(next((tmp_path / "out").glob("*_operations.json")).read_text())
    (op,) = ops["operations"]
    assert op["duration_s"] == pytest.approx(1.0)
    assert op["mechanical_energy_j"] == pytest.approx(-1.0)
    assert op["mechanical_energy_abs_j"] == pytest.approx(11.0)
    assert op["energy_wh"] == pytest.approx((P0_W - 1.0) / 3600.0)
    assert list((tmp_path / "out").glob("*_power.png"))


def test_sigkill_loses_only_the_open_file(ros_stack, tmp_path):
    recorder = ros_stack.start_node(
        "ow_power",
        "record",
        name="record_kill",
        params={
            "output_dir": str(tmp_path),
            "prefix": "kill",
            "split_duration_s": 1.0,
            "topics": ["/kill/joint_states"],
        },
        wait_for_topics=["/record_kill/status"],
    )
    status = Status("record_kill")
    feeder = Feeder("/kill/joint_states")
    _wait_connected(ros_stack, "/record_kill", ["/clock", "/kill/joint_states"])
    _wait_publishing(feeder.joint_states, ["/record_kill"])
    n = 351  # 3.5 s of simulation time: three full files and an open one
    for k in range(n):
        feeder.step(k, ["j"], [0.0], [0.0], start_s=200.0)
    _wait(
        lambda: len(status.latest.get("closed", [])) >= 3 and status.latest.get("messages") == n,
        "three closed bags",
    )
    closed = [Path(p) for p in status.latest["closed"]]
    recorder.signal(signal.SIGKILL)
    recorder.proc.wait(timeout=20)

    bags = sorted(tmp_path.glob("*.bag"))
    assert bags == closed
    assert len(list(tmp_path.glob("*.bag.active"))) == 1  # the open file, lost
    with AnyReader(bags) as reader:
        positions = [
            int(reader.deserialize(raw, c.msgtype).position[0]) for c, _, raw in reader.messages()
        ]
    # What was flushed is a gap-free prefix of what was sent, and at most the last ~1 s is lost.
    assert positions == list(range(len(positions)))
    assert n - len(positions) <= 1.0 / PERIOD_S + 20
    subprocess.run(["rosbag", "info", str(bags[-1])], capture_output=True, check=True)
