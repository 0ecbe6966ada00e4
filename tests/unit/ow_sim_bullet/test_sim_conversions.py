"""tf transforms built from URDF joints agree with pinocchio; the wire serialisers with genpy;
the batch publisher writes what rospy would; trajectory requests from messages."""

from __future__ import annotations

import io
import struct
import threading
from types import SimpleNamespace

import genpy
import numpy as np
import pinocchio as pin
import pytest
from geometry_msgs.msg import PointStamped, WrenchStamped
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from tf2_msgs.msg import TFMessage

from ow_dem_bridge.api import Wrench
from ow_description.description import URDF_PATH
from ow_msgs.msg import JointStatesFlag, ToolState
from ow_sim_bullet import wire
from ow_sim_bullet.conversions import (
    TrajectoryRequest,
    joint_frames,
    quaternion_from_matrix,
    quaternion_from_rpy,
    stamp,
    transform_msg,
)
from ow_sim_bullet.errors import CommandError
from ow_sim_bullet.tool_tracking import ToolSnapshot


def quaternion_matrix(q: tuple[float, float, float, float]) -> np.ndarray:
    return pin.Quaternion(q[3], q[0], q[1], q[2]).toRotationMatrix()


def test_joint_transforms_compose_to_pinocchio_link_poses():
    text = URDF_PATH.read_text()
    model = pin.buildModelFromUrdf(str(URDF_PATH))
    data = model.createData()
    rng = np.random.default_rng(3)
    q = rng.uniform(-1.0, 1.0, model.nq)
    pin.framesForwardKinematics(model, data, q)
    angle = {model.names[i]: q[model.joints[i].idx_q] for i in range(1, model.njoints)}
    poses = {"base_link": np.eye(4)}
    frames = joint_frames(text)
    assert {f.child for f in frames} >= {"l_scoop_tip", "l_grinder_tip", "lander_sample_dock0"}
    for _ in frames:  # resolve in tree order
        for frame in frames:
            if frame.parent in poses and frame.child not in poses:
                local = np.eye(4)
                local[:3, :3] = quaternion_matrix(frame.rotation_at(angle.get(frame.joint, 0.0)))
                local[:3, 3] = frame.translation
                poses[frame.child] = poses[frame.parent] @ local
    for link, pose in poses.items():
        expected = data.oMf[model.getFrameId(link)].homogeneous
        assert np.allclose(pose, expected, atol=1e-9), link


def test_quaternion_from_rpy_is_the_urdf_rotation_with_the_usual_sign():
    rng = np.random.default_rng(5)
    for roll, pitch, yaw in rng.uniform(-4.0, 4.0, (50, 3)):
        q = quaternion_from_rpy(roll, pitch, yaw)
        assert np.allclose(quaternion_matrix(q), pin.rpy.rpyToMatrix(roll, pitch, yaw))
        # The closed form of qz(yaw) qy(pitch) qx(roll): the sign tf has always been sent with.
        cr, sr = np.cos(roll / 2), np.sin(roll / 2)
        cp, sp = np.cos(pitch / 2), np.sin(pitch / 2)
        cy, sy = np.cos(yaw / 2), np.sin(yaw / 2)
        expected = (
            sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy,
            cr * cp * cy + sr * sp * sy,
        )
        assert np.allclose(q, expected, rtol=0.0, atol=1e-12)


def test_joint_rotations_are_the_origin_turned_about_the_axis():
    rng = np.random.default_rng(6)
    for frame in joint_frames(URDF_PATH.read_text()):
        if frame.axis is None:
            assert frame.rotation_at(1.0) == frame.rotation
            continue
        origin = quaternion_matrix(frame.rotation)
        for angle in rng.uniform(-7.0, 7.0, 10):
            turn = pin.AngleAxis(angle, np.array(frame.axis)).matrix()
            rotation = quaternion_matrix(frame.rotation_at(angle))
            assert np.allclose(rotation, origin @ turn, rtol=0.0, atol=1e-12), frame.joint


def test_quaternion_from_matrix_round_trips():
    rng = np.random.default_rng(0)
    for _ in range(20):
        rotation = pin.exp3(rng.normal(size=3) * 2.0)
        assert np.allclose(quaternion_matrix(quaternion_from_matrix(rotation)), rotation)


def test_stamp_is_exact_to_the_nanosecond():
    assert stamp(12.34).secs == 12 and stamp(12.34).nsecs == 340_000_000
    assert stamp(0.01 * 3).nsecs == 30_000_000


def genpy_bytes(msg: genpy.Message, seq: int | None = None) -> bytes:
    """genpy's serialisation, with the header sequence number rospy would set."""
    if seq is not None:
        msg.header.seq = seq
    buffer = io.BytesIO()
    msg.serialize(buffer)
    return buffer.getvalue()


#: s of sim time: ordinary, a whole second, and one that rounds up to the next nanosecond.
TIMES = [0.0, 12.34, 3.0, 1.0 - 1e-10, 123456.789]


@pytest.mark.parametrize("time_s", TIMES)
def test_joint_state_wire_is_genpys_serialisation(time_s):
    names = ["j_a", "j_long_name", "j_ü"]
    rng = np.random.default_rng(1)
    position, velocity, effort = rng.normal(size=(3, 3)) * 1e3
    msg = JointState()
    msg.header.stamp = stamp(time_s)
    msg.name = names
    msg.position, msg.velocity, msg.effort = position.tolist(), velocity.tolist(), effort.tolist()
    expected = genpy_bytes(msg, seq=42)
    assert wire.JointStateWire(names)(42, time_s, position, velocity, effort) == expected
    decoded = JointState().deserialize(expected)
    assert decoded.name == names and decoded.position == tuple(position)


def test_joint_state_wire_refuses_arrays_of_the_wrong_length():
    with pytest.raises(ValueError, match="expected 3 joint values, got 2"):
        wire.JointStateWire(["a", "b", "c"])(1, 0.0, np.zeros(2), np.zeros(3), np.zeros(3))


@pytest.mark.parametrize("time_s", TIMES)
def test_tf_wire_is_genpys_serialisation_of_the_joint_transforms(time_s):
    frames = [f for f in joint_frames(URDF_PATH.read_text()) if f.axis is not None]
    joint_index = list(range(len(frames)))[::-1]
    positions = np.random.default_rng(2).uniform(-3.0, 3.0, len(frames))
    msg = TFMessage(
        [transform_msg(f, positions[k], time_s) for f, k in zip(frames, joint_index, strict=True)]
    )
    assert wire.TfWire(frames, joint_index)(5, time_s, positions) == genpy_bytes(msg)


@pytest.mark.parametrize("time_s", TIMES)
def test_stamped_and_clock_wires_are_genpys_serialisation(time_s):
    force, torque = np.array([1.5, -2.25, 1e-300]), np.array([-0.0, 3.0, 7e10])
    wrench = WrenchStamped()
    wrench.header.stamp, wrench.header.frame_id = stamp(time_s), "l_scoop"
    f, t = wrench.wrench.force, wrench.wrench.torque
    f.x, f.y, f.z = force.tolist()
    t.x, t.y, t.z = torque.tolist()
    assert wire.StampedWire("l_scoop").wrench(3, time_s, force, torque) == genpy_bytes(wrench, 3)
    point = PointStamped()
    point.header.stamp, point.header.frame_id = stamp(time_s), "base_link"
    point.point.x, point.point.y, point.point.z = 1.7, -0.05, -0.155
    serialised = wire.StampedWire("base_link").point(9, time_s, 1.7, -0.05, -0.155)
    assert serialised == genpy_bytes(point, 9)
    assert wire.clock(1, time_s) == genpy_bytes(Clock(clock=stamp(time_s)))


@pytest.mark.parametrize("time_s", TIMES)
def test_joint_flags_wire_is_genpys_serialisation_whatever_the_flags(time_s):
    serialise = wire.JointFlagsWire()
    names = ("j_dist_pitch", "j_hand_yaw", "j_ü")
    for flags in [(False, False, False), (True, False, True), (False, False, False)]:
        msg = JointStatesFlag(name=list(names), flags=list(flags))
        msg.header.stamp, msg.header.frame_id = stamp(time_s), "base_link"
        payload = serialise(11, time_s, names, flags)
        assert payload == genpy_bytes(msg, 11)
        assert JointStatesFlag().deserialize(payload).flags == list(flags)
    with pytest.raises(ValueError, match="3 joint names but 2 flags"):
        serialise(1, 0.0, names, (True, False))


def tool_snapshot(time_s: float, model: bool) -> ToolSnapshot:
    rng = np.random.default_rng(3)
    pose = np.eye(4)
    pose[:3, :3] = pin.rpy.rpyToMatrix(*rng.uniform(-3.0, 3.0, 3))
    pose[:3, 3] = rng.normal(size=3)
    return ToolSnapshot(
        tool="scoop",
        link="l_scoop",
        time=time_s,
        X_base_link=pose,
        linear_velocity=rng.normal(size=3),
        angular_velocity=rng.normal(size=3),
        tip=rng.normal(size=3),
        terrain_z=-0.155,
        depth=0.0123,
        progress=0.456,
        material=7,
        force=rng.normal(size=3),
        torque=rng.normal(size=3),
        model_wrench=Wrench(rng.normal(size=3), rng.normal(size=3)) if model else None,
        model_depth=0.0101 if model else 0.0,
    )


@pytest.mark.parametrize("time_s", TIMES)
@pytest.mark.parametrize("model", [False, True])
def test_tool_wires_are_genpys_serialisation_of_the_snapshot(time_s, model):
    snapshot = tool_snapshot(time_s, model)
    state = ToolState()
    state.header.stamp, state.header.frame_id = stamp(time_s), "base_link"
    state.tool, state.link = "scoop", "l_scoop"
    p, o = state.pose.position, state.pose.orientation
    p.x, p.y, p.z = snapshot.X_base_link[:3, 3].tolist()
    q = pin.Quaternion(snapshot.X_base_link[:3, :3])
    o.x, o.y, o.z, o.w = q.x, q.y, q.z, q.w
    lin, ang = state.twist.linear, state.twist.angular
    lin.x, lin.y, lin.z = snapshot.linear_velocity.tolist()
    ang.x, ang.y, ang.z = snapshot.angular_velocity.tolist()
    state.depth, state.progress, state.material = 0.0123, 0.456, 7
    tool = wire.ToolWire("scoop", "l_scoop")
    assert tool.state(4, snapshot) == genpy_bytes(state, 4)
    state.depth = snapshot.model_depth
    assert tool.model_state(5, snapshot) == genpy_bytes(state, 5)
    wrench = WrenchStamped()
    wrench.header.stamp, wrench.header.frame_id = stamp(time_s), "l_scoop"
    if model:
        f, t = wrench.wrench.force, wrench.wrench.torque
        f.x, f.y, f.z = snapshot.model_wrench.force.tolist()
        t.x, t.y, t.z = snapshot.model_wrench.torque.tolist()
    assert tool.model_wrench(6, snapshot) == genpy_bytes(wrench, 6)


class FakeConnection:
    def __init__(self, fail: bool = False) -> None:
        self.fail, self.data, self.closed = fail, [], False

    def write_data(self, data: bytes) -> None:
        if self.fail:
            raise OSError("connection reset")
        self.data.append(data)

    def close(self) -> None:
        self.closed = True


class FakeImpl:
    """The parts of rospy 1.15's ``_PublisherImpl`` a BatchPublisher uses."""

    def __init__(self, connections: list[FakeConnection]) -> None:
        self.connections = connections
        self.publock = threading.RLock()
        self.seq = 0
        self.closed = False
        self.resolved_name = "/topic"
        self.message_data_sent = 0


def batch(connections: list[FakeConnection], shutdown: bool = False):
    impl = FakeImpl(connections)
    logged: list[str] = []
    publisher = wire.BatchPublisher(SimpleNamespace(impl=impl), lambda: shutdown, logged.append)
    return publisher, impl, logged


def test_batch_publisher_writes_queued_messages_length_prefixed_in_one_write():
    good, bad = FakeConnection(), FakeConnection(fail=True)
    publisher, impl, logged = batch([good, bad])
    publisher.publish(wire.clock, 1.0)
    publisher.publish(wire.clock, 2.0)
    assert impl.seq == 2 and good.data == []  # queued, not written
    publisher.flush()
    first, second = wire.clock(1, 1.0), wire.clock(2, 2.0)
    expected = struct.pack("<I", len(first)) + first + struct.pack("<I", len(second)) + second
    assert good.data == [expected]
    assert impl.message_data_sent == len(expected)
    # The failing subscriber is dropped as rospy drops it; the others still get the data.
    assert bad.closed and "dropping a subscriber of /topic: connection reset" in logged[0]
    publisher.flush()
    assert good.data == [expected]  # nothing new


def test_batch_publisher_builds_nothing_without_subscribers_or_while_shutting_down():
    publisher, impl, _ = batch([])
    publisher.publish(lambda seq: pytest.fail("built without subscribers"))
    assert impl.seq == 0
    connection = FakeConnection()
    publisher, impl, _ = batch([connection], shutdown=True)
    publisher.publish(wire.clock, 1.0)
    publisher.flush()
    assert connection.data == [] and impl.message_data_sent == 0


def frame(seq: int, time_s: float) -> bytes:
    payload = wire.clock(seq, time_s)
    return struct.pack("<I", len(payload)) + payload


def test_a_flush_for_some_nodes_leaves_the_others_their_messages_for_the_next_flush():
    arm, recorder, monitors = (FakeConnection() for _ in range(3))
    arm.endpoint_id, recorder.endpoint_id, monitors.endpoint_id = "/arm", "/record", "/monitors"
    publisher, impl, _ = batch([arm, recorder, monitors])
    publisher.publish(wire.clock, 1.0)
    publisher.flush(only={"/arm"})
    assert arm.data == [frame(1, 1.0)] and recorder.data == monitors.data == []
    publisher.publish(wire.clock, 2.0)
    publisher.flush(only={"/arm", "/record"})
    # The recorder gets what it missed first, in one write: the stream is the same for all.
    assert arm.data == [frame(1, 1.0), frame(2, 2.0)]
    assert recorder.data == [frame(1, 1.0) + frame(2, 2.0)] and monitors.data == []
    impl.connections.remove(recorder)  # closed meanwhile: what it was owed is forgotten
    publisher.flush()
    assert monitors.data == [frame(1, 1.0) + frame(2, 2.0)]
    assert arm.data == [frame(1, 1.0), frame(2, 2.0)]  # nothing new for it
    assert publisher._behind == {}
    assert impl.message_data_sent == len(frame(1, 1.0) + frame(2, 2.0))  # each message once


def point(time_s: float, positions, velocities=()):
    return SimpleNamespace(
        time_from_start=genpy.Duration.from_sec(time_s),
        positions=positions,
        velocities=velocities,
    )


def trajectory_msg(points, stamp_s: float = 0.0):
    return SimpleNamespace(
        joint_names=["j_a", "j_b"],
        header=SimpleNamespace(stamp=genpy.Time.from_sec(stamp_s)),
        points=points,
    )


def test_a_trajectory_request_starts_at_its_stamp_or_on_arrival():
    msg = trajectory_msg([point(1.0, [0.1, 0.2], [0.0, 0.0]), point(2.0, [0.3, 0.4], [0.0, 0.0])])
    request = TrajectoryRequest.from_msg(msg)
    on_arrival = request.build(12.5, ["j_a", "j_b", "j_c"])
    assert on_arrival.start_time == 12.5
    assert on_arrival.velocities is not None
    assert np.allclose(on_arrival.positions, [[0.1, 0.2], [0.3, 0.4]])
    stamped = TrajectoryRequest.from_msg(trajectory_msg(msg.points, stamp_s=20.0))
    assert stamped.build(12.5, ["j_a", "j_b"]).start_time == 20.0
    linear = TrajectoryRequest.from_msg(trajectory_msg([point(1.0, [0.1, 0.2])]))
    assert linear.velocities is None


def test_a_trajectory_request_with_velocities_on_some_points_only_is_refused():
    msg = trajectory_msg([point(1.0, [0.1, 0.2], [0.0, 0.0]), point(2.0, [0.3, 0.4])])
    with pytest.raises(CommandError, match="give velocities on every point or on none"):
        TrajectoryRequest.from_msg(msg)
    request = TrajectoryRequest.from_msg(trajectory_msg([point(1.0, [0.1, 0.2])]))
    with pytest.raises(CommandError, match="unknown joint"):
        request.build(0.0, ["j_a"])


def test_a_dem_dig_message_carries_its_sample_or_its_error():
    from ow_sim_bullet.conversions import dem_dig_msg

    summary = {
        "start_time": 112.7,
        "exchanges": 1856,
        "particles": 738,
        "loose_particles": 266,
        "sample": {"sample_particles": 21.0, "sample_volume_m3": 3.2e-4, "sample_mass_kg": 0.5},
        "error": None,
    }
    msg = dem_dig_msg(131.25, "scoop", summary)
    assert (msg.header.stamp.secs, msg.header.stamp.nsecs) == (131, 250_000_000)
    assert (msg.tool, msg.start_time, msg.exchanges, msg.particles) == ("scoop", 112.7, 1856, 738)
    assert (msg.sample_particles, msg.sample_volume, msg.sample_mass) == (21, 3.2e-4, 0.5)
    assert msg.error == ""
    failed = dem_dig_msg(5.0, "scoop", {**summary, "sample": None, "error": "killed"})
    assert (failed.sample_particles, failed.sample_volume, failed.error) == (0, 0.0, "killed")
