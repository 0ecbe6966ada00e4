"""Reading chosen topics of a run's split bags in one pass (ow_power.bagread), without ROS."""

from __future__ import annotations

from datetime import datetime
from pathlib import Path

import pytest
from rosbags.highlevel import AnyReader
from rosbags.rosbag1 import Writer
from rosbags.typesys import Stores, get_typestore

from ow_power.bagread import merge_messages, read_messages
from ow_power.errors import BagReadError
from ow_power.synthetic import write_split_series

STORE = get_typestore(Stores.ROS1_NOETIC)
START = datetime(2025, 1, 2, 3, 4, 5)


def _split_run(directory: Path) -> list[Path]:
    return write_split_series(directory, START)


def _bag(path: Path, messages: list[tuple[str, str, int, object]]) -> Path:
    """A bag of (topic, msgtype, bag time ns, message) written in the given order."""
    with Writer(path) as writer:
        connections = {}
        for topic, msgtype, t_ns, msg in messages:
            if topic not in connections:
                connections[topic] = writer.add_connection(topic, msgtype, typestore=STORE)
            writer.write(connections[topic], t_ns, STORE.serialize_ros1(msg, msgtype))
    return path


def _float64(value: float) -> object:
    return STORE.types["std_msgs/msg/Float64"](data=value)


def test_each_topic_is_in_time_order_across_the_split_files(tmp_path):
    bags = _split_run(tmp_path)
    assert len(bags) == 3
    found = read_messages(bags, ["/a", "/b"])
    assert [msg.data for _, msg in found["/a"]] == pytest.approx([1.0 + 0.1 * k for k in range(30)])
    assert [ns for ns, _ in found["/a"]] == [10**9 + k * 10**8 for k in range(30)]
    assert [msg.data for _, msg in found["/b"]] == [0, 5, 10, 15, 20, 25]


def test_a_latched_message_comes_once_per_file_as_anyreader_gives_it(tmp_path):
    bags = _split_run(tmp_path)
    found = read_messages(bags, ["/state"])["/state"]
    assert [msg.data for _, msg in found] == ["ready"] * len(bags)
    with AnyReader(bags) as reader:
        connections = [c for c in reader.connections if c.topic == "/state"]
        expected = [ns for _, ns, _ in reader.messages(connections=connections)]
    assert [ns for ns, _ in found] == expected


def test_a_topic_no_bag_has_gives_an_empty_list(tmp_path):
    bags = _split_run(tmp_path)
    found = read_messages(bags, ["/a", "/nobody"])
    assert found["/nobody"] == []
    assert set(found) == {"/a", "/nobody"}
    assert read_messages(bags, ["/nobody"]) == {"/nobody": []}


def test_messages_are_sorted_by_bag_time_and_equal_times_keep_the_file_order(tmp_path):
    first = _bag(
        tmp_path / "first.bag",
        [
            ("/x", "std_msgs/msg/Float64", 5, _float64(1.0)),
            ("/x", "std_msgs/msg/Float64", 2, _float64(0.0)),
        ],
    )
    second = _bag(
        tmp_path / "second.bag",
        [
            ("/x", "std_msgs/msg/Float64", 5, _float64(2.0)),
            ("/x", "std_msgs/msg/Float64", 1, _float64(-1.0)),
        ],
    )
    found = read_messages([first, second], ["/x"])["/x"]
    assert [(ns, msg.data) for ns, msg in found] == [(1, -1.0), (2, 0.0), (5, 1.0), (5, 2.0)]
    found = read_messages([second, first], ["/x"])["/x"]
    assert [(ns, msg.data) for ns, msg in found] == [(1, -1.0), (2, 0.0), (5, 2.0), (5, 1.0)]


def test_an_unreadable_or_missing_file_is_an_error_naming_it(tmp_path):
    good = _split_run(tmp_path / "run")
    junk = tmp_path / "junk.bag"
    junk.write_bytes(b"not a bag")
    with pytest.raises(BagReadError, match=r"cannot read .*junk\.bag"):
        read_messages([*good, junk], ["/a"])
    with pytest.raises(BagReadError, match=r"cannot read .*missing\.bag"):
        read_messages([tmp_path / "missing.bag"], ["/a"])


def test_a_definition_that_does_not_match_its_md5_is_an_error_naming_the_file(tmp_path):
    path = tmp_path / "lying.bag"
    msgdef, _ = STORE.generate_msgdef("std_msgs/msg/Float64")
    with Writer(path) as writer:
        connection = writer.add_connection(
            "/x", "std_msgs/msg/Float64", msgdef=msgdef, md5sum="0" * 32
        )
        writer.write(connection, 1, STORE.serialize_ros1(_float64(1.0), "std_msgs/msg/Float64"))
    with pytest.raises(BagReadError, match=r"lying\.bag: the definition of std_msgs/msg/Float64"):
        read_messages([path], ["/x"])
    # A topic not asked for is not even parsed.
    assert read_messages([path], ["/y"]) == {"/y": []}


def _values(found):
    return {topic: [(ns, msg.data) for ns, msg in series] for topic, series in found.items()}


@pytest.mark.parametrize("split", [0, 1, 2, 3])
def test_files_read_in_two_goes_and_merged_give_what_one_pass_gives(tmp_path, split):
    bags = _split_run(tmp_path)
    topics = ["/a", "/b", "/state", "/nobody"]
    merged = merge_messages(
        read_messages(bags[:split], topics), read_messages(bags[split:], topics)
    )
    assert _values(merged) == _values(read_messages(bags, topics))


def test_merged_messages_at_equal_times_keep_the_earlier_files_first(tmp_path):
    first = _bag(tmp_path / "first.bag", [("/x", "std_msgs/msg/Float64", 5, _float64(1.0))])
    second = _bag(
        tmp_path / "second.bag",
        [
            ("/x", "std_msgs/msg/Float64", 5, _float64(2.0)),
            ("/x", "std_msgs/msg/Float64", 1, _float64(-1.0)),
        ],
    )
    merged = merge_messages(read_messages([first], ["/x"]), read_messages([second], ["/x"]))
    assert _values(merged) == _values(read_messages([first, second], ["/x"]))
    assert [v for _, v in _values(merged)["/x"]] == [-1.0, 1.0, 2.0]
