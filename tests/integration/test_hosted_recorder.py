"""The recorder as a component of another node (ow_power.hosted_record_node), hosted by this
test process on a real master as the mission's process hosts it: the same bags as the record
node, a topic the host subscribes to itself included, its progress and status where the record
node's are."""

from __future__ import annotations

import json
import time

import pytest
import rospy
from rosbags.highlevel import AnyReader
from sensor_msgs.msg import JointState
from std_msgs.msg import Header, String

from ow_mission.testing import advertise, subscribe
from ow_msgs.srv import RecorderProgress
from ow_power.errors import ConfigError
from ow_power.hosted_record_node import HostedRecorder

NAMESPACE = "/record_hosted"
TYPED, RAW = "/hosted/joint_states", "/hosted/notes"
N = 50


def _wait(condition, what, timeout_s=20.0):
    deadline = time.monotonic() + timeout_s
    while not condition():
        if time.monotonic() > deadline:
            pytest.fail(f"timed out waiting for {what}")
        time.sleep(0.01)


def _connected(publisher, node):
    return node in {c.endpoint_id for c in publisher.impl.connections}


def test_a_hosted_recorder_writes_what_the_record_node_writes_and_its_hosts_own_topics(
    ros_stack, tmp_path
):
    # The host takes this topic itself, after the recorder started (rospy: one subscription per
    # topic and process, typed by its first subscriber): named, the recorder subscribes to it
    # typed and writes the host's messages serialised again.
    taken = []
    # One file: the notes have no stamp and are written at this process's clock.
    params = {"output_dir": str(tmp_path), "prefix": "hosted", "split_duration_s": 0.0}
    params["topics"] = [TYPED, RAW]
    recorder = HostedRecorder(params, NAMESPACE, typed={TYPED: JointState, "/other": String})
    try:
        subscribe(TYPED, JointState, lambda m: taken.append(m.header.stamp.to_sec()))
        assert rospy.get_param(f"{NAMESPACE}/topics") == [TYPED, RAW]
        statuses = []
        subscribe(f"{NAMESPACE}/status", String, lambda m: statuses.append(json.loads(m.data)))
        joints = advertise(TYPED, JointState, queue_size=None)
        notes = advertise(RAW, String, queue_size=None)
        me = rospy.get_name()
        _wait(lambda: _connected(joints, me) and _connected(notes, me), "the recorder connected")
        sent = []
        for k in range(N):
            stamp = rospy.Time.from_sec(10.0 + 0.01 * k)
            msg = JointState(
                header=Header(seq=k, stamp=stamp, frame_id="base_link"),
                name=["j_shou_yaw", "j_grinder"],
                position=[0.1 * k, -0.2],
                velocity=[0.5, 0.0],
                effort=[3.0, float(k)],
            )
            joints.publish(msg)
            notes.publish(String(data=f"note {k}"))
            sent.append(msg)
            time.sleep(0.002)
        progress = rospy.ServiceProxy(f"{NAMESPACE}/progress", RecorderProgress)
        _wait(lambda: list(progress().messages) == [N, N], f"{N} messages of each topic")
        reply = progress()
        assert list(reply.topics) == [TYPED, RAW]
        assert reply.latest_s[0] == pytest.approx(10.0 + 0.01 * (N - 1))
        _wait(lambda: statuses and statuses[-1]["messages"] == 2 * N, "its status, every second")
    finally:
        bags = recorder.close()
        rospy.delete_param(NAMESPACE)
    assert recorder.close() == bags  # once
    assert len(bags) == 1 and bags[0].parent == tmp_path and not list(tmp_path.glob("*.active"))
    assert taken == [m.header.stamp.to_sec() for m in sent]  # the host got its messages
    with AnyReader(bags) as reader:
        typed = [c for c in reader.connections if c.topic == TYPED]
        assert typed[0].msgtype == "sensor_msgs/msg/JointState"
        read = [reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages(typed)]
        times = [t for _, t, _ in reader.messages(typed)]
        notes_read = [
            reader.deserialize(raw, c.msgtype).data
            for c, _, raw in reader.messages([c for c in reader.connections if c.topic == RAW])
        ]
    # Byte for byte what was published: at its header stamp, every field as sent.
    assert times == [m.header.stamp.to_nsec() for m in sent]
    for got, msg in zip(read, sent, strict=True):
        assert (got.header.seq, got.header.frame_id) == (msg.header.seq, "base_link")
        assert list(got.name) == msg.name and got.position.tolist() == msg.position
        assert got.effort.tolist() == msg.effort
    assert notes_read == [f"note {k}" for k in range(N)]


def test_a_hosted_recorder_refuses_bad_parameters_naming_them(ros_stack, tmp_path):
    with pytest.raises(ConfigError, match="split_duration_s"):
        HostedRecorder({"output_dir": str(tmp_path), "split_duration_s": -1.0}, NAMESPACE)
    with pytest.raises(ConfigError, match="topic"):
        HostedRecorder({"output_dir": str(tmp_path), "topicz": ["/a"]}, NAMESPACE)
