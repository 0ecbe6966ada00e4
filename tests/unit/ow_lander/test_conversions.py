"""Messages of the arm services built from the pure types (no master)."""

import io
import json

import genpy
import numpy as np
import pytest
from geometry_msgs.msg import TransformStamped
from tf2_msgs.msg import TFMessage

from ow_description.trajectory import PathSegment, time_parameterize
from ow_lander.conversions import (
    guarded_move_result_msg,
    operation_msg,
    tf_message_stamps,
    trajectory_msg,
)
from ow_lander.execution.monitor import ExecutionResult
from ow_msgs.msg import Operation
from ow_msgs.srv import PublishTrajectoryResponse, UnstowResponse


def test_trajectory_msg_carries_every_row_from_its_start_time():
    trajectory = time_parameterize(
        [PathSegment("s", np.array([[0.0, 0.0], [0.3, -0.2]]))],
        ("a", "b"),
        np.ones(2),
        np.ones(2),
        0.1,
    )
    msg = trajectory_msg(trajectory, 12.25)
    assert msg.header.stamp == genpy.Time(12, 250_000_000)
    assert msg.joint_names == ["a", "b"]
    assert len(msg.points) == len(trajectory.times)
    for point, t, q, v in zip(
        msg.points, trajectory.times, trajectory.positions, trajectory.velocities, strict=True
    ):
        assert point.time_from_start == genpy.Duration.from_sec(float(t))
        assert point.positions == q.tolist() and point.velocities == v.tolist()


def test_operation_markers_carry_the_parameters_and_the_end_result():
    start = operation_msg(genpy.Time(5), 3, "unstow", Operation.START, {"x": np.float32(0.1)})
    assert (start.id, start.name, start.event, start.header.frame_id) == (
        3,
        "unstow",
        0,
        "base_link",
    )
    assert json.loads(start.parameters) == {"x": 0.1}
    assert not start.success and start.message == "" and start.trajectory_file == ""
    response = UnstowResponse(success=True, message="planned", trajectory_file="/t/u.csv")
    end = operation_msg(genpy.Time(6), 3, "unstow", Operation.END, {}, response)
    assert (end.success, end.message, end.trajectory_file) == (True, "planned", "/t/u.csv")
    executed = PublishTrajectoryResponse(success=False, message="tracking error")
    end = operation_msg(genpy.Time(7), 4, "publish_trajectory", Operation.END, {}, executed)
    assert (end.success, end.message, end.trajectory_file) == (False, "tracking error", "")


def test_guarded_move_result_msg():
    found = ExecutionResult(
        True, "ground found", ground_found=True, ground_position=np.array([1.7, 0.0, -0.15])
    )
    msg = guarded_move_result_msg(found, genpy.Time(9))
    assert msg.success and msg.frame == "base_link" and msg.header.stamp == genpy.Time(9)
    assert (msg.position.x, msg.position.y, msg.position.z) == (1.7, 0.0, -0.15)
    missed = guarded_move_result_msg(ExecutionResult(False, "no ground"), genpy.Time(9))
    assert not missed.success and (missed.position.x, missed.position.z) == (0.0, 0.0)


def _tf_bytes(stamps: list[tuple[int, int]], frames: list[str]) -> bytes:
    msg = TFMessage()
    for i, ((secs, nsecs), frame) in enumerate(zip(stamps, frames, strict=True)):
        transform = TransformStamped()
        transform.header.seq = 7 + i
        transform.header.stamp = genpy.Time(secs, nsecs)
        transform.header.frame_id = frame
        transform.child_frame_id = f"{frame}_child_{'x' * i}"
        transform.transform.translation.x = 0.1 * i
        transform.transform.rotation.w = 1.0
        msg.transforms.append(transform)
    buffer = io.BytesIO()
    msg.serialize(buffer)
    return buffer.getvalue()


@pytest.mark.parametrize(
    ("stamps", "frames"),
    [
        ([], []),
        ([(12, 340_000_000)], ["base_link"]),
        ([(40, 170_000_001)] * 12, [f"l_link{i}" for i in range(12)]),
        ([(3, 999_999_999), (1, 0), (4_000_000_000, 5)], ["a", "", "über_link"]),
    ],
)
def test_tf_stamps_are_read_as_genpy_deserialises_them(stamps, frames):
    data = _tf_bytes(stamps, frames)
    expected = [t.header.stamp.to_sec() for t in TFMessage().deserialize(data).transforms]
    assert tf_message_stamps(data) == expected
    assert tf_message_stamps(memoryview(data)) == expected


def test_tf_stamps_of_a_truncated_or_longer_message_raise():
    data = _tf_bytes([(1, 2), (3, 4)], ["a", "b"])
    with pytest.raises(ValueError, match="not a tf2_msgs/TFMessage"):
        tf_message_stamps(data[:-1])
    with pytest.raises(ValueError, match="end at byte"):
        tf_message_stamps(data + b"\0")
