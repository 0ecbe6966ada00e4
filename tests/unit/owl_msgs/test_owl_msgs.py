"""owl_msgs against the definitions of NASA OceanWATERS' owl_msgs (nasa/ow_simulator, owl_msgs/).

An autonomy client written for OceanWATERS must work unchanged against this package, so every
action and message here has exactly OceanWATERS' field names, field types, field order and
constants. The tables below are written from the published definitions (see docs/owl_msgs.md
for the files and commits); the MD5 sums were computed with genmsg from those published files,
so equal sums mean OceanWATERS nodes and ours accept each other's topics and action goals.

Not found in the published index, taken from the reference spec's field lists instead (their
sums come from our own files): ArmStow, ArmUnstow, TaskDeliverSample, TaskGrind,
ArmJointPositions, ArmJointAccelerations, ArmJointTorques.
"""

from __future__ import annotations

import io
from types import ModuleType

import pytest

Fields = tuple[tuple[str, str], ...]

HEADER = ("header", "std_msgs/Header")
POSE = "geometry_msgs/Pose"
POINT = "geometry_msgs/Point"
EMPTY: Fields = ()

#: action -> (goal, result, feedback), each ((field, type), ...) in declaration order.
ACTIONS: dict[str, tuple[Fields, Fields, Fields]] = {
    "ArmUnstow": (EMPTY, EMPTY, EMPTY),
    "ArmStow": (EMPTY, EMPTY, EMPTY),
    "ArmStop": (EMPTY, EMPTY, EMPTY),
    "ArmMoveJoint": (
        (("relative", "bool"), ("joint", "int32"), ("angle", "float64")),
        (("final_angles", "float64[]"),),
        (("angles", "float64[]"),),
    ),
    "ArmMoveJoints": (
        (("relative", "bool"), ("angles", "float64[]")),
        (("final_angles", "float64[]"),),
        (("angles", "float64[]"),),
    ),
    "ArmMoveJointsGuarded": (
        (
            ("relative", "bool"),
            ("angles", "float64[]"),
            ("force_threshold", "float64"),
            ("torque_threshold", "float64"),
        ),
        (("final_angles", "float64[]"), ("final_force", "float64"), ("final_torque", "float64")),
        (("angles", "float64[]"), ("force", "float64"), ("torque", "float64")),
    ),
    "ArmMoveCartesian": (
        (("frame", "int32"), ("relative", "bool"), ("pose", POSE)),
        (("final_pose", POSE),),
        (("pose", POSE),),
    ),
    "ArmMoveCartesianGuarded": (
        (
            ("frame", "int32"),
            ("relative", "bool"),
            ("pose", POSE),
            ("force_threshold", "float64"),
            ("torque_threshold", "float64"),
        ),
        (("final_pose", POSE), ("final_force", "float64"), ("final_torque", "float64")),
        (("pose", POSE), ("force", "float64"), ("torque", "float64")),
    ),
    "ArmFindSurface": (
        (
            ("frame", "int32"),
            ("relative", "bool"),
            ("position", POINT),
            ("normal", "geometry_msgs/Vector3"),
            ("distance", "float64"),
            ("overdrive", "float64"),
            ("force_threshold", "float64"),
            ("torque_threshold", "float64"),
        ),
        (
            ("final_pose", POSE),
            ("final_distance", "float64"),
            ("final_force", "float64"),
            ("final_torque", "float64"),
        ),
        (("pose", POSE), ("distance", "float64"), ("force", "float64"), ("torque", "float64")),
    ),
    "TaskGrind": (
        (
            ("x_start", "float32"),
            ("y_start", "float32"),
            ("depth", "float32"),
            ("length", "float32"),
            ("parallel", "float32"),
            ("ground_position", "float32"),
        ),
        (("final", POINT),),
        (("current", POINT),),
    ),
    "TaskScoopCircular": (
        (
            ("frame", "int32"),
            ("relative", "bool"),
            ("point", POINT),
            ("depth", "float64"),
            ("parallel", "bool"),
        ),
        EMPTY,
        EMPTY,
    ),
    "TaskScoopLinear": (
        (
            ("frame", "int32"),
            ("relative", "bool"),
            ("point", POINT),
            ("depth", "float64"),
            ("length", "float64"),
        ),
        EMPTY,
        EMPTY,
    ),
    "TaskDeliverSample": (EMPTY, EMPTY, EMPTY),
    "TaskDiscardSample": (
        (("frame", "int32"), ("relative", "bool"), ("point", POINT), ("height", "float64")),
        EMPTY,
        EMPTY,
    ),
    "PanTiltMoveJoints": (
        (("pan", "float64"), ("tilt", "float64")),
        (("pan_position", "float64"), ("tilt_position", "float64")),
        (("pan_position", "float64"), ("tilt_position", "float64")),
    ),
    "PanTiltMoveCartesian": ((("frame", "int32"), ("point", POINT)), EMPTY, EMPTY),
    "FaultClear": ((("fault", "uint64"),), EMPTY, EMPTY),
    "CameraCapture": (EMPTY, EMPTY, EMPTY),
    "CameraSetExposure": ((("automatic", "bool"), ("exposure", "float64")), EMPTY, EMPTY),
    "LightSetIntensity": ((("name", "string"), ("intensity", "float64")), EMPTY, EMPTY),
}

#: message -> ((field, type), ...) in declaration order.
MESSAGES: dict[str, Fields] = {
    "ArmJointPositions": (HEADER, ("value", "float64[7]")),
    "ArmJointVelocities": (HEADER, ("value", "float64[7]")),
    "ArmJointAccelerations": (HEADER, ("value", "float64[7]")),
    "ArmJointTorques": (HEADER, ("value", "float64[7]")),
    "ArmPose": (HEADER, ("value", POSE)),
    "ArmEndEffectorForceTorque": (HEADER, ("value", "geometry_msgs/Wrench")),
    "PanTiltPosition": (HEADER, ("value", "float64[2]")),
    "BatteryStateOfCharge": (HEADER, ("value", "float64")),
    "BatteryRemainingUsefulLife": (HEADER, ("value", "int32")),
    "BatteryTemperature": (HEADER, ("value", "float64")),
    "ArmFaultsStatus": (HEADER, ("value", "uint64")),
    "PanTiltFaultsStatus": (HEADER, ("value", "uint64")),
    "CameraFaultsStatus": (HEADER, ("value", "uint64")),
    "PowerFaultsStatus": (HEADER, ("value", "uint64")),
    "SystemFaultsStatus": (HEADER, ("value", "uint64")),
}

#: message -> its constants (all uint64 bit flags); messages not listed have none.
CONSTANTS: dict[str, dict[str, int]] = {
    "ArmFaultsStatus": {
        "NONE": 0,
        "HARDWARE": 1,
        "TRAJECTORY_GENERATION": 2,
        "COLLISION": 4,
        "E_STOP": 8,
        "POSITION_LIMIT": 16,
        "JOINT_TORQUE_LIMIT": 32,
        "VELOCITY_LIMIT": 64,
        "NO_FORCE_DATA": 128,
        "FORCE_TORQUE_LIMIT": 256,
    },
    "PanTiltFaultsStatus": {"NONE": 0, "PAN_JOINT_LOCKED": 1, "TILT_JOINT_LOCKED": 2},
    "CameraFaultsStatus": {"NONE": 0, "NO_IMAGE": 1},
    "PowerFaultsStatus": {
        "NONE": 0,
        "LOW_STATE_OF_CHARGE": 1,
        "INSTANTANEOUS_CAPACITY_LOSS": 2,
        "THERMAL_FAULT": 4,
    },
    "SystemFaultsStatus": {
        "NONE": 0,
        "SYSTEM": 1,
        "ARM_GOAL_ERROR": 2,
        "ARM_EXECUTION_ERROR": 4,
        "TASK_GOAL_ERROR": 8,
        "CAMERA_GOAL_ERROR": 16,
        "CAMERA_EXECUTION_ERROR": 32,
        "PAN_TILT_GOAL_ERROR": 64,
        "PAN_TILT_EXECUTION_ERROR": 128,
        "POWER_EXECUTION_ERROR": 256,
    },
}

# The MD5 sums of the types on the wire: each action's goal, result and feedback topics, and
# the telemetry messages. An action with no fields has the same result and feedback sums as
# every other action with no result or feedback fields.
_EMPTY_RESULT = "1eb06eeff08fa7ea874431638cb52332"
_EMPTY_FEEDBACK = "aae20e09065c3809e8a8e87c4c8953fd"
_EMPTY_GOAL = "4b30be6cd12b9e72826df56b481f40e0"
WIRE_MD5: dict[str, tuple[str, str, str]] = {
    "ArmUnstow": (_EMPTY_GOAL, _EMPTY_RESULT, _EMPTY_FEEDBACK),
    "ArmStow": (_EMPTY_GOAL, _EMPTY_RESULT, _EMPTY_FEEDBACK),
    "ArmStop": (_EMPTY_GOAL, _EMPTY_RESULT, _EMPTY_FEEDBACK),
    "ArmMoveJoint": (
        "f94adc5391c976377cb08e9c2ea05aec",
        "5f730a7cd6bae45e2a94e90d3e08111f",
        "ab1fa26ac587cf686bebb498beadba74",
    ),
    "ArmMoveJoints": (
        "b94830454c9adce7d4f4ed06eb7fe80b",
        "5f730a7cd6bae45e2a94e90d3e08111f",
        "ab1fa26ac587cf686bebb498beadba74",
    ),
    "ArmMoveJointsGuarded": (
        "0c39112b2618cd8f58b0e695b95e6c12",
        "ffd2ba4720ce2b79c1e76607b409a1c5",
        "3491974b4f51d39103f131ccd73dd10e",
    ),
    "ArmMoveCartesian": (
        "b338fed8489ff806bbecd77315862c61",
        "83fa661dabef8c3bfb64ac4fbb2b2c2a",
        "af4562daaf23d4b08b0902b9a1e5001e",
    ),
    "ArmMoveCartesianGuarded": (
        "547ed68be67406640c1def0add5c8bb0",
        "2814e72dfff3bb4668d9b19e8610412a",
        "1fd472f6b28e7f934bc50ad3c053f511",
    ),
    "ArmFindSurface": (
        "392a33d9828ce0c13e04def1eebb06a7",
        "de01aaebb5c538266927f574d1d931da",
        "820e5de6f3251cb22a283afc4fd8b1fd",
    ),
    "TaskGrind": (
        "9edde001a7ced72786e1e692fa95a5e6",
        "a52ccb15072a310adabf033343ba9baa",
        "ba0bf3201c773e6e33fab68aada5d35a",
    ),
    "TaskScoopCircular": ("ef7af1f7129acb2c78effc90372a4067", _EMPTY_RESULT, _EMPTY_FEEDBACK),
    "TaskScoopLinear": ("67689861437557285e6d0a5a2e8678c4", _EMPTY_RESULT, _EMPTY_FEEDBACK),
    "TaskDeliverSample": (_EMPTY_GOAL, _EMPTY_RESULT, _EMPTY_FEEDBACK),
    "TaskDiscardSample": ("1457fbe47f06153b530ddcfa99c988b8", _EMPTY_RESULT, _EMPTY_FEEDBACK),
    "PanTiltMoveJoints": (
        "b0c2c0cddc886952650bacf93f720d5d",
        "160bd5cf2293933b4d2fb032926aedef",
        "7549898e111f07ab1a283d9fd617b228",
    ),
    "PanTiltMoveCartesian": ("2fd01ec2decf159171827ba29f802008", _EMPTY_RESULT, _EMPTY_FEEDBACK),
    "FaultClear": ("109fab129fe640c7947c1ed2ecbf22f3", _EMPTY_RESULT, _EMPTY_FEEDBACK),
    "CameraCapture": (_EMPTY_GOAL, _EMPTY_RESULT, _EMPTY_FEEDBACK),
    "CameraSetExposure": ("8219b8dba1ac96e690ed90b8a43d908f", _EMPTY_RESULT, _EMPTY_FEEDBACK),
    "LightSetIntensity": ("15aefa82a5ecf7d518524c88bdc71c6b", _EMPTY_RESULT, _EMPTY_FEEDBACK),
}
MESSAGE_MD5: dict[str, str] = {
    "ArmEndEffectorForceTorque": "510f42d5ac29bf7d38072cffdf7443c3",
    "ArmFaultsStatus": "1128ca7b8240435901002333059f2415",
    "ArmJointAccelerations": "9d5d1a73bc647e96c8129619b37200c2",
    "ArmJointPositions": "9d5d1a73bc647e96c8129619b37200c2",
    "ArmJointTorques": "9d5d1a73bc647e96c8129619b37200c2",
    "ArmJointVelocities": "9d5d1a73bc647e96c8129619b37200c2",
    "ArmPose": "bd9ff3eb88f58064fe349f6945c62407",
    "BatteryRemainingUsefulLife": "f231299e824089b22a987717bd7ace62",
    "BatteryStateOfCharge": "d053817de0764f9ee90dbc89c4cdd751",
    "BatteryTemperature": "d053817de0764f9ee90dbc89c4cdd751",
    "CameraFaultsStatus": "618581fe0c7b0ba7c689c8f0c5c31cc0",
    "PanTiltFaultsStatus": "a3910de717754d13e1be7f5a01be7ab4",
    "PanTiltPosition": "c93656ce3f9549a063777501c41c6d2d",
    "PowerFaultsStatus": "ce4f063c86b8facfc56bd4d076bcc47c",
    "SystemFaultsStatus": "dbcd2f28b03983a03eeefcde51cebe04",
}

_ACTION_PARTS = ("Goal", "Result", "Feedback")


@pytest.fixture(scope="module")
def owl() -> ModuleType:
    """The generated ``owl_msgs.msg`` module; a missing build is a failure, not a skip."""
    try:
        import owl_msgs.msg
    except ImportError as err:
        pytest.fail(f"owl_msgs is not built or not on the path ({err}): run make setup, env.sh")
    return owl_msgs.msg


def _fields(cls: type) -> Fields:
    return tuple(zip(cls.__slots__, cls._slot_types, strict=True))


def _constants(cls: type) -> dict[str, int]:
    return {name: getattr(cls, name) for name in dir(cls) if name.isupper()}


def test_the_tables_cover_the_same_types():
    assert set(WIRE_MD5) == set(ACTIONS)
    assert set(MESSAGE_MD5) == set(MESSAGES)
    assert set(CONSTANTS) <= set(MESSAGES)


def test_the_package_defines_exactly_the_tabled_types(owl):
    suffixes = ("Action", "ActionGoal", "ActionResult", "ActionFeedback", *_ACTION_PARTS)
    expected = {f"{a}{s}" for a in ACTIONS for s in suffixes} | set(MESSAGES)
    defined = {name for name, value in vars(owl).items() if isinstance(value, type)}
    assert defined == expected, (
        f"missing: {sorted(expected - defined)}, not in the table: {sorted(defined - expected)}"
    )


@pytest.mark.parametrize("action", sorted(ACTIONS))
def test_action_goal_result_and_feedback_fields(owl, action):
    for part, expected in zip(_ACTION_PARTS, ACTIONS[action], strict=True):
        cls = getattr(owl, f"{action}{part}")
        assert cls._type == f"owl_msgs/{action}{part}"
        assert _fields(cls) == expected, f"{action}{part}"


@pytest.mark.parametrize("action", sorted(ACTIONS))
def test_action_wrappers_are_actionlib_shaped(owl, action):
    assert _fields(getattr(owl, f"{action}Action")) == (
        ("action_goal", f"owl_msgs/{action}ActionGoal"),
        ("action_result", f"owl_msgs/{action}ActionResult"),
        ("action_feedback", f"owl_msgs/{action}ActionFeedback"),
    )
    assert _fields(getattr(owl, f"{action}ActionGoal")) == (
        HEADER,
        ("goal_id", "actionlib_msgs/GoalID"),
        ("goal", f"owl_msgs/{action}Goal"),
    )
    for part in ("Result", "Feedback"):
        assert _fields(getattr(owl, f"{action}Action{part}")) == (
            HEADER,
            ("status", "actionlib_msgs/GoalStatus"),
            (part.lower(), f"owl_msgs/{action}{part}"),
        )


@pytest.mark.parametrize("action", sorted(ACTIONS))
def test_action_wire_md5_sums_match_oceanwaters(owl, action):
    got = tuple(getattr(owl, f"{action}Action{part}")._md5sum for part in _ACTION_PARTS)
    assert got == WIRE_MD5[action]


@pytest.mark.parametrize("message", sorted(MESSAGES))
def test_message_fields(owl, message):
    cls = getattr(owl, message)
    assert cls._type == f"owl_msgs/{message}"
    assert _fields(cls) == MESSAGES[message]
    assert cls._has_header


@pytest.mark.parametrize("message", sorted(MESSAGES))
def test_message_constants(owl, message):
    assert _constants(getattr(owl, message)) == CONSTANTS.get(message, {})


@pytest.mark.parametrize("message", sorted(MESSAGES))
def test_message_md5_sums_match_oceanwaters(owl, message):
    assert getattr(owl, message)._md5sum == MESSAGE_MD5[message]


def test_fault_flags_are_distinct_bits(owl):
    for message, constants in CONSTANTS.items():
        flags = [v for k, v in constants.items() if k != "NONE"]
        assert all(v > 0 and v & (v - 1) == 0 for v in flags), message
        assert len(set(flags)) == len(flags), message


def test_a_goal_round_trips_through_its_wire_format(owl):
    from geometry_msgs.msg import Point, Vector3

    goal = owl.ArmFindSurfaceGoal(
        frame=0,
        relative=False,
        position=Point(1.6, 0.1, -0.15),
        normal=Vector3(0.0, 0.0, 1.0),
        distance=0.2,
        overdrive=0.05,
        force_threshold=200.0,
        torque_threshold=100.0,
    )
    buffer = io.BytesIO()
    goal.serialize(buffer)
    decoded = owl.ArmFindSurfaceGoal().deserialize(buffer.getvalue())
    assert decoded == goal


def test_arm_joint_arrays_are_fixed_at_seven_values(owl):
    import genpy

    assert len(owl.ArmJointPositions().value) == 7
    six_joints = owl.ArmJointPositions(value=[0.0] * 6)
    with pytest.raises(genpy.SerializationError):
        six_joints.serialize(io.BytesIO())
