"""Split bag writing and per-operation analysis on synthetic runs, without ROS."""

import json
import subprocess
from datetime import datetime

import numpy as np
import pandas as pd
import pytest
from rosbags.highlevel import AnyReader

from ow_power.analysis import analyze, format_table, pair_operations, plot_power, write_summary
from ow_power.bagwriter import SplitBagWriter, record_time_ns, stamp_offset, starts_with_header
from ow_power.config import PowerConfig
from ow_power.errors import AnalysisError, RecorderError
from ow_power.synthetic import OW_MSGS_DIR, BagMessages, Segment, ow_typestore, write_run

JOINTS = ("j_shou_yaw", "j_shou_pitch", "j_prox_pitch", "j_grinder")
SEGMENTS = (
    Segment("unstow", 3.0, {"j_shou_pitch": 0.1}, {"j_shou_pitch": 50.0}),  # 5 W
    Segment(  # +2 W and -6 W: net -4 W, |.| 8 W
        "guarded_move",
        4.0,
        {"j_shou_pitch": 0.1, "j_prox_pitch": -0.2},
        {"j_shou_pitch": 20.0, "j_prox_pitch": 30.0},
    ),
    Segment("grind", 2.5, {"j_grinder": 0.1}, {"j_grinder": 1.0}),  # 0.1 W
)
START = datetime(2025, 1, 2, 3, 4, 5)


def _run(tmp_path, split_duration_s=0.0, with_power=True, compression="none"):
    writer = SplitBagWriter(
        tmp_path, split_duration_s=split_duration_s, start=START, compression=compression
    )
    write_run(writer, SEGMENTS, JOINTS, with_power=with_power)
    return writer.close()


def _count(bags, topic):
    with AnyReader(bags) as reader:
        return sum(1 for _ in reader.messages([c for c in reader.connections if c.topic == topic]))


def test_the_typestore_has_every_ow_msgs_message_as_ros_generates_it():
    import ow_msgs.msg

    assert OW_MSGS_DIR.parts[-2:] == ("ow_msgs", "msg")
    names = sorted(path.stem for path in OW_MSGS_DIR.glob("*.msg"))
    assert "Power" in names and "Operation" in names
    store = ow_typestore()
    for name in names:
        _, md5 = store.generate_msgdef(f"ow_msgs/msg/{name}")
        assert md5 == getattr(ow_msgs.msg, name)._md5sum, name


def test_a_run_is_split_into_closed_bags_that_rosbag_reads(tmp_path):
    bags = _run(tmp_path, split_duration_s=4.0)
    assert [b.name for b in bags] == [f"ow_2025-01-02-03-04-05_{i:04d}.bag" for i in range(3)]
    assert not list(tmp_path.glob("*.active"))
    # 9.5 s at 100 Hz: 951 joint states, none lost or doubled by the splits.
    assert _count(bags, "/joint_states") == 951
    info = subprocess.run(
        ["rosbag", "info", str(bags[1])], capture_output=True, text=True, check=True
    ).stdout
    assert "ow_msgs/Power" in info and "sensor_msgs/JointState" in info
    assert "duration:    4.0s" in info


def test_bz2_bags_are_readable(tmp_path):
    bags = _run(tmp_path, compression="bz2")
    assert _count(bags, "/power") == 951


def test_a_new_run_never_overwrites_an_old_one(tmp_path):
    first = _run(tmp_path)
    contents = first[0].read_bytes()
    second = _run(tmp_path)
    assert second[0].name == "ow_2025-01-02-03-04-05-1_0000.bag"
    assert first[0].read_bytes() == contents


def test_a_bag_in_the_way_is_an_error_not_an_overwrite(tmp_path):
    writer = SplitBagWriter(tmp_path, start=START)
    blocker = tmp_path / f"{writer.name}_0000.bag"
    blocker.write_bytes(b"precious")
    messages = BagMessages()
    ros1_type, md5, msgdef, data = messages.serialize("std_msgs/msg/Float64", data=1.0)
    with pytest.raises(RecorderError, match="exists already, not overwriting"):
        writer.write("/x", ros1_type, md5, msgdef, 0, data)
    assert blocker.read_bytes() == b"precious"


def test_a_closed_writer_drops_late_messages(tmp_path):
    writer = SplitBagWriter(tmp_path)
    ros1_type, md5, msgdef, data = BagMessages().serialize("std_msgs/msg/Float64", data=1.0)
    assert writer.write("/x", ros1_type, md5, msgdef, 1, data)
    assert len(writer.close()) == 1
    assert not writer.write("/x", ros1_type, md5, msgdef, 2, data)
    assert writer.close() == writer.closed_files


def test_split_by_size(tmp_path):
    writer = SplitBagWriter(tmp_path, split_size_mb=0.001)  # 1000 bytes
    ros1_type, md5, msgdef, data = BagMessages().serialize("std_msgs/msg/Float64", data=1.0)
    for k in range(500):  # 8 bytes each
        writer.write("/x", ros1_type, md5, msgdef, k, data)
    bags = writer.close()
    assert len(bags) == 4
    assert _count(bags, "/x") == 500


@pytest.mark.parametrize("compression", ["none", "bz2"])
def test_the_writer_writes_the_bytes_rosbags_writes(tmp_path, compression):
    """The recorder's writer (its records from bytes made once per connection, the chunks it
    wrote kept as counts) against rosbags' own, message for message: the same file."""
    from rosbags.rosbag1 import Writer

    from ow_power.bagwriter import _Writer

    messages = BagMessages()
    kinds = [messages.serialize("std_msgs/msg/String", data="x" * (40 + 13 * k)) for k in range(3)]
    files = []
    for name, writer_class in (("rosbags.bag", Writer), ("ours.bag", _Writer)):
        writer = writer_class(tmp_path / name)
        if compression == "bz2":
            writer.set_compression(Writer.CompressionFormat.BZ2)
        writer.open()
        connections = [
            writer.add_connection(f"/t{k}", "std_msgs/msg/String", msgdef=msgdef, md5sum=md5)
            for k, (_, md5, msgdef, _) in enumerate(kinds)
        ]
        for k in range(40000):  # a few chunks, in uneven turns; stamps past 2**32 ns
            c = (k * k) % 3
            writer.write(connections[c], 5 * 10**9 + 1_000_003 * k, kinds[c][3])
        writer.close()
        files.append((tmp_path / name).read_bytes())
    assert compression == "bz2" or len(files[0]) > 3 * (1 << 20)  # chunks of 1 MB
    assert files[0] == files[1]


def test_a_long_recording_keeps_only_counts_of_the_chunks_it_wrote(tmp_path):
    """The writer keeps, of each chunk written, the message count per connection: rosbag
    reads the counts from the bag's index, and the writer's memory does not grow with the
    messages (it kept a (time, offset) pair per message, about 50 MB for a mission)."""
    import tracemalloc

    writer = SplitBagWriter(tmp_path)
    ros1_type, md5, msgdef, data = BagMessages().serialize("std_msgs/msg/String", data="x" * 400)
    n = 30000  # about 13 MB: a dozen chunks of rosbags' 1 MB
    tracemalloc.start()
    try:
        for k in range(n):
            writer.write(f"/t{k % 3}", ros1_type, md5, msgdef, 10**9 + k * 10**6, data)
        grown, _ = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    (bag,) = writer.close()
    assert grown < 1_500_000, grown  # 4.8 MB before: 160 bytes a message
    info = subprocess.run(
        ["rosbag", "info", "--yaml", str(bag)], capture_output=True, text=True, check=True
    ).stdout
    assert "messages: 30000" in info
    assert [_count([bag], f"/t{i}") for i in range(3)] == [10000] * 3
    with AnyReader([bag]) as reader:
        stamps = [t for _, t, _ in reader.messages()]
    assert stamps == [10**9 + k * 10**6 for k in range(n)]


@pytest.mark.parametrize("with_power", [True, False])
def test_energy_per_operation_matches_the_closed_form(tmp_path, with_power):
    bags = _run(tmp_path, split_duration_s=4.0, with_power=with_power)
    result = analyze([tmp_path])  # a directory stands for its bags
    assert result.bags == bags
    assert result.source == ("/power" if with_power else "/joint_states")
    summary = result.summary.set_index("name")
    expected = {  # (duration s, net W, |W|)
        "unstow": (3.0, 5.0, 5.0),
        "guarded_move": (4.0, -4.0, 8.0),
        "grind": (2.5, 0.1, 0.1),
    }
    for name, (duration, net_w, abs_w) in expected.items():
        row = summary.loc[name]
        assert row["duration_s"] == pytest.approx(duration)
        assert row["mechanical_energy_j"] == pytest.approx(net_w * duration)
        assert row["mechanical_energy_abs_j"] == pytest.approx(abs_w * duration)
        assert row["energy_wh"] == pytest.approx((net_w + 43.0) * duration / 3600.0)
        assert row["peak_power_w"] == pytest.approx(abs_w)
        assert row["mean_power_w"] == pytest.approx(abs_w)
        assert row["success"] and row["complete"]
    # The operations tile the run, so they add up to the whole.
    assert result.total["mechanical_energy_j"] == pytest.approx(
        summary["mechanical_energy_j"].sum()
    )
    assert result.total["duration_s"] == pytest.approx(9.5)


def test_recompute_uses_the_given_p0(tmp_path):
    _run(tmp_path)
    result = analyze([tmp_path], recompute=True, config=PowerConfig(auxiliary_power_w=0.0))
    assert result.source == "/joint_states"
    assert result.total["energy_wh"] == pytest.approx(result.total["mechanical_energy_j"] / 3600)


def test_outputs_table_csv_json_and_png(tmp_path):
    _run(tmp_path)
    result = analyze([tmp_path])
    table = format_table(result)
    assert "guarded_move" in table and "(whole run)" in table and "-16.00" in table
    write_summary(result, tmp_path / "ops.csv", tmp_path / "ops.json")
    csv = pd.read_csv(tmp_path / "ops.csv")
    assert list(csv["name"]) == ["unstow", "guarded_move", "grind"]
    document = json.loads((tmp_path / "ops.json").read_text())
    assert document["operations"][2]["mechanical_energy_j"] == pytest.approx(0.25)
    assert document["total"]["duration_s"] == pytest.approx(9.5)
    plot_power(result, tmp_path / "power.png")
    assert (tmp_path / "power.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_operations_cut_by_the_recording_are_kept_and_flagged():
    markers = [
        {
            "stamp_s": 2.0,
            "id": 7,
            "name": "grind",
            "event": 1,
            "parameters": "{}",
            "success": True,
            "message": "ok",
        },  # started before the recording
        {
            "stamp_s": 3.0,
            "id": 8,
            "name": "stow",
            "event": 0,
            "parameters": "{}",
            "success": False,
            "message": "",
        },  # never ends
    ]
    ops = pair_operations(markers, t_first=1.0, t_last=9.0)
    assert list(ops["name"]) == ["grind", "stow"]
    assert list(ops["start_s"]) == [1.0, 3.0] and list(ops["end_s"]) == [2.0, 9.0]
    assert not ops["complete"].any()
    assert ops["success"].iloc[0] and ops["success"].iloc[1] is None


def test_analysis_errors_name_the_bag(tmp_path):
    with pytest.raises(AnalysisError, match=r"missing\.bag does not exist"):
        analyze([tmp_path / "missing.bag"])
    with pytest.raises(AnalysisError, match=r"no \.bag files"):
        analyze([tmp_path])
    (tmp_path / "junk.bag").write_bytes(b"not a bag")
    with pytest.raises(AnalysisError, match=r"cannot read .*junk\.bag"):
        analyze([tmp_path])


def test_a_bag_without_power_or_joint_states_is_an_error(tmp_path):
    writer = SplitBagWriter(tmp_path)
    ros1_type, md5, msgdef, data = BagMessages().serialize("std_msgs/msg/Float64", data=1.0)
    writer.write("/other", ros1_type, md5, msgdef, 1, data)
    writer.close()
    with pytest.raises(AnalysisError, match="no power samples"):
        analyze([tmp_path])


# ------------------------------------------------------- bags that replay in viewers (ow_viz)
def _with_tf(store):
    """``store`` knowing tf2_msgs/TFMessage (not in rosbags' Noetic store)."""
    from rosbags.typesys import get_types_from_msg

    store.register(
        get_types_from_msg("geometry_msgs/TransformStamped[] transforms", "tf2_msgs/msg/TFMessage")
    )
    return store


def _latched_run(tmp_path):
    """10 s of stamped joint states, split every 4 s, with latched topics sent once at the
    start (two publishers of /tf_static, as the simulation and the viz node) and a terrain
    marker replaced half-way."""
    m = BagMessages()
    _with_tf(m.store)
    writer = SplitBagWriter(tmp_path, split_duration_s=4.0, start=START)
    description = m.serialize("std_msgs/msg/String", data="<robot name='lander'/>")
    writer.write("/robot_description", *description[:3], 10**9, description[3], True, "/viz")
    for callerid, child in (("/sim", "l_ant_foot"), ("/viz", "base_link")):
        transform = m.store.types["geometry_msgs/msg/TransformStamped"](
            header=m.header(10**9, "world"),
            child_frame_id=child,
            transform=m.store.types["geometry_msgs/msg/Transform"](
                translation=m.store.types["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0),
                rotation=m.store.types["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
            ),
        )
        tf = m.serialize("tf2_msgs/msg/TFMessage", transforms=[transform])
        writer.write("/tf_static", *tf[:3], 10**9, tf[3], True, callerid)
    stamps = []
    for k in range(1001):  # 100 Hz, received in clumps of 4 (as the simulation sends them)
        stamp_ns = 10**9 + k * 10**7
        arrival_ns = 10**9 + (k // 4 + 1) * 4 * 10**7
        state = m.serialize(
            "sensor_msgs/msg/JointState",
            header=m.header(stamp_ns, "base_link"),
            name=["j_shou_yaw"],
            position=np.zeros(1),
            velocity=np.zeros(1),
            effort=np.zeros(1),
        )
        stamps.append(stamp_ns)
        writer.write(
            "/joint_states", *state[:3], record_time_ns(state[2], state[3], arrival_ns), state[3]
        )
        if k in (0, 500):
            marker = m.serialize("std_msgs/msg/String", data=f"terrain {k}")
            writer.write("/viz/terrain", *marker[:3], arrival_ns, marker[3], True, "/viz")
    return writer.close(), stamps


def test_every_split_file_has_every_latched_topic_flagged_as_latched(tmp_path):
    import rosbag

    bags, _ = _latched_run(tmp_path)
    assert len(bags) == 3
    for path in bags:
        with rosbag.Bag(str(path)) as bag:
            topics = bag.get_type_and_topic_info().topics
            assert topics["/robot_description"].msg_type == "std_msgs/String"
            assert topics["/tf_static"].message_count == 2  # one per publisher
            assert topics["/tf_static"].connections == 2
            for connection in bag._connections.values():
                latched = connection.topic != "/joint_states"
                assert (connection.header.get("latching") == b"1") == latched, connection.topic
            first_ns = min(t.to_nsec() for _, _, t in bag.read_messages())
            latched_msgs = list(bag.read_messages(topics=["/robot_description", "/tf_static"]))
            # Repeated at the start of the file, so a viewer opening it has them at once.
            assert all(t.to_nsec() == first_ns for _, _, t in latched_msgs), path.name
            children = {
                m.transforms[0].child_frame_id for _, m, _ in bag.read_messages("/tf_static")
            }
            assert children == {"l_ant_foot", "base_link"}
    # The latest terrain is the one repeated: the second half's files show the replaced one.
    with rosbag.Bag(str(bags[-1])) as bag:
        assert [m.data for _, m, _ in bag.read_messages("/viz/terrain")] == ["terrain 500"]


def test_record_times_are_header_stamps_not_arrival_clumps(tmp_path):
    import rosbag

    bags, stamps = _latched_run(tmp_path)
    times = []
    for path in bags:
        with rosbag.Bag(str(path)) as bag:
            for _, msg, t in bag.read_messages("/joint_states"):
                assert t == msg.header.stamp
                times.append(t.to_nsec())
    assert times == stamps


@pytest.mark.parametrize(
    ("msgtype", "has_header"),
    [
        ("sensor_msgs/msg/JointState", True),
        ("visualization_msgs/msg/Marker", True),
        ("geometry_msgs/msg/WrenchStamped", True),
        ("tf2_msgs/msg/TFMessage", False),  # headers inside its transforms only
        ("std_msgs/msg/String", False),
        ("std_msgs/msg/Header", False),
        ("ow_msgs/msg/Power", True),
    ],
)
def test_a_message_is_stamped_by_its_header_only_when_it_starts_with_one(msgtype, has_header):
    msgdef, _ = _with_tf(ow_typestore()).generate_msgdef(msgtype)
    assert starts_with_header(msgdef) == has_header
    genpy_style = "# a comment\nuint8 ADD=0\nHeader header  # stamp\nfloat64 x\n"
    assert starts_with_header(genpy_style)


def _wire(msg) -> bytes:
    from io import BytesIO

    buffer = BytesIO()
    msg.serialize(buffer)
    return buffer.getvalue()


def test_a_list_of_stamped_messages_is_recorded_at_its_first_ones_stamp():
    """/tf and marker arrays have no header of their own: they go in the bag where their first
    transform or marker holds, not when they arrived (the recorder gets the simulation's
    outputs in batches, up to 0.5 s of sim time late, and a viewer replays /tf by bag time)."""
    import genpy
    from geometry_msgs.msg import TransformStamped
    from std_msgs.msg import Header, String
    from tf2_msgs.msg import TFMessage
    from visualization_msgs.msg import Marker, MarkerArray

    def transform(secs: int, nsecs: int) -> TransformStamped:
        return TransformStamped(header=Header(stamp=genpy.Time(secs, nsecs)))

    tf = TFMessage([transform(12, 5), transform(13, 0)])
    assert stamp_offset(TFMessage._full_text) == 8
    assert record_time_ns(TFMessage._full_text, _wire(tf), 1) == 12_000_000_005
    assert record_time_ns(TFMessage._full_text, _wire(TFMessage([])), 1) == 1  # none: arrival
    markers = MarkerArray([Marker(header=Header(stamp=genpy.Time(7, 0)))])
    assert record_time_ns(MarkerArray._full_text, _wire(markers), 1) == 7_000_000_000
    assert stamp_offset(Marker._full_text) == 4
    assert stamp_offset(String._full_text) == 0
    assert stamp_offset("float64[] values\n") == 0  # a list, but of numbers


def test_a_header_stamp_of_zero_takes_the_arrival_time():
    m = BagMessages()
    _, _, msgdef, data = m.serialize(
        "geometry_msgs/msg/PointStamped",
        header=m.header(0),
        point=m.store.types["geometry_msgs/msg/Point"](x=0.0, y=0.0, z=0.0),
    )
    assert record_time_ns(msgdef, data, 123) == 123
    # On simulation time 0 is its start: the first joint state's /power goes in at 0, not at
    # its arrival (0 or 0.5 s: the load decided, and two equal runs differed).
    assert record_time_ns(msgdef, data, 123, zero_is_a_time=True) == 0
    _, _, string_def, text = m.serialize("std_msgs/msg/String", data="no stamp")
    assert record_time_ns(string_def, text, 123, zero_is_a_time=True) == 123
    with pytest.raises(RecorderError, match="a message of 3 bytes cannot start with a Header"):
        record_time_ns(msgdef, b"abc", 1)


def test_a_late_latched_message_is_read_after_the_repeated_one(tmp_path):
    import rosbag

    m = BagMessages()
    writer = SplitBagWriter(tmp_path, split_duration_s=1.0, start=START)
    ros1_type, md5, msgdef, old = m.serialize("std_msgs/msg/String", data="old terrain")
    writer.write("/sim/terrain", ros1_type, md5, msgdef, 10**9, old, True, "/sim")
    value = m.serialize("std_msgs/msg/Float64", data=1.0)
    writer.write("/x", *value[:3], 3 * 10**9, value[3])  # opens file 1: "old terrain" repeated
    new = m.serialize("std_msgs/msg/String", data="new terrain")[3]
    writer.write("/sim/terrain", ros1_type, md5, msgdef, 2 * 10**9, new, True, "/sim")  # late
    bags = writer.close()
    with rosbag.Bag(str(bags[-1])) as bag:
        terrains = [(msg.data, t.to_nsec()) for _, msg, t in bag.read_messages("/sim/terrain")]
    assert terrains == [("old terrain", 3 * 10**9), ("new terrain", 3 * 10**9)]
