"""The fast decoders of the run's joint states and power give what rosbags' deserialiser gives."""

from __future__ import annotations

import io
import struct

import genpy
import numpy as np
import pytest
from geometry_msgs.msg import WrenchStamped
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from sensor_msgs.msg import JointState

from ow_msgs.msg import Power
from ow_power.bagdecode import fast_decoder


def serialised(msg: genpy.Message) -> bytes:
    buffer = io.BytesIO()
    msg.serialize(buffer)
    return buffer.getvalue()


def store_of(*classes: type) -> tuple[object, list[str]]:
    store = get_typestore(Stores.EMPTY)
    names = []
    for cls in classes:
        package, name = cls._type.split("/")
        names.append(f"{package}/msg/{name}")
        store.register(get_types_from_msg(cls._full_text, names[-1]))
    return store, names


def assert_same(decoded: object, expected: object) -> None:
    """Field by field, nested dataclasses included; arrays by value and dtype."""
    assert type(decoded) is type(expected)
    for field in expected.__dataclass_fields__:
        a, b = getattr(decoded, field), getattr(expected, field)
        if isinstance(b, np.ndarray):
            assert isinstance(a, np.ndarray) and a.dtype == b.dtype
            assert np.array_equal(a, b)
        elif hasattr(b, "__dataclass_fields__"):
            assert_same(a, b)
        else:
            assert a == b and type(a) is type(b), field


def joint_state(k: int, names: list[str]) -> JointState:
    msg = JointState()
    msg.header.seq, msg.header.frame_id = k, "base_ü" if k % 2 else ""
    msg.header.stamp = genpy.Time(12 + k, 340_000_000 + k)
    rng = np.random.default_rng(k)
    msg.name = names
    msg.position, msg.velocity = rng.normal(size=(2, len(names))).tolist()
    msg.effort = [] if k == 2 else rng.normal(size=len(names)).tolist()
    return msg


def test_joint_states_decode_as_rosbags_deserialises_them_whatever_the_names():
    store, (msgtype,) = store_of(JointState)
    decode = fast_decoder(store, msgtype)
    assert decode is not None
    for k, names in enumerate([["j_a", "j_b"], ["j_a", "j_b"], ["j_ü", "j_long_name", "x"], []]):
        data = serialised(joint_state(k, names))
        decoded = decode(data)
        assert_same(decoded, store.deserialize_ros1(data, msgtype))
        decoded.name.append("changed")  # each message has its own list
        assert decode(data).name == names


def test_power_decodes_as_rosbags_deserialises_it():
    store, (msgtype,) = store_of(Power)
    decode = fast_decoder(store, msgtype)
    msg = Power(name=["j_a", "j_b"], joint_power=[1.5, -2.0], mechanical_power=-0.5)
    msg.header.stamp = genpy.Time(3, 7)
    msg.auxiliary_power, msg.total_power, msg.electrical_energy = 43.0, 42.5, 1e-300
    data = serialised(msg)
    assert_same(decode(data), store.deserialize_ros1(data, msgtype))
    assert decode(data).electrical_energy == 1e-300


def test_other_types_are_left_to_rosbags_and_truncated_bytes_raise():
    store, (wrench, joints) = store_of(WrenchStamped, JointState)
    assert fast_decoder(store, wrench) is None  # nested Wrench
    decode = fast_decoder(store, joints)
    data = serialised(joint_state(1, ["j_a", "j_b"]))
    for cut in (5, len(data) - 20):  # in the efforts; in the names
        with pytest.raises((ValueError, struct.error)):  # what bagread reports as unreadable
            decode(data[:-cut])
